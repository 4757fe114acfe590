//! The subgroup-coherent traversal mode (`TraversalMode::Subgroup`) on lavapipe (or any
//! adapter with subgroups) against the per-ray kernel and the CPU twin: closest hits equal the
//! per-ray kernel's bit for bit and the twin's (or are genuine ties the f64 oracle names);
//! any hits are judged by the oracle. Soups, the bunny, rays at shared edges and vertices,
//! both BVH memories, trusted modules and Möller–Trumbore, invalid rays and partial
//! subgroups, rays the driver's loop cap cuts short, and the fallback to per-ray where the
//! mode cannot run.

mod common;

use std::sync::Arc;

use common::hard::nan_zero_and_empty_rays;
use common::{gpu, gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::build;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::{GpuArrays, GpuForm, Mask};
use lancer::camera::Camera;
use lancer::geometry::{Aabb, Hit, Ray, Triangle, TriangleTest};
use lancer::gpu::{shaders, BvhMemory};
use lancer::mesh::Mesh;
use lancer::trace::compare::compare_hits;
use lancer::trace::files::{bounce_rays, default_light, shadow_rays};
use lancer::{
    Accel, Device, Query, RayStats, Robustness, TraceResult, Tracer, TracerOptions, TraversalMode,
};

fn bits(hits: &[Hit]) -> Vec<[u32; 4]> {
    hits.iter()
        .map(|h| [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()])
        .collect()
}

/// Traces on `device` in `mode` (statistics on); the mode that ran must be the one asked
/// for on a GPU with subgroups.
fn trace(
    device: &Device,
    layout: &Arc<dyn GpuForm>,
    rays: &[Ray],
    query: Query,
    options: TracerOptions,
) -> TraceResult {
    let options = TracerOptions {
        stats: true,
        ..options
    };
    let mut t = Tracer::with_layout(device, layout.clone(), &options).unwrap();
    t.trace(rays, query).unwrap()
}

/// Subgroup mode against the per-ray kernel and the CPU twin, for every layout offering
/// the mode, in both memories unless `memories` says otherwise. Returns the rays on which the
/// subgroup hits are bit-identical to the twin's (of the last layout).
fn check(
    name: &str,
    mesh: &Mesh,
    rays: &[Ray],
    query: Query,
    robustness: Robustness,
    memories: &[BvhMemory],
) -> usize {
    assert!(
        gpu().subgroups.is_some(),
        "{} has no subgroups: these tests need them",
        gpu().adapter
    );
    let tree = build(mesh, &Default::default());
    let mut identical = 0;
    for &kind in LayoutKind::ALL {
        let layout: Arc<dyn GpuForm> = flatten(kind, &tree, mesh).into();
        if layout.subgroup_wgsl().is_none() {
            continue;
        }
        let base = TracerOptions {
            layout: Some(kind),
            robustness,
            ..TracerOptions::default()
        };
        let twin = trace(&Device::cpu(), &layout, rays, query, base);
        for &memory in memories {
            let o = TracerOptions { memory, ..base };
            let per_ray = trace(gpu_device(), &layout, rays, query, o);
            let sub = trace(
                gpu_device(),
                &layout,
                rays,
                query,
                TracerOptions {
                    mode: TraversalMode::Subgroup,
                    ..o
                },
            );
            let label = format!("{name} {kind} {memory:?} {query:?}");
            assert_eq!(per_ray.mode, TraversalMode::PerRay, "{label}");
            assert_eq!(sub.mode, TraversalMode::Subgroup, "{label}");
            let cmp = compare_hits(mesh, rays, query, &twin.hits, &sub.hits);
            println!(
                "{label}: {} identical to the twin, {} agree, {} ties, {} disagree; {} retraced",
                cmp.identical,
                cmp.agree,
                cmp.ties,
                cmp.disagree.len(),
                sub.cpu_retraced
            );
            assert!(
                cmp.disagree.is_empty(),
                "{label}: {} disagree with the twin; first: {:?}",
                cmp.disagree.len(),
                cmp.disagree[0]
            );
            // None of these sets comes near a driver's loop cap: a retraced ray is a kernel
            // that did not finish (it would hang where the driver has no cap).
            assert_eq!(sub.cpu_retraced, 0, "{label}: rays retraced on the CPU");
            if query == Query::Closest {
                // Closest hits do not depend on the visiting order: bit for bit the per-ray
                // kernel's, which runs the same tests.
                let (a, b) = (bits(&per_ray.hits), bits(&sub.hits));
                let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
                assert_eq!(differ, 0, "{label}: {differ} rays differ from per-ray");
            }
            // Work is counted for valid rays only; every valid ray loads at least the root.
            let stats = sub.stats.unwrap();
            for (r, s) in rays.iter().zip(&stats) {
                assert_eq!(r.is_valid(), s.nodes > 0, "{label}: {r:?} counted {s:?}");
            }
            identical = cmp.identical;
        }
    }
    identical
}

const BOTH: [BvhMemory; 2] = [BvhMemory::Buffers, BvhMemory::Textures];

#[test]
fn every_layout_with_the_mode_has_a_valid_subgroup_kernel() {
    let mesh = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)]);
    let tree = build(&mesh, &Default::default());
    let mut offered = Vec::new();
    for &kind in LayoutKind::ALL {
        let layout = flatten(kind, &tree, &mesh);
        let Some(src) =
            shaders::trace_subgroup_source(layout.as_ref(), &lancer::gpu::BufferParts::WHOLE)
        else {
            continue;
        };
        let m = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{kind}: {}", e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&m)
        .unwrap_or_else(|e| panic!("{kind}: {}", e.emit_to_string(&src)));
        offered.push(kind);
    }
    assert!(offered.contains(&LayoutKind::DfsSign), "{offered:?}");
}

#[test]
fn random_soups_closest_and_any() {
    for seed in 0..2 {
        let mut rng = Rng::new(700 + seed);
        let mesh = soup(&mut rng, 3000, 0.15);
        // Not a whole number of subgroups or workgroups: the last subgroup is partly empty.
        let rays = random_rays(&mut rng, 6003, &mesh);
        for query in [Query::Closest, Query::Any] {
            let name = format!("soup {seed}");
            check(&name, &mesh, &rays, query, Robustness::default(), &BOTH);
        }
    }
}

#[test]
fn trusted_modules_and_moller_trumbore() {
    let mut rng = Rng::new(45);
    let mesh = soup(&mut rng, 2000, 0.2);
    let rays = random_rays(&mut rng, 3000, &mesh);
    for trusted in [false, true] {
        for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
            let rob = Robustness {
                triangle_test: test,
                checked_module: !trusted,
                ..Robustness::default()
            };
            let name = format!("trusted={trusted} {test:?}");
            check(
                &name,
                &mesh,
                &rays,
                Query::Closest,
                rob,
                &[BvhMemory::default()],
            );
        }
    }
}

#[test]
fn bunny_primary_shadow_and_bounce_rays() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let primary = Camera::default_view(&mesh.bounds(), 96, 72).primary_rays();
    let cpu = Device::cpu();
    let tree = build(&mesh, &Default::default());
    let layout: Arc<dyn GpuForm> = flatten(LayoutKind::DfsSign, &tree, &mesh).into();
    let hits = trace(&cpu, &layout, &primary, Query::Closest, Default::default()).hits;
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    let bounce = bounce_rays(&mesh, &primary, &hits, 3);
    assert!(shadow.len() > 1000, "{} shadow rays", shadow.len());
    let rob = Robustness::default();
    let same = check("bunny primary", &mesh, &primary, Query::Closest, rob, &BOTH);
    assert!(same > primary.len() * 9 / 10, "{same} identical");
    check("bunny shadow", &mesh, &shadow, Query::Any, rob, &BOTH);
    check(
        "bunny bounce",
        &mesh,
        &bounce,
        Query::Closest,
        rob,
        &[BvhMemory::default()],
    );
}

#[test]
fn rays_at_shared_edges_and_vertices() {
    // A bumpy grid of quads: every ray passes through a shared vertex or an edge midpoint.
    let n = 24;
    let p = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
        Vec3::new(x, y, 0.2 * (7.0 * x).sin() * (5.0 * y).cos())
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    let mesh = Mesh::from_triangles(tris);
    let mut rng = Rng::new(12);
    let rays: Vec<Ray> = (0..4000)
        .map(|k| {
            let (i, j) = (
                1 + rng.u64() as usize % (n - 1),
                1 + rng.u64() as usize % (n - 1),
            );
            let target = match k % 3 {
                0 => p(i, j),
                1 => 0.5 * (p(i, j) + p(i + 1, j)),
                _ => 0.5 * (p(i, j) + p(i + 1, j + 1)),
            };
            let o = target + rng.dir() * 2.0;
            Ray::new(o, (target - o).normalize(), 0.0, 100.0)
        })
        .collect();
    for query in [Query::Closest, Query::Any] {
        check(
            "edges and vertices",
            &mesh,
            &rays,
            query,
            Robustness::default(),
            &BOTH,
        );
    }
}

#[test]
fn invalid_rays_and_partial_subgroups_end_as_misses() {
    let mut rng = Rng::new(3);
    let mesh = soup(&mut rng, 800, 0.2);
    let mut rays = random_rays(&mut rng, 1001, &mesh);
    let bad = nan_zero_and_empty_rays();
    // Invalid rays among valid ones in the same subgroups, and a subgroup of only invalid ones.
    for (k, r) in bad.iter().enumerate() {
        rays[13 * k + 1] = *r;
        rays[8 * 40 + k] = *r;
    }
    rays[8 * 40 + 7] = bad[0];
    for query in [Query::Closest, Query::Any] {
        check(
            "invalid rays",
            &mesh,
            &rays,
            query,
            Robustness::default(),
            &BOTH,
        );
    }
    // Batches of one ray, of only invalid rays, and of none, for every layout with the mode.
    let tree = build(&mesh, &Default::default());
    for &kind in LayoutKind::ALL {
        let layout: Arc<dyn GpuForm> = flatten(kind, &tree, &mesh).into();
        if layout.subgroup_wgsl().is_none() {
            continue;
        }
        let sub = TracerOptions {
            layout: Some(kind),
            mode: TraversalMode::Subgroup,
            ..TracerOptions::default()
        };
        for batch in [&rays[..1], &bad[..], &[]] {
            let r = trace(gpu_device(), &layout, batch, Query::Closest, sub);
            let cpu = trace(&Device::cpu(), &layout, batch, Query::Closest, sub);
            assert_eq!(
                bits(&r.hits),
                bits(&cpu.hits),
                "{kind}, {} rays",
                batch.len()
            );
        }
    }
}

#[test]
fn rays_the_driver_cuts_short_are_traced_again_on_the_cpu() {
    // 120,000 coincident triangles: one subgroup step tests one triangle, so these rays need
    // more loop iterations than lavapipe up to Mesa 22 runs (65,535); the host traces them
    // again on the twin. On a driver without that cap they simply finish.
    let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let mesh = Mesh::from_triangles(vec![t; 120_000]);
    let rays: Vec<Ray> = (0..40)
        .map(|i| {
            let p = Vec3::new(0.1 + 0.01 * i as f32, 0.2, 0.0);
            Ray::new(p + Vec3::Z, Vec3::NEG_Z, 0.0, 10.0)
        })
        .collect();
    let tree = build(&mesh, &Default::default());
    let layout: Arc<dyn GpuForm> = flatten(LayoutKind::DfsSign, &tree, &mesh).into();
    let twin = trace(
        &Device::cpu(),
        &layout,
        &rays,
        Query::Closest,
        Default::default(),
    );
    let options = |mode| TracerOptions {
        mode,
        ..TracerOptions::default()
    };
    let per_ray = trace(
        gpu_device(),
        &layout,
        &rays,
        Query::Closest,
        options(TraversalMode::PerRay),
    );
    let sub = trace(
        gpu_device(),
        &layout,
        &rays,
        Query::Closest,
        options(TraversalMode::Subgroup),
    );
    println!(
        "retraced on the CPU: per-ray {}, subgroup {}",
        per_ray.cpu_retraced, sub.cpu_retraced
    );
    assert_eq!(sub.mode, TraversalMode::Subgroup);
    assert_eq!(bits(&sub.hits), bits(&twin.hits));
    assert!(
        sub.hits.iter().all(|h| h.prim == 0),
        "the smallest index wins"
    );
    if per_ray.cpu_retraced > 0 {
        // This driver caps loops; the subgroup loop runs 120,000 steps, so it is cut too.
        assert_eq!(sub.cpu_retraced, rays.len());
    }
}

/// dfs-sign without its subgroup traversal: a layout that lacks the mode.
struct PerRayOnly(Arc<dyn GpuForm>);

impl Accel for PerRayOnly {
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }
    fn intersect_masked(
        &self,
        ray: &Ray,
        q: Query,
        rob: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        self.0.intersect_masked(ray, q, rob, mask, stats)
    }
}

impl GpuForm for PerRayOnly {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn arrays(&self) -> GpuArrays<'_> {
        self.0.arrays()
    }
    fn wgsl(&self) -> String {
        self.0.wgsl()
    }
    fn validate(&self) -> Result<(), String> {
        self.0.validate()
    }
    fn node_bytes(&self) -> usize {
        self.0.node_bytes()
    }
}

/// (what, device, layout, workgroup size, the mode that must run).
type Case<'a> = (
    &'a str,
    &'a Device,
    &'a Arc<dyn GpuForm>,
    u32,
    TraversalMode,
);

#[test]
fn where_the_mode_cannot_run_it_falls_back_to_per_ray() {
    let mut rng = Rng::new(77);
    let mesh = soup(&mut rng, 500, 0.2);
    let rays = random_rays(&mut rng, 700, &mesh);
    let tree = build(&mesh, &Default::default());
    let layout: Arc<dyn GpuForm> = flatten(LayoutKind::DfsSign, &tree, &mesh).into();
    let sub = TracerOptions {
        mode: TraversalMode::Subgroup,
        ..TracerOptions::default()
    };
    let twin = trace(
        &Device::cpu(),
        &layout,
        &rays,
        Query::Closest,
        Default::default(),
    );
    let lanes = gpu().subgroups.expect("subgroups").max;
    let no_mode: Arc<dyn GpuForm> = Arc::new(PerRayOnly(layout.clone()));
    let cpu = Device::cpu();
    let cases: [Case; 4] = [
        ("the CPU", &cpu, &layout, 64, TraversalMode::PerRay),
        (
            "a layout without it",
            gpu_device(),
            &no_mode,
            64,
            TraversalMode::PerRay,
        ),
        (
            "a partial subgroup",
            gpu_device(),
            &layout,
            lanes + 1,
            TraversalMode::PerRay,
        ),
        (
            "whole subgroups",
            gpu_device(),
            &layout,
            2 * lanes,
            TraversalMode::Subgroup,
        ),
    ];
    for (name, device, layout, workgroup_size, want) in cases {
        let options = TracerOptions {
            workgroup_size,
            ..sub
        };
        let mut t = Tracer::with_layout(device, layout.clone(), &options).unwrap();
        assert_eq!(t.mode(), want, "{name}");
        let r = t.trace(&rays, Query::Closest).unwrap();
        assert_eq!(r.mode, want, "{name}");
        let cmp = compare_hits(&mesh, &rays, Query::Closest, &twin.hits, &r.hits);
        assert!(cmp.disagree.is_empty(), "{name}: {:?}", cmp.disagree[0]);
    }
    // Changing the workgroup size or the mode settles the mode again.
    let mut t = Tracer::with_layout(gpu_device(), layout.clone(), &sub).unwrap();
    assert_eq!(t.mode(), TraversalMode::Subgroup);
    t.set_kernel(Robustness::default(), lanes + 1, false);
    assert_eq!(t.mode(), TraversalMode::PerRay);
    t.set_kernel(Robustness::default(), 64, false);
    assert_eq!(t.mode(), TraversalMode::Subgroup);
    t.set_mode(TraversalMode::PerRay);
    assert_eq!(
        t.trace(&rays, Query::Closest).unwrap().mode,
        TraversalMode::PerRay
    );
}
