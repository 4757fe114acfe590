//! The hard cases of the GPU forms of the structures other than the BVH — the kd-tree
//! (src/accel/kdtree/kdtree.wgsl) and the BIH (src/accel/bih/bih.wgsl) — against their CPU
//! twins, each tree's own traversal, on lavapipe (or any adapter): every ray's hit (t, prim,
//! u, v) and work (nodes visited, triangles tested) agree bit for bit, closest and any hit,
//! the tree in either BVH memory; the f64 oracle judges the GPU's answers. The suite every
//! GPU form runs (soups, models, kernel variants, bad rays) is tests/gpu_vs_cpu.rs; here the
//! cases over [`FORMS`], then each structure's own planes and depth cap.

mod common;

use std::sync::Arc;

use common::gpu_twin::{bits, cpu_device, gpu_form, judged, same_on_gpu};
use common::hard::{
    chain_centres, coincident_stacks, corner_cascade, corner_rays, extreme_rays, grid,
    invalid_rays, kd_tree_at_the_depth_cap, soup_on_a_grid, split_plane_rays, stack_rays,
};
use common::{gpu_device, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bih::{Bih, BihOptions, MAX_BIH_DEPTH};
use lancer::accel::kdtree::{KdOptions, KdTree};
use lancer::accel::AccelKind;
use lancer::accel::GpuForm;
use lancer::geometry::Ray;
use lancer::mesh::Mesh;
use lancer::{Device, Query, Robustness, Tracer, TracerOptions};

/// Every structure besides the BVH with a GPU form, and what its error names it.
const FORMS: [(AccelKind, &str); 2] = [(AccelKind::KdTree, "kd-tree"), (AccelKind::Bih, "BIH")];

#[test]
fn rays_at_shared_edges_and_vertices() {
    let (mesh, targets) = grid(24, 0.37);
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let mut rays = Vec::new();
    for &t in &targets {
        let mut o = c + rng.dir() * 20.0;
        o.z = o.z.abs() + 1.0;
        rays.push(Ray::new(o, (t - o).normalize(), 0.0, 3.4e38));
        rays.push(Ray::new(t - Vec3::Z * 5.0, Vec3::Z, 0.0, f32::INFINITY));
    }
    for (kind, _) in FORMS {
        let name = format!("{kind} grid");
        let hits = same_on_gpu(&name, &gpu_form(kind, &mesh), &rays, Robustness::default());
        let leaks = hits[0].iter().filter(|h| !h.is_hit()).count();
        assert_eq!(
            leaks, 0,
            "{kind}: rays through shared edges and vertices leaked"
        );
        judged(&name, &mesh, &rays, &hits, 1);
    }
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    let rays = stack_rays(&mut rng, 2000);
    for (kind, _) in FORMS {
        let name = format!("{kind} coincident");
        let hits = same_on_gpu(&name, &gpu_form(kind, &mesh), &rays, Robustness::default());
        // Equal t goes to the smaller index: exactly the oracle's answer nearly everywhere.
        assert!(judged(&name, &mesh, &rays, &hits, 1) > 1800);
    }
}

#[test]
fn invalid_and_extreme_rays() {
    let mut rng = Rng::new(41);
    let mesh = soup(&mut rng, 500, 0.3);
    let invalid = invalid_rays();
    let rays = extreme_rays(&mut rng, 3000);
    for (kind, _) in FORMS {
        let tree = gpu_form(kind, &mesh);
        let hits = same_on_gpu("invalid", &tree, &invalid, Robustness::default());
        assert!(hits.iter().flatten().all(|h| !h.is_hit()), "{kind}");
        let options = TracerOptions {
            stats: true,
            ..TracerOptions::default()
        };
        let mut gpu = Tracer::with_layout(gpu_device(), tree.clone(), &options).unwrap();
        let stats = gpu.trace(&invalid, Query::Closest).unwrap().stats.unwrap();
        assert!(
            stats.iter().all(|s| s.nodes == 0 && s.tris == 0),
            "{kind}: {stats:?}"
        );
        let name = format!("{kind} extreme");
        let hits = same_on_gpu(&name, &tree, &rays, Robustness::default());
        judged(&name, &mesh, &rays, &hits, 1);
    }
}

#[test]
fn the_tracer_runs_each_form_on_a_gpu_and_refuses_the_grids() {
    let mut rng = Rng::new(9);
    let mesh = soup(&mut rng, 800, 0.2);
    let rays = random_rays(&mut rng, 2000, &mesh);
    let options = TracerOptions::default();
    for (kind, named) in FORMS {
        let trace = |device: &'static Device| {
            let mut t = Tracer::with_structure(device, &mesh, kind, &options).unwrap();
            assert_eq!(t.layout().is_some(), !device.is_cpu());
            t.trace(&rays, Query::Closest).unwrap().hits
        };
        let (cpu, gpu) = (trace(cpu_device()), trace(gpu_device()));
        assert!(
            cpu.iter().zip(&gpu).all(|(a, b)| bits(a) == bits(b)),
            "{kind}"
        );
        assert!(gpu.iter().filter(|h| h.is_hit()).count() > 1000, "{kind}");
        // An empty mesh: one empty leaf, every ray a miss that visits nothing (on both).
        let empty = gpu_form(kind, &Mesh::default());
        let hits = same_on_gpu("empty", &empty, &rays[..100], Robustness::default());
        assert!(hits.iter().flatten().all(|h| !h.is_hit()), "{kind}");
        // The refusal names the structures that do have GPU kernels.
        let e = Tracer::with_structure(gpu_device(), &mesh, AccelKind::UniformGrid, &options)
            .err()
            .expect("the grid has no GPU kernel")
            .to_string();
        assert!(e.contains(named) && e.contains("--device cpu"), "{e}");
    }
}

// One structure's own planes and depth cap.

#[test]
fn kdtree_axis_parallel_rays_on_split_planes() {
    let mut rng = Rng::new(21);
    let mesh = soup_on_a_grid(&mut rng);
    let tree = KdTree::build(&mesh, &KdOptions::default()).unwrap();
    let planes = tree.split_planes();
    assert!(planes.len() > 100);
    let rays = split_plane_rays(&mut rng, &mesh, &planes, 3000);
    let tree: Arc<dyn GpuForm> = Arc::new(tree);
    let hits = same_on_gpu("split planes", &tree, &rays, Robustness::default());
    judged("split planes", &mesh, &rays, &hits, 1);
}

#[test]
fn bih_axis_parallel_rays_on_clip_planes() {
    let mut rng = Rng::new(21);
    let mesh = soup_on_a_grid(&mut rng);
    let tree = Bih::build(&mesh, &BihOptions::default()).unwrap();
    // Both planes of every node: the left child's maximum and the right child's minimum.
    let planes: Vec<(usize, f32)> = (tree.clip_planes().into_iter())
        .flat_map(|(k, l, r)| [(k, l), (k, r)])
        .filter(|(_, p)| p.abs() < f32::MAX)
        .collect();
    assert!(planes.len() > 100);
    let rays = split_plane_rays(&mut rng, &mesh, &planes, 3000);
    let tree: Arc<dyn GpuForm> = Arc::new(tree);
    let hits = same_on_gpu("clip planes", &tree, &rays, Robustness::default());
    judged("clip planes", &mesh, &rays, &hits, 1);
}

#[test]
fn kdtree_at_the_depth_cap_stays_within_the_kernel_stack() {
    let mut rng = Rng::new(71);
    let (mesh, tree) = kd_tree_at_the_depth_cap(&mut rng);
    let rays = corner_rays(&mut rng, &mesh);
    let hits = same_on_gpu(
        "deep",
        &(Arc::new(tree) as Arc<dyn GpuForm>),
        &rays,
        Robustness::default(),
    );
    judged("deep", &mesh, &rays, &hits, 4);
}

#[test]
fn bih_at_the_depth_cap_stays_within_the_kernel_stack() {
    let mut rng = Rng::new(71);
    let mesh = corner_cascade(&mut rng);
    let opts = BihOptions {
        max_leaf: 1,
        ..BihOptions::default()
    };
    let tree = Bih::build(&mesh, &opts).unwrap();
    let s = tree.stats();
    assert!(
        s.max_depth > MAX_BIH_DEPTH - 8 && s.max_depth <= MAX_BIH_DEPTH,
        "{s:?}"
    );
    // Rays at the chain's small triangles from nearby, and at random.
    let mut rays = random_rays(&mut rng, 500, &mesh);
    for (c, a) in chain_centres() {
        for _ in 0..4 {
            let o = c + rng.dir() * 4.0 * a;
            rays.push(Ray::new(o, (c - o).normalize(), 0.0, 3.4e38));
        }
    }
    let hits = same_on_gpu(
        "deep",
        &(Arc::new(tree) as Arc<dyn GpuForm>),
        &rays,
        Robustness::default(),
    );
    judged("deep", &mesh, &rays, &hits, 1);
}
