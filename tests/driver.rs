//! The driver's own traversal (Vulkan ray queries, `gpu::DriverTracer`) against lancer's CPU
//! twin, judged by the f64 oracle: an independent implementation on both sides, so a bug that
//! lancer's GPU kernel and its twin share would show here. Runs where the adapter offers ray
//! queries (lavapipe from Mesa 25 does; scripts/test.sh runs this file on it and sets
//! LANCER_EXPECT_RAY_QUERY, so there a missing feature fails instead of skipping). The
//! refusal without ray queries is tested on every adapter.

mod common;

use common::{gpu, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::build;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::camera::Camera;
use lancer::geometry::{Hit, Ray, MISS};
use lancer::gpu::{DriverTracer, GpuContext};
use lancer::mesh::Mesh;
use lancer::trace::compare::compare_hits_independent;
use lancer::trace::files::{bounce_rays, default_light, shadow_rays};
use lancer::{Device, Query, Tracer, TracerOptions};

/// The adapter when it has ray queries; None (said on stderr) when it has none and none was
/// promised.
fn ray_query_gpu() -> Option<&'static GpuContext> {
    let ctx = gpu();
    if ctx.ray_query {
        return Some(ctx);
    }
    assert!(
        std::env::var_os("LANCER_EXPECT_RAY_QUERY").is_none(),
        "LANCER_EXPECT_RAY_QUERY is set but {} offers no ray queries",
        ctx.adapter
    );
    eprintln!(
        "NOT RUN: {} offers no ray queries (lavapipe from Mesa 25 does)",
        ctx.adapter
    );
    None
}

fn twin_hits(mesh: &Mesh, rays: &[Ray], query: Query) -> Vec<Hit> {
    let cpu = Device::cpu();
    let mut t = Tracer::new(&cpu, mesh, &TracerOptions::default()).unwrap();
    t.trace(rays, query).unwrap().hits
}

/// Traces `rays` with the driver (triangles in the dfs-sign leaf order) and asserts that
/// every answer agrees with the CPU twin or is a genuine tie the oracle names.
fn check(ctx: &GpuContext, name: &str, mesh: &Mesh, rays: &[Ray], query: Query) {
    let layout = flatten(LayoutKind::DfsSign, &build(mesh, &Default::default()), mesh);
    let mut driver = DriverTracer::new(ctx, layout.as_ref()).unwrap();
    let (got, _) = driver.trace(rays, query).unwrap();
    assert_eq!(got.len(), rays.len());
    let reference = twin_hits(mesh, rays, query);
    let cmp = compare_hits_independent(mesh, rays, query, &reference, &got);
    let hits = got.iter().filter(|h| h.is_hit()).count();
    println!(
        "{name} {query:?}: {} rays, {hits} hits; {} agree ({} identical), {} ties, {} disagree",
        rays.len(),
        cmp.agree,
        cmp.identical,
        cmp.ties,
        cmp.disagree.len()
    );
    assert!(
        cmp.disagree.is_empty(),
        "{name} {query:?}: {} disagree; first: {:?}",
        cmp.disagree.len(),
        cmp.disagree[0]
    );
    // Not vacuous: the rays hit something, and closest hits name the same triangle at a t
    // the oracle accepts (any-hit may name any occluder).
    assert!(hits > 0, "{name}: no hits");
    if query == Query::Closest {
        assert!(cmp.agree * 100 >= rays.len() * 99, "{name}: too few agree");
    }
}

#[test]
fn the_driver_agrees_with_the_cpu_twin_on_the_bunny() {
    let Some(ctx) = ray_query_gpu() else { return };
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let primary = Camera::default_view(&mesh.bounds(), 128, 128).primary_rays();
    let hits = twin_hits(&mesh, &primary, Query::Closest);
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    let bounce = bounce_rays(&mesh, &primary, &hits, 1);
    let random = random_rays(&mut Rng::new(7), 20_000, &mesh);
    check(ctx, "bunny primary", &mesh, &primary, Query::Closest);
    check(ctx, "bunny shadow", &mesh, &shadow, Query::Any);
    check(ctx, "bunny bounce", &mesh, &bounce, Query::Closest);
    check(ctx, "bunny random", &mesh, &random, Query::Closest);
    check(ctx, "bunny random", &mesh, &random, Query::Any);
}

#[test]
fn the_driver_agrees_on_random_soups() {
    let Some(ctx) = ray_query_gpu() else { return };
    for seed in 0..2 {
        let mut rng = Rng::new(500 + seed);
        let mesh = soup(&mut rng, 3000, 0.15);
        let rays = random_rays(&mut rng, 20_000, &mesh);
        check(ctx, "soup", &mesh, &rays, Query::Closest);
        check(ctx, "soup", &mesh, &rays, Query::Any);
    }
}

#[test]
fn invalid_rays_and_an_empty_mesh_are_misses() {
    let Some(ctx) = ray_query_gpu() else { return };
    let mesh = soup(&mut Rng::new(9), 100, 0.3);
    let layout = flatten(
        LayoutKind::DfsSign,
        &build(&mesh, &Default::default()),
        &mesh,
    );
    let mut driver = DriverTracer::new(ctx, layout.as_ref()).unwrap();
    let c = mesh.bounds().center();
    let o = c - Vec3::Z * 10.0;
    let bad = [
        Ray::new(o, Vec3::new(f32::NAN, 0.0, 1.0), 0.0, 1e30),
        Ray::new(o, Vec3::ZERO, 0.0, 1e30),
        Ray::new(Vec3::splat(f32::INFINITY), Vec3::Z, 0.0, 1e30),
        Ray::new(o, Vec3::Z, 5.0, 1.0),
    ];
    let (got, _) = driver.trace(&bad, Query::Closest).unwrap();
    assert!(got.iter().all(|h| h.prim == MISS), "{got:?}");
    let empty = Mesh::from_triangles(Vec::new());
    let layout = flatten(
        LayoutKind::DfsSign,
        &build(&empty, &Default::default()),
        &empty,
    );
    let mut driver = DriverTracer::new(ctx, layout.as_ref()).unwrap();
    let (got, _) = driver
        .trace(&[Ray::new(o, Vec3::Z, 0.0, 1e30)], Query::Any)
        .unwrap();
    assert_eq!(got[0].prim, MISS);
}

#[test]
fn an_adapter_without_ray_queries_is_refused_with_a_reason() {
    // The adapter's own device, told it has no ray queries: the refusal runs everywhere.
    let ctx = gpu();
    let mut without: GpuContext = ctx.clone();
    without.ray_query = false;
    let mesh = soup(&mut Rng::new(1), 10, 0.3);
    let layout = flatten(
        LayoutKind::DfsSign,
        &build(&mesh, &Default::default()),
        &mesh,
    );
    let Err(e) = DriverTracer::new(&without, layout.as_ref()) else {
        panic!("a driver tracer opened without ray queries");
    };
    assert!(e.to_string().contains("no ray queries"), "{e}");
}
