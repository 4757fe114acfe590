//! The `bvh2-wide-node` layout's CPU twin (src/accel/bvh/layouts/bvh2_wide_node) against the f64 oracle
//! and an f32 brute force: closest hits equal the brute force bit for bit (so no box the
//! tie rule needs is cut, whatever the near-first order), any hits are real hits; on random
//! soups, the bunny, rays through shared edges and vertices, axis-parallel rays on node-box
//! faces, coincident triangles, and a hand-made tree at the depth cap that fills the stack
//! (also on the GPU, with and without bounds checks). A tree one level deeper is refused by
//! `Bvh::new` (a layout that deep, by validate(): the layouts' unit tests); other
//! corruptions are the unit tests in mod.rs. GPU ≡ twin on everything
//! else is tests/gpu_vs_cpu.rs.

mod common;

use common::accel_check::{
    assert_closest_is_brute_force, check, check_against, no_leaks_at_shared_edges,
    smallest_index_at_nearest_t,
};
use common::hard::{coincident_stacks, edge_rays, grid, stack_rays};
use common::{gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build as build_bvh, BuildOptions, Bvh, Node, MAX_DEPTH};
use lancer::accel::GpuForm;
use lancer::accel::{build, Accel, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::{Aabb, Ray, Triangle};
use lancer::gpu::BvhMemory;
use lancer::mesh::Mesh;
use lancer::trace::oracle::Truths;
use lancer::{Device, Query, RayStats, Robustness, Tracer, TracerOptions};

const WIDE: LayoutKind = LayoutKind::Bvh2WideNode;

fn wide(mesh: &Mesh) -> Box<dyn Accel> {
    build(AccelKind::Bvh(WIDE), mesh, &BuildOptions::default()).expect("builds")
}

#[test]
fn random_soups_against_the_oracle_and_the_brute_force() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        let accel = wide(&mesh);
        let (exact, _) = check(&format!("soup {seed}"), &mesh, accel.as_ref(), &rays);
        assert!(exact > 2500);
        assert_closest_is_brute_force(&format!("soup {seed}"), &mesh, accel.as_ref(), &rays);
    }
}

#[test]
fn bunny_against_the_oracle_and_dfs_sign() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let bvh = build_bvh(&mesh, &BuildOptions::default());
    let accel = flatten(WIDE, &bvh, &mesh);
    let dfs = flatten(LayoutKind::DfsSign, &bvh, &mesh);
    for l in [&accel, &dfs] {
        let per_tri = l.bytes() as f64 / l.triangles() as f64;
        println!("bunny {}: {per_tri:.1} bytes per triangle", l.name());
    }
    let mut rng = Rng::new(7);
    let rays = random_rays(&mut rng, 3000, &mesh);
    // The oracle tests all 69,451 triangles per ray: few rays judged.
    check("bunny random", &mesh, accel.as_ref(), &rays[..200]);
    let cam = Camera::default_view(&mesh.bounds(), 16, 16);
    let (exact, _) = check("bunny primary", &mesh, accel.as_ref(), &cam.primary_rays());
    assert!(exact > 128);
    // Closest hits are order-independent: the same as dfs-sign's (same tree, same tests),
    // bit for bit, on many more rays.
    let rob = Robustness::default();
    let primary = Camera::default_view(&mesh.bounds(), 96, 96).primary_rays();
    for (what, rays) in [("random", &rays), ("primary 96²", &primary)] {
        let (a, sa) = accel.trace_batch(rays, Query::Closest, &rob);
        let (b, sb) = dfs.trace_batch(rays, Query::Closest, &rob);
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        let (na, ta) = RayStats::means(&sa);
        let (nb, tb) = RayStats::means(&sb);
        println!(
            "bunny {what}: bvh2-wide-node {na:.1} records ({:.0} B), {ta:.1} triangle tests; \
             dfs-sign {nb:.1} nodes ({:.0} B), {tb:.1} triangle tests per ray",
            na * 64.0,
            nb * 32.0
        );
        assert_eq!(
            differ, 0,
            "bunny {what}: {differ} rays differ from dfs-sign"
        );
        // Both child boxes per record: fewer node loads than dfs-sign's one box per node.
        assert!(na < nb, "bunny {what}: {na} records vs {nb} nodes per ray");
    }
}

#[test]
fn rays_at_shared_edges_and_vertices_never_leak() {
    let (mesh, targets) = grid(24, 0.37);
    let accel = wide(&mesh);
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let rays = edge_rays(&mut rng, c, &targets);
    // Equal t at a shared edge goes to the smaller index, even across leaves.
    no_leaks_at_shared_edges("grid edges", &mesh, accel.as_ref(), &rays);
}

/// Every node box's face planes (axis, position) of the tree the layout flattens.
fn box_planes(node: &Node, out: &mut Vec<(usize, f32)>) {
    let b = node.bbox();
    for axis in 0..3 {
        out.push((axis, b.lo[axis]));
        out.push((axis, b.hi[axis]));
    }
    if let Node::Inner { children, .. } = node {
        for c in children.iter() {
            box_planes(c, out);
        }
    }
}

#[test]
fn axis_parallel_rays_on_child_box_faces() {
    // Zero (and −0.0) direction components with origins exactly on the planes of the
    // children's boxes: the shared slab test's parallel-axis rule, on the twin's scalar path.
    let mut rng = Rng::new(21);
    let mesh = soup(&mut rng, 1500, 0.25);
    let mut planes = Vec::new();
    box_planes(
        build_bvh(&mesh, &BuildOptions::default()).root(),
        &mut planes,
    );
    let accel = wide(&mesh);
    let b = mesh.bounds();
    let mut rays = Vec::new();
    for i in 0..4000 {
        let (axis, pos) = planes[rng.u64() as usize % planes.len()];
        let mut o = b.lo + (b.hi - b.lo) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
        o += rng.vec3(-0.3, 0.3) * (i % 2) as f32;
        o[axis] = pos;
        let mut d = Vec3::ZERO;
        match i % 3 {
            // Along an axis within the plane, or across it.
            0 => d[(axis + 1 + (i / 3) % 2) % 3] = if rng.f32() < 0.5 { 1.0 } else { -1.0 },
            1 => d[axis] = if rng.f32() < 0.5 { 2.0 } else { -0.5 },
            // Within the plane, any direction; the axis component ±0.
            _ => {
                d = rng.dir();
                d[axis] = if i % 2 == 0 { 0.0 } else { -0.0 };
            }
        }
        let tmin = if i % 5 == 0 { -1.0 } else { 0.0 };
        rays.push(Ray::new(o, d, tmin, 3.4e38));
    }
    let (exact, _) = check("axis-parallel", &mesh, accel.as_ref(), &rays);
    assert!(
        exact > 100,
        "{exact} hits judged exactly: the rays miss everything"
    );
    assert_closest_is_brute_force("axis-parallel", &mesh, accel.as_ref(), &rays);
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // Copies of one triangle at several depths, indices interleaved among random triangles,
    // so equal-t copies sit in different leaves visited in either order.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    for max_leaf in [1, 16] {
        let opts = BuildOptions {
            max_leaf,
            ..BuildOptions::default()
        };
        let accel = build(AccelKind::Bvh(WIDE), &mesh, &opts).unwrap();
        let rays = stack_rays(&mut rng, 2000);
        let truths = Truths::new(&mesh, &rays);
        let (hits, _) = accel.trace_batch(&rays, Query::Closest, &Robustness::default());
        let exact = smallest_index_at_nearest_t(&format!("max_leaf {max_leaf}"), &truths, &hits);
        println!("coincident, max_leaf {max_leaf}: {exact} of 2000 rays exactly the oracle's");
        assert!(exact > 1800);
        check_against("coincident", &truths, accel.as_ref());
        assert_closest_is_brute_force("coincident", &mesh, accel.as_ref(), &rays);
    }
}

#[test]
fn empty_mesh_single_triangle_and_invalid_rays() {
    let empty = wide(&Mesh::default());
    assert!(empty.bounds().is_empty());
    let r = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 10.0);
    let rob = Robustness::default();
    let mut s = RayStats::default();
    assert!(!empty.intersect(&r, Query::Closest, &rob, &mut s).is_hit());
    // A single leaf is the root: the header's reference is a leaf, no inner record.
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )]);
    let accel = wide(&one);
    let mut s = RayStats::default();
    let h = accel.intersect(&r, Query::Closest, &rob, &mut s);
    assert_eq!((h.prim, h.t), (0, 1.0));
    assert_eq!(
        (s.nodes, s.tris),
        (1, 1),
        "the header, then the leaf's triangle"
    );
    let mut rng = Rng::new(41);
    let mesh = soup(&mut rng, 500, 0.3);
    let accel = wide(&mesh);
    for r in [
        Ray::new(Vec3::NAN, Vec3::X, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 0.0, f32::NAN),
        Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0), 0.0, 1.0),
    ] {
        let mut s = RayStats::default();
        assert!(!accel.intersect(&r, Query::Closest, &rob, &mut s).is_hit());
        assert_eq!(s, RayStats::default(), "{r:?} traversed");
    }
}

/// A hand-made chain `depth` inner nodes deep over `depth + 1` random triangles in the unit
/// cube: the node at depth d holds the rest of the chain (child 0) and leaf d (child 1),
/// the last one two leaves; every box is the whole cube, so a ray entering it hits both
/// children everywhere (equal entries: the chain first) and pushes once per level.
fn chain(rng: &mut Rng, depth: usize) -> (lancer::Result<Bvh>, Mesh) {
    let tris = (0..=depth)
        .map(|_| Triangle::new(rng.vec3(0.0, 1.0), rng.vec3(0.0, 1.0), rng.vec3(0.0, 1.0)))
        .collect();
    let cube = Aabb {
        lo: Vec3::ZERO,
        hi: Vec3::ONE,
    };
    // Leaves hold the order's positions left to right: leaf d (triangle d) is at position
    // depth − d.
    let leaf = |d: usize| Node::Leaf {
        bbox: cube,
        start: (depth - d) as u32,
        count: 1,
    };
    let mut node = leaf(depth);
    for d in (0..depth).rev() {
        node = Node::Inner {
            bbox: cube,
            axis: 0,
            nodes: node.nodes() + 2,
            children: Box::new([node, leaf(d)]),
        };
    }
    let order = (0..=depth as u32).rev().collect();
    let mesh = Mesh::from_triangles(tris);
    (Bvh::new(node, order, &mesh), mesh)
}

#[test]
fn a_tree_at_the_depth_cap_fills_the_stack_on_cpu_and_gpu() {
    let mut rng = Rng::new(71);
    // One level deeper than the stack allows is refused before any flatten (a layout that
    // deep from a file, by validate: the layouts' unit tests).
    let (bvh, _) = chain(&mut rng, MAX_DEPTH + 1);
    let e = bvh.unwrap_err().to_string();
    assert!(e.contains(&format!("deeper than {MAX_DEPTH}")), "{e}");
    let (bvh, mesh) = chain(&mut rng, MAX_DEPTH);
    let bvh = bvh.unwrap();
    let layout = flatten(WIDE, &bvh, &mesh);
    layout.validate().unwrap();
    let rays = random_rays(&mut rng, 2000, &mesh);
    check("chain", &mesh, layout.as_ref(), &rays);
    assert_closest_is_brute_force("chain", &mesh, layout.as_ref(), &rays);
    let rob = Robustness::default();
    let (hits, stats) = layout.trace_batch(&rays, Query::Closest, &rob);
    let mut hit = 0;
    for (h, s) in hits.iter().zip(&stats) {
        if h.is_hit() {
            // Every record, every leaf: MAX_DEPTH pushes, the stack full.
            assert_eq!(
                (s.nodes, s.tris),
                (1 + MAX_DEPTH as u32, 1 + MAX_DEPTH as u32)
            );
            hit += 1;
        }
    }
    assert!(hit > 500, "{hit} rays hit the chain");
    // The GPU, with and without bounds checks (a trusted module relies on the stack bound
    // validate() checked): the twin's answers and work, ray for ray.
    let layout: std::sync::Arc<dyn GpuForm> = layout.into();
    for checked_module in [true, false] {
        for query in [Query::Closest, Query::Any] {
            let options = TracerOptions {
                layout: Some(WIDE),
                memory: BvhMemory::Buffers,
                robustness: Robustness {
                    checked_module,
                    ..Robustness::default()
                },
                stats: true,
                ..TracerOptions::default()
            };
            let cpu = Tracer::with_layout(&Device::cpu(), layout.clone(), &options)
                .unwrap()
                .trace(&rays, query)
                .unwrap();
            let gpu = Tracer::with_layout(gpu_device(), layout.clone(), &options)
                .unwrap()
                .trace(&rays, query)
                .unwrap();
            assert_eq!(cpu.hits, gpu.hits, "checked {checked_module} {query:?}");
            assert_eq!(cpu.stats, gpu.stats, "checked {checked_module} {query:?}");
        }
    }
}
