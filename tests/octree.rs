//! The octree's own options and invariants (src/accel/octree); what every structure must do
//! is in tests/conformance.rs. Here: soups with deep trees of small leaves; rays through
//! shared edges and along cell planes; coincident triangles in split cells; the memory cap
//! refuses instead of aborting; the stats add up and count duplicated references.

mod common;

use common::accel_check::{
    assert_closest_is_brute_force, check, check_against, no_leaks_at_shared_edges, same_as_bvh,
    smallest_index_at_nearest_t,
};
use common::hard::{
    coincident_stacks, corner_rays_by, edge_rays, grid, needles, shrinking_corner_by,
    soup_on_a_grid, split_plane_rays, stack_rays,
};
use common::speed::thread_cpu_ns;
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::BuildOptions;
use lancer::accel::octree::{Octree, OctreeOptions, MAX_OCTREE_DEPTH};
use lancer::accel::{build, Accel, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::{Ray, Triangle};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, Truths};
use lancer::{Query, RayStats, Robustness};

fn oct(mesh: &Mesh) -> Octree {
    Octree::build(mesh, &OctreeOptions::default()).expect("octree builds")
}

#[test]
fn random_soups_against_the_oracle_and_the_bvh() {
    for seed in 0..3 {
        let mut rng = Rng::new(500 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        // The defaults, and (once) a deep tree of small leaves: many cells per ray.
        let deep = OctreeOptions {
            max_depth: MAX_OCTREE_DEPTH,
            leaf_size: 1,
            traversal_cost: 1.0,
            ..OctreeOptions::default()
        };
        let all = [OctreeOptions::default(), deep];
        for opts in &all[..if seed == 0 { 2 } else { 1 }] {
            let tree = Octree::build(&mesh, opts).unwrap();
            let name = format!("soup {seed}, {opts:?}");
            println!("{name}: {:?}", tree.stats());
            let (agree, _) = check(&name, &mesh, &tree, &rays);
            assert!(agree > 2500);
            assert_eq!(same_as_bvh(&name, &mesh, &tree, &rays), 0);
            assert_closest_is_brute_force(&name, &mesh, &tree, &rays);
        }
    }
}

#[test]
fn one_thread_builds_the_same_tree() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let par = oct(&mesh);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| oct(&mesh));
    assert_eq!(par.stats(), one.stats());
    assert_eq!(par.split_planes(), one.split_planes());
    let mut rng = Rng::new(3);
    let rays = random_rays(&mut rng, 500, &mesh);
    let rob = Robustness::default();
    let (a, sa) = par.trace_batch(&rays, Query::Closest, &rob);
    let (b, sb) = one.trace_batch(&rays, Query::Closest, &rob);
    assert_eq!(a, b);
    assert_eq!(sa, sb);
}

#[test]
fn rays_at_shared_edges_and_vertices_never_leak() {
    let (mesh, targets) = grid(24, 0.37);
    let tree = oct(&mesh);
    assert!(tree.stats().max_depth >= 3, "{:?}", tree.stats());
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let rays = edge_rays(&mut rng, c, &targets);
    // Where two triangles meet at the ray, equal t goes to the smaller index even when the
    // two sit in different cells.
    no_leaks_at_shared_edges("grid edges", &mesh, &tree, &rays);
}

#[test]
fn axis_parallel_rays_on_cell_planes() {
    let mut rng = Rng::new(21);
    let mesh = soup_on_a_grid(&mut rng);
    let tree = oct(&mesh);
    let planes = tree.split_planes();
    assert!(planes.len() > 100);
    // Every fourth ray starts on two planes (often on a line where two of a cell's
    // mid-planes meet).
    let rays = split_plane_rays(&mut rng, &mesh, &planes, 4000);
    check("axis-parallel on cell planes", &mesh, &tree, &rays);
    same_as_bvh("axis-parallel on cell planes", &mesh, &tree, &rays);
    assert_closest_is_brute_force("axis-parallel on cell planes", &mesh, &tree, &rays);
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // k copies of one triangle at several depths, indices interleaved between the stacks,
    // among random triangles: the answer must be the smallest index at the nearest t. Small
    // leaves split the copies' cells as far as they can be split.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    for opts in [
        OctreeOptions::default(),
        OctreeOptions {
            leaf_size: 1,
            max_depth: MAX_OCTREE_DEPTH,
            traversal_cost: 0.0,
            ..OctreeOptions::default()
        },
    ] {
        let tree = Octree::build(&mesh, &opts).unwrap();
        println!("coincident, {opts:?}: {:?}", tree.stats());
        let rays = stack_rays(&mut rng, 2000);
        let truths = Truths::new(&mesh, &rays);
        let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
        let exact = smallest_index_at_nearest_t("the octree", &truths, &hits);
        println!(
            "coincident: {exact} of {} rays give the oracle's index",
            rays.len()
        );
        assert!(exact > 1800);
        check_against("coincident", &truths, &tree);
        assert_closest_is_brute_force("coincident", &mesh, &tree, &rays);
    }
}

#[test]
fn coplanar_triangles_on_a_mid_plane_at_exactly_equal_t() {
    // Overlapping coplanar triangles in the plane z = 4, the root cube's middle (the cube
    // spans the bounds [0, 8]³ grown by a small margin), integer vertices; small triangles
    // elsewhere make the root split. Rays along ±z from dyadic points compute the same t
    // exactly for all of them, so the smallest index must win, whichever cell meets it.
    // Rays along the plane, from inside it, meet them edge-on.
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let mut tris = vec![
        Triangle::new(p(0.0, 0.0, 0.0), p(8.0, 0.0, 0.0), p(0.0, 8.0, 0.0)),
        Triangle::new(p(0.0, 0.0, 8.0), p(8.0, 0.0, 8.0), p(0.0, 8.0, 8.0)),
        Triangle::new(p(0.0, 0.0, 4.0), p(8.0, 0.0, 4.0), p(0.0, 8.0, 4.0)), // 2: big
        Triangle::new(p(1.0, 1.0, 4.0), p(5.0, 1.0, 4.0), p(1.0, 5.0, 4.0)), // 3: small
        Triangle::new(p(0.0, 0.0, 4.0), p(6.0, 0.0, 4.0), p(0.0, 6.0, 4.0)), // 4: middle
        Triangle::new(p(1.0, 1.0, 4.0), p(1.0, 5.0, 4.0), p(5.0, 1.0, 4.0)), // 5: flipped
        Triangle::new(p(0.5, 0.5, 4.0), p(7.0, 0.5, 4.0), p(0.5, 7.0, 4.0)), // 6
    ];
    let mut rng = Rng::new(51);
    for i in 0..200 {
        // Clutter above and below, never between z = 3 and z = 5 where the rays run.
        let mut c = rng.vec3(0.5, 7.5);
        c.z = rng.range(0.5, 1.5) + if i % 2 == 0 { 6.0 } else { 0.0 };
        tris.push(Triangle::new(
            c,
            c + rng.vec3(-0.1, 0.1),
            c + rng.vec3(-0.1, 0.1),
        ));
    }
    let mesh = Mesh::from_triangles(tris);
    let tree = Octree::build(
        &mesh,
        &OctreeOptions {
            leaf_size: 2,
            ..OctreeOptions::default()
        },
    )
    .unwrap();
    let mid = tree.cube().center();
    assert!((mid.z - 4.0).abs() < 1e-3, "{:?}", tree.cube());
    let mut rays = Vec::new();
    for _ in 0..1500 {
        let x = (rng.u64() % 64) as f32 / 8.0 + 1.0 / 16.0;
        let y = (rng.u64() % 64) as f32 / 8.0 + 1.0 / 16.0;
        let up = rng.u64().is_multiple_of(2);
        let (z, dz) = if up { (3.0, 1.0) } else { (5.0, -1.0) };
        let dz = dz * [1.0, 2.0, 0.5][(rng.u64() % 3) as usize];
        rays.push(Ray::new(p(x, y, z), p(0.0, 0.0, dz), 0.0, 3.4e38));
        rays.push(Ray::new(p(x, y, 8.0 - z), p(0.0, -0.0, -dz), 0.0, 3.4e38));
        // Along the mid-plane, from inside it.
        rays.push(Ray::new(p(x, y, 4.0), p(1.0, 0.5, 0.0), -0.25, 3.4e38));
    }
    check("coplanar at equal t", &mesh, &tree, &rays);
    let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
    let mut coplanar = 0;
    for (r, h) in rays.iter().zip(&hits) {
        // Rays in the plane (d.z = 0) meet the coplanar triangles edge-on: not judged here.
        if r.dir.z == 0.0 {
            continue;
        }
        // Where the oracle's answer is one of the coplanar triangles (2 to 6), its t is
        // exact in f32 too.
        let truth = oracle::closest(&mesh, r);
        assert_eq!(h.is_hit(), truth.is_some(), "{r:?}");
        if let Some((t, prim @ 2..=6)) = truth {
            assert_eq!((h.t as f64, h.prim), (t, prim), "{r:?}");
            coplanar += 1;
        }
    }
    println!("{coplanar} rays meet the coplanar triangles first");
    assert!(coplanar > 1000);
    assert_closest_is_brute_force("coplanar at equal t", &mesh, &tree, &rays);
}

#[test]
fn empty_mesh_and_single_triangle() {
    for mesh in [
        Mesh::default(),
        Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X)]),
    ] {
        let tree = oct(&mesh);
        assert_eq!(tree.stats().references, 0);
        assert!(tree.bounds().is_empty() && tree.cube().is_empty());
        let r = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, 3.4e38);
        let mut s = RayStats::default();
        let h = tree.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
        assert!(!h.is_hit() && s == RayStats::default());
    }
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )]);
    let tree = oct(&one);
    let r = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 1.0);
    let mut s = RayStats::default();
    let h = tree.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
    assert_eq!((h.prim, h.t), (0, 1.0));
    assert_eq!(s, RayStats { nodes: 1, tris: 1 });
    // A ray that misses the cube visits nothing.
    let r = Ray::new(Vec3::splat(5.0), Vec3::X, 0.0, 3.4e38);
    let mut s = RayStats::default();
    tree.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
    assert_eq!(s, RayStats::default());
}

#[test]
fn a_tree_at_the_depth_cap_traces_within_its_stack() {
    // Triangles shrinking geometrically towards a corner, with clutter, leaves of one
    // triangle and a cap above the largest: the tree reaches MAX_OCTREE_DEPTH.
    let mut rng = Rng::new(71);
    let mesh = shrinking_corner_by(&mut rng, 0.9);
    let opts = OctreeOptions {
        max_depth: 100,
        leaf_size: 1,
        traversal_cost: 1.0,
        ..OctreeOptions::default()
    };
    let tree = Octree::build(&mesh, &opts).unwrap();
    let s = tree.stats();
    println!("deep: {s:?}");
    assert_eq!(s.depth_cap, MAX_OCTREE_DEPTH);
    assert_eq!(s.max_depth, MAX_OCTREE_DEPTH, "{s:?}");
    let rays = corner_rays_by(&mut rng, &mesh, 0.9);
    check("deep", &mesh, &tree, &rays);
    assert_closest_is_brute_force("deep", &mesh, &tree, &rays);
}

/// Options that split every cell above the leaf size and the depth cap (no split test).
fn split_always(max_depth: usize, leaf_size: usize) -> OctreeOptions {
    OctreeOptions {
        max_depth,
        leaf_size,
        traversal_cost: f32::NEG_INFINITY,
        ..OctreeOptions::default()
    }
}

#[test]
fn the_memory_cap_refuses_with_an_error() {
    let mut rng = Rng::new(51);
    let mesh = needles(&mut rng, 2000);
    // Up front: not even the triangles fit.
    let tiny = OctreeOptions {
        max_bytes: Some(1024),
        ..OctreeOptions::default()
    };
    let e = Octree::build(&mesh, &tiny).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("2000 triangles") && e.contains("1.0 KiB") && e.contains("max_bytes"),
        "{e}"
    );
    // While building: the triangles fit, the duplicated references do not (every cell
    // split down to depth 6, whatever it costs).
    let always = split_always(6, 4);
    let fits = Octree::build(&mesh, &always).unwrap();
    let s = fits.stats();
    assert!(s.duplicated_references > 10_000, "needles: {s:?}");
    let base = 2000 * (40 + 72 + 4 + 12) + 8;
    let tight = OctreeOptions {
        max_bytes: Some(base + s.duplicated_references as u64 * 12 / 2),
        ..always
    };
    let e = Octree::build(&mesh, &tight).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("needs at least") && e.contains("OctreeOptions::max_bytes"),
        "{e}"
    );
    // With twice the room the finished tree's references and nodes take, it builds.
    let room = OctreeOptions {
        max_bytes: Some(base + 2 * (s.duplicated_references as u64 * 12 + s.nodes as u64 * 16)),
        ..always
    };
    assert_eq!(Octree::build(&mesh, &room).unwrap().stats(), s);
}

#[test]
fn stats_add_up() {
    let mut rng = Rng::new(61);
    let mesh = needles(&mut rng, 1000);
    for (cap, leaf) in [(2, 8), (6, 4), (7, 1), (40, 16)] {
        let tree = Octree::build(&mesh, &split_always(cap, leaf)).unwrap();
        let s = tree.stats();
        println!("cap {cap}, leaf {leaf}: {s:?}");
        assert_eq!(s.triangles, 1000);
        assert_eq!(s.depth_cap, cap.min(MAX_OCTREE_DEPTH));
        assert!(s.max_depth <= s.depth_cap && s.max_depth > 0);
        // Each inner node has 1 to 8 stored children and three planes.
        let inner = s.nodes - s.leaves;
        assert_eq!(tree.split_planes().len(), 3 * inner);
        assert!(s.nodes > inner && s.nodes - 1 <= 8 * inner);
        assert!(s.references >= s.triangles);
        assert_eq!(s.duplicated_references, s.references - s.triangles);
        assert!(s.largest_leaf >= s.references / s.leaves);
        // Leaves above the cap hold at most `leaf` triangles: only the cap stops a split.
        assert!(
            s.largest_leaf <= leaf || s.max_depth == s.depth_cap,
            "{s:?}"
        );
        assert_eq!(s.bytes, s.nodes * 8 + s.references * 4 + s.triangles * 40);
        // Every triangle is referenced where it is met: all rays still judged right.
        let rays = random_rays(&mut rng, 300, &mesh);
        check(
            &format!("needles, cap {cap}, leaf {leaf}"),
            &mesh,
            &tree,
            &rays,
        );
    }
    // The split test: needles, which every split copies into most children, are not split
    // at the default traversal cost; a soup of small triangles is.
    let s = oct(&mesh).stats();
    assert!(s.references < 2 * s.triangles, "{s:?}");
    let s = oct(&soup(&mut rng, 1000, 0.05)).stats();
    assert!(s.max_depth >= 3 && s.leaves > 50, "{s:?}");
    // Excluded triangles are left out; indices stay the original ones.
    let mut tris = soup(&mut rng, 300, 0.2).triangles;
    tris[5] = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::X);
    tris[17].v[1] = Vec3::NAN;
    let mesh = Mesh::from_triangles(tris);
    let tree = oct(&mesh);
    assert_eq!(tree.stats().triangles, 298);
    assert_eq!(tree.bounds(), mesh.bounds());
    let rays = random_rays(&mut rng, 1000, &mesh);
    check("with excluded triangles", &mesh, &tree, &rays);
}

#[test]
fn duplicated_references_are_counted() {
    // Two corner triangles make the bounds [-1, 1]³, so the root cube's centre is the origin
    // (up to the margin's rounding). Eight small triangles, one inside each octant, and one
    // big triangle in the plane x = 0.5 across the whole upper-x half: with one level of
    // cells the small and corner ones are referenced once each, the big one by the four
    // upper-x octants.
    let mut tris = vec![
        Triangle::new(
            Vec3::splat(-1.0),
            Vec3::new(-0.95, -1.0, -1.0),
            Vec3::new(-1.0, -0.95, -1.0),
        ),
        Triangle::new(
            Vec3::splat(1.0),
            Vec3::new(0.95, 1.0, 1.0),
            Vec3::new(1.0, 0.95, 1.0),
        ),
        Triangle::new(
            Vec3::new(0.5, -0.9, -0.9),
            Vec3::new(0.5, 0.9, -0.9),
            Vec3::new(0.5, 0.0, 0.95),
        ),
    ];
    for c in 0..8 {
        let s = |a: u32| if c >> a & 1 == 1 { 0.5 } else { -0.5 };
        let o = Vec3::new(s(0) - 0.2, s(1), s(2));
        tris.push(Triangle::new(
            o,
            o + Vec3::new(0.1, 0.0, 0.0),
            o + Vec3::new(0.0, 0.1, 0.1),
        ));
    }
    let mesh = Mesh::from_triangles(tris);
    let one_level = OctreeOptions {
        max_depth: 1,
        leaf_size: 1,
        ..OctreeOptions::default()
    };
    let tree = Octree::build(&mesh, &one_level).unwrap();
    let s = tree.stats();
    println!("{s:?}");
    assert!(tree.cube().center().abs().max_element() < 1e-4);
    assert_eq!((s.nodes, s.leaves, s.max_depth), (9, 8, 1));
    assert_eq!((s.references, s.duplicated_references), (14, 3));
    assert_eq!(
        s.largest_leaf, 3,
        "the (+, +, +) octant: small, corner and big"
    );
    let rays = random_rays(&mut Rng::new(5), 500, &mesh);
    check("one level", &mesh, &tree, &rays);
}

#[test]
fn the_mailbox_tests_a_triangle_once_per_ray() {
    // One big triangle in z = 0 under a lattice of small ones at z = 0.5: leaves of one
    // triangle split the cells down until the bottom layer holds the big triangle alone. A
    // ray along its plane, just above it, crosses many of those cells and tests it once.
    let mut tris = vec![Triangle::new(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(0.0, 10.0, 0.0),
    )];
    for i in 0..40 {
        for j in 0..40 {
            let c = Vec3::new(i as f32 * 0.25 + 0.1, j as f32 * 0.25 + 0.1, 0.5);
            tris.push(Triangle::new(
                c,
                c + Vec3::new(0.02, 0.0, 0.0),
                c + Vec3::new(0.0, 0.02, 0.01),
            ));
        }
    }
    let mesh = Mesh::from_triangles(tris);
    let tree = Octree::build(&mesh, &split_always(MAX_OCTREE_DEPTH, 1)).unwrap();
    let r = Ray::new(
        Vec3::new(0.2, 0.2, 0.01),
        Vec3::new(1.0, 1.0, 0.0),
        0.0,
        3.4e38,
    );
    let mut s = RayStats::default();
    let h = tree.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
    println!("{h:?} {s:?} {:?}", tree.stats());
    assert!(!h.is_hit());
    assert!(s.nodes > 20, "{s:?}");
    assert_eq!(s.tris, 1, "{s:?}");
    // Stats of one ray match trace_batch's.
    let (hits, stats) = tree.trace_batch(&[r], Query::Closest, &Robustness::default());
    assert_eq!((hits[0], stats[0]), (h, s));
}

#[test]
fn a_million_triangles_build_in_bounded_memory() {
    // A soup of 2²⁰ small triangles: the build's time and the tree's size, printed.
    let mut rng = Rng::new(91);
    let mesh = soup(&mut rng, 1 << 20, 0.004);
    let t = std::time::Instant::now();
    let tree = oct(&mesh);
    let s = tree.stats();
    println!(
        "2²⁰ triangles: built in {:.2} s, {:.1} MiB, {s:?}",
        t.elapsed().as_secs_f64(),
        s.bytes as f64 / 1048576.0
    );
    assert_eq!(s.triangles, 1 << 20);
    // Memory linear in the triangles: a few references each.
    assert!(s.references < 4 * s.triangles, "{s:?}");
    let rays = random_rays(&mut rng, 32, &mesh);
    assert_closest_is_brute_force("2²⁰ triangles", &mesh, &tree, &rays);
}

/// The octree's options against build time, size and speed on the bunny, beside the BVH
/// and the kd-tree: one thread, timed by its own CPU time, best of 3, on the 512² default
/// view and 2¹⁸ random rays. Variants as `depth:leaf:cost`, comma-separated, in
/// `OCTREE_VARIANTS`: `cargo test --release --test octree -- --ignored --nocapture
/// bunny_depth_leaf_and_cost`.
#[test]
#[ignore]
fn bunny_depth_leaf_and_cost() {
    use std::time::Instant;
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let primary = Camera::default_view(&mesh.bounds(), 512, 512).primary_rays();
    let random = random_rays(&mut Rng::new(17), 1 << 18, &mesh);
    let rob = Robustness::default();
    let mut all: Vec<(String, Box<dyn Accel>, String)> = Vec::new();
    for kind in [
        AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        AccelKind::KdTree,
    ] {
        let t = Instant::now();
        let a = build(kind, &mesh, &BuildOptions::default()).unwrap();
        let info = format!("build {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
        all.push((kind.to_string(), a, info));
    }
    let variants = std::env::var("OCTREE_VARIANTS").unwrap_or_else(|_| {
        "14:4:1,14:4:2,14:4:4,14:4:8,14:1:4,14:8:4,14:16:4,8:4:4,10:4:4,12:4:4".into()
    });
    for v in variants.split(',') {
        let f: Vec<f32> = v.split(':').map(|x| x.parse().unwrap()).collect();
        let opts = OctreeOptions {
            max_depth: f[0] as usize,
            leaf_size: f[1] as usize,
            traversal_cost: f[2],
            ..OctreeOptions::default()
        };
        let t = Instant::now();
        let tree = Octree::build(&mesh, &opts).unwrap();
        let s = tree.stats();
        let info = format!(
            "build {:.0} ms, {:.2} M refs, {:.1} MiB, depth {}, largest leaf {}",
            t.elapsed().as_secs_f64() * 1e3,
            s.references as f64 / 1e6,
            s.bytes as f64 / 1048576.0,
            s.max_depth,
            s.largest_leaf
        );
        all.push((format!("octree {v}"), Box::new(tree), info));
    }
    for (what, rays) in [("primary 512²", &primary), ("random 2¹⁸", &random)] {
        for (name, a, info) in &all {
            let mut best = f64::INFINITY;
            let (mut nodes, mut tris) = (0u64, 0u64);
            for _ in 0..3 {
                (nodes, tris) = (0, 0);
                let cpu0 = thread_cpu_ns();
                for r in rays.iter() {
                    let mut s = RayStats::default();
                    std::hint::black_box(a.intersect(r, Query::Closest, &rob, &mut s));
                    nodes += s.nodes as u64;
                    tris += s.tris as u64;
                }
                best = best.min((thread_cpu_ns() - cpu0) as f64 * 1e-9);
            }
            let n = rays.len() as f64;
            println!(
                "{what} | {name} | {:.2} Mrays/s | {:.1} cells | {:.1} tris | {info}",
                n / best / 1e6,
                nodes as f64 / n,
                tris as f64 / n
            );
        }
    }
}
