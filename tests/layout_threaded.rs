//! The `threaded` layout (src/accel/bvh/layouts/threaded): eight copies of the dfs-sign tree, one per
//! ray octant, walked without a stack. Its twin must visit exactly the nodes dfs-sign's twin
//! visits, in the same order: so closest and any hits are dfs-sign's bit for bit and so is
//! the work per ray (nodes and triangles), on the bunny's primary, shadow and random rays,
//! random soups, rays with signed-zero and axis-parallel directions (the octant's sign rule),
//! and trees of one leaf and of none. The same rays on the GPU equal the twin's hits and
//! work. `validate`'s refusals are the unit tests in mod.rs; GPU ≡ twin on everything else
//! is tests/gpu_vs_cpu.rs.

mod common;

use std::sync::Arc;

use common::{gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::accel::GpuForm;
use lancer::camera::Camera;
use lancer::geometry::{Hit, Ray, Triangle};
use lancer::mesh::Mesh;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{Device, Query, RayStats, Robustness, Tracer, TracerOptions};

fn bits(hits: &[Hit]) -> Vec<[u32; 4]> {
    hits.iter()
        .map(|h| [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()])
        .collect()
}

fn work(stats: &[RayStats]) -> Vec<(u32, u32)> {
    stats.iter().map(|s| (s.nodes, s.tris)).collect()
}

/// The threaded twin against dfs-sign's over the same tree, both queries: hits and work
/// equal ray for ray. Returns the threaded layout.
fn same_as_dfs_sign(name: &str, mesh: &Mesh, rays: &[Ray]) -> Arc<dyn GpuForm> {
    let tree = build(mesh, &BuildOptions::default());
    let threaded: Arc<dyn GpuForm> = flatten(LayoutKind::Threaded, &tree, mesh).into();
    threaded.validate().unwrap();
    let dfs = flatten(LayoutKind::DfsSign, &tree, mesh);
    let rob = Robustness::default();
    for query in [Query::Closest, Query::Any] {
        let (h, s) = threaded.trace_batch(rays, query, &rob);
        let (dh, ds) = dfs.trace_batch(rays, query, &rob);
        let differ = bits(&h)
            .iter()
            .zip(bits(&dh))
            .filter(|(a, b)| **a != *b)
            .count();
        assert_eq!(
            differ, 0,
            "{name} {query:?}: {differ} hits differ from dfs-sign's"
        );
        assert_eq!(
            work(&s),
            work(&ds),
            "{name} {query:?}: work differs from dfs-sign's"
        );
        assert_eq!(
            bits(&threaded.trace_hits(rays, query, &rob)),
            bits(&h),
            "{name}"
        );
        let hit = h.iter().filter(|h| h.is_hit()).count();
        println!(
            "{name} {query:?}: {} rays, {hit} hits, same as dfs-sign",
            rays.len()
        );
    }
    threaded
}

/// The GPU kernel against the twin (hits and work), both queries.
fn same_on_gpu(name: &str, layout: &Arc<dyn GpuForm>, rays: &[Ray]) {
    let options = TracerOptions {
        layout: Some(LayoutKind::Threaded),
        stats: true,
        ..TracerOptions::default()
    };
    for query in [Query::Closest, Query::Any] {
        let run = |device: &Device| {
            let mut t = Tracer::with_layout(device, layout.clone(), &options).unwrap();
            t.trace(rays, query).unwrap()
        };
        let (gpu, cpu) = (run(gpu_device()), run(&Device::cpu()));
        assert_eq!(
            bits(&gpu.hits),
            bits(&cpu.hits),
            "{name} {query:?}: GPU hits"
        );
        assert_eq!(
            work(&gpu.stats.unwrap()),
            work(&cpu.stats.unwrap()),
            "{name} {query:?}: GPU work"
        );
    }
}

#[test]
fn bunny_rays_visit_what_dfs_sign_visits() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let primary = Camera::default_view(&mesh.bounds(), 128, 96).primary_rays();
    let dfs = flatten(
        LayoutKind::DfsSign,
        &build(&mesh, &Default::default()),
        &mesh,
    );
    let (hits, _) = dfs.trace_batch(&primary, Query::Closest, &Robustness::default());
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    assert!(shadow.len() > 2000, "{} shadow rays", shadow.len());
    let mut rng = Rng::new(31);
    let random = random_rays(&mut rng, 5000, &mesh);
    same_as_dfs_sign("bunny primary", &mesh, &primary);
    same_as_dfs_sign("bunny shadow", &mesh, &shadow);
    let layout = same_as_dfs_sign("bunny random", &mesh, &random);
    same_on_gpu("bunny random", &layout, &random);
}

#[test]
fn soups_and_every_octant_including_signed_zeros() {
    let mut rng = Rng::new(77);
    let mesh = soup(&mut rng, 3000, 0.15);
    let mut rays = random_rays(&mut rng, 4000, &mesh);
    // Directions with zero components of either sign, and along the axes: the octant bit is
    // set for a negative component only (-0.0 counts as positive, as dfs-sign's order has it).
    let centre = mesh.bounds().center();
    for k in 0..2000 {
        let mut d = rng.dir();
        for axis in 0..3 {
            match (k >> (2 * axis)) & 3 {
                0 => d[axis] = 0.0,
                1 => d[axis] = -0.0,
                _ => {}
            }
        }
        if d.abs().max_element() == 0.0 {
            d = Vec3::new(-0.0, -0.0, -1.0);
        }
        let o = centre - d.normalize_or(Vec3::X) * 3.0 + rng.vec3(-0.4, 0.4);
        rays.push(Ray::new(o, d, 0.0, 10.0));
    }
    let octants: std::collections::HashSet<_> = rays
        .iter()
        .map(|r| (r.dir.x < 0.0, r.dir.y < 0.0, r.dir.z < 0.0))
        .collect();
    assert_eq!(octants.len(), 8);
    let layout = same_as_dfs_sign("soup", &mesh, &rays);
    same_on_gpu("soup", &layout, &rays);
}

#[test]
fn one_leaf_and_no_triangles() {
    let one = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)]);
    let rays: Vec<Ray> = [Vec3::Z, Vec3::NEG_Z, Vec3::new(-0.3, -0.2, -1.0)]
        .iter()
        .map(|&d| Ray::new(Vec3::new(0.2, 0.2, 0.0) - d, d, 0.0, 10.0))
        .collect();
    let layout = same_as_dfs_sign("one triangle", &one, &rays);
    // A leaf root: eight copies of one node.
    assert_eq!(layout.arrays().nodes.len(), 8 * 32);
    let (hits, _) = layout.trace_batch(&rays, Query::Closest, &Robustness::default());
    assert!(hits.iter().all(|h| h.prim == 0), "{hits:?}");
    same_on_gpu("one triangle", &layout, &rays);
    let none = same_as_dfs_sign("no triangles", &Mesh::default(), &rays);
    let (hits, _) = none.trace_batch(&rays, Query::Closest, &Robustness::default());
    assert!(hits.iter().all(|h| !h.is_hit()));
}
