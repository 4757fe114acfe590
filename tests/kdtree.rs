//! The kd-tree's own options and invariants (src/accel/kdtree); what every structure must
//! do is in tests/conformance.rs. Here: parallel and serial builds are one tree;
//! axis-parallel rays on split planes; coincident triangles keep the tie rule under other
//! SAH constants; a tree at the depth cap; the memory cap refuses instead of aborting; the
//! stats add up.

mod common;

use common::accel_check::{
    assert_closest_is_brute_force, check, check_against, same_as_bvh, smallest_index_at_nearest_t,
};
use common::hard::{
    coincident_stacks, corner_rays, kd_tree_at_the_depth_cap, needles, soup_on_a_grid,
    split_plane_rays, stack_rays,
};
use common::speed::{bvh_entrant, race, Entrant};
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::kdtree::{KdOptions, KdTree, MAX_KD_DEPTH};
use lancer::accel::Accel;
use lancer::camera::Camera;
use lancer::geometry::{Hit, Triangle};
use lancer::mesh::Mesh;
use lancer::trace::oracle::Truths;
use lancer::{Query, RayStats, Robustness};

fn kd(mesh: &Mesh) -> KdTree {
    KdTree::build(mesh, &KdOptions::default()).expect("kd-tree builds")
}

#[test]
fn parallel_build_equals_serial_build() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let par = kd(&mesh);
    let ser = KdTree::build(
        &mesh,
        &KdOptions {
            parallel: false,
            ..KdOptions::default()
        },
    )
    .unwrap();
    assert_eq!(par.stats(), ser.stats());
    assert_eq!(par.split_planes(), ser.split_planes());
    let mut rng = Rng::new(3);
    let rays = random_rays(&mut rng, 500, &mesh);
    let rob = Robustness::default();
    let (a, sa) = par.trace_batch(&rays, Query::Closest, &rob);
    let (b, sb) = ser.trace_batch(&rays, Query::Closest, &rob);
    assert_eq!(a, b);
    assert_eq!(sa, sb);
}

#[test]
fn axis_parallel_rays_on_split_planes() {
    let mut rng = Rng::new(21);
    let mesh = soup_on_a_grid(&mut rng);
    let tree = kd(&mesh);
    let planes = tree.split_planes();
    assert!(planes.len() > 100);
    let rays = split_plane_rays(&mut rng, &mesh, &planes, 4000);
    check("axis-parallel on split planes", &mesh, &tree, &rays);
    same_as_bvh("axis-parallel on split planes", &mesh, &tree, &rays);
    assert_closest_is_brute_force("axis-parallel on split planes", &mesh, &tree, &rays);
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // k copies of one triangle at several depths, indices interleaved between the stacks,
    // among random triangles: the answer must be the smallest index at the nearest t.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    for opts in [
        KdOptions::default(),
        KdOptions {
            intersection_cost: 20.0,
            empty_bonus: 1.0,
            ..KdOptions::default()
        },
    ] {
        let tree = KdTree::build(&mesh, &opts).unwrap();
        let rays = stack_rays(&mut rng, 2000);
        let truths = Truths::new(&mesh, &rays);
        let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
        let exact = smallest_index_at_nearest_t("the kd-tree", &truths, &hits);
        println!(
            "coincident: {exact} of {} rays exactly the oracle's index",
            rays.len()
        );
        assert!(exact > 1800);
        check_against("coincident", &truths, &tree);
        assert_closest_is_brute_force("coincident", &mesh, &tree, &rays);
    }
}

#[test]
fn a_tree_at_the_depth_cap_traces_within_its_stack() {
    // Triangles shrinking geometrically (to 1e-7) towards a corner, with clutter: the SAH keeps
    // splitting towards the corner until the cap, 64 levels asked for (more are refused).
    let mut rng = Rng::new(71);
    let (mesh, tree) = kd_tree_at_the_depth_cap(&mut rng);
    let s = tree.stats();
    println!("deep: {s:?}");
    assert_eq!(s.depth_cap, MAX_KD_DEPTH);
    let rays = corner_rays(&mut rng, &mesh);
    check("deep", &mesh, &tree, &rays);
    assert_closest_is_brute_force("deep", &mesh, &tree, &rays);
}

#[test]
fn the_memory_cap_refuses_with_an_error() {
    let mut rng = Rng::new(51);
    let mesh = needles(&mut rng, 2000);
    // Up front: not even the triangles fit.
    let tiny = KdOptions {
        max_memory: Some(1024),
        ..KdOptions::default()
    };
    let e = KdTree::build(&mesh, &tiny).unwrap_err().to_string();
    println!("{e}");
    assert!(e.contains("2000 triangles") && e.contains("1.0 KiB"), "{e}");
    // While building: the triangles fit, the duplicated references do not.
    let fits = KdTree::build(&mesh, &KdOptions::default()).unwrap();
    let dup = fits.stats().duplicated_references;
    assert!(dup > 400, "needles are duplicated: {:?}", fits.stats());
    for parallel in [false, true] {
        let tight = KdOptions {
            max_memory: Some(2000 * 150 + 20_000),
            parallel,
            ..KdOptions::default()
        };
        let e = KdTree::build(&mesh, &tight).unwrap_err().to_string();
        println!("{e}");
        assert!(
            e.contains("references so far") && e.contains("KdOptions::max_memory"),
            "{e}"
        );
    }
}

#[test]
fn stats_add_up() {
    let mut rng = Rng::new(61);
    let mesh = needles(&mut rng, 1000);
    for cap in [Some(3), Some(10), None] {
        let tree = KdTree::build(
            &mesh,
            &KdOptions {
                max_depth: cap,
                ..KdOptions::default()
            },
        )
        .unwrap();
        let s = tree.stats();
        println!("cap {cap:?}: {s:?}");
        assert_eq!(s.triangles, 1000);
        assert_eq!(s.nodes, 2 * s.leaves - 1, "a full binary tree");
        assert_eq!(tree.split_planes().len(), s.nodes - s.leaves);
        assert!(s.max_depth <= s.depth_cap && s.depth_cap <= MAX_KD_DEPTH);
        if let Some(c) = cap {
            assert_eq!(s.depth_cap, c);
        }
        assert!(s.references >= s.triangles);
        assert_eq!(s.duplicated_references, s.references - s.triangles);
        assert!(s.empty_leaves < s.leaves);
        assert!(s.bytes >= s.nodes * 8 + s.references * 4 + s.triangles * 36);
        // Every triangle is referenced at least once: all rays still judged right.
        let rays = random_rays(&mut rng, 500, &mesh);
        check(&format!("needles, cap {cap:?}"), &mesh, &tree, &rays);
    }
    // Excluded triangles are left out; indices stay the original ones.
    let mut tris = soup(&mut rng, 300, 0.2).triangles;
    tris[5] = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::X);
    tris[17].v[1] = Vec3::NAN;
    let mesh = Mesh::from_triangles(tris);
    let tree = kd(&mesh);
    assert_eq!(tree.stats().triangles, 298);
    assert_eq!(tree.bounds(), mesh.bounds());
    let rays = random_rays(&mut rng, 1000, &mesh);
    check("with excluded triangles", &mesh, &tree, &rays);
}

#[test]
fn stats_count_nodes_and_mailboxed_tests() {
    let Some(mesh) = load_model("teapot.obj") else {
        return;
    };
    let tree = kd(&mesh);
    let rays = Camera::default_view(&mesh.bounds(), 32, 32).primary_rays();
    let (hits, stats) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
    for ((r, h), s) in rays.iter().zip(&hits).zip(&stats) {
        assert!(s.nodes >= 1, "the root's box test counts: {r:?}");
        if h.is_hit() {
            assert!(s.tris >= 1);
        }
    }
    let (n, t) = RayStats::means(&stats);
    println!("teapot 32²: {n:.1} nodes, {t:.1} triangle tests per ray");
    // A single ray's stats match intersect's.
    let mut s = RayStats::default();
    let h: Hit = tree.intersect(&rays[500], Query::Closest, &Robustness::default(), &mut s);
    assert_eq!((h, s), (hits[500], stats[500]));
}

/// Mrays/s of the kd-tree and the BVH side by side on the bunny's 1024² default view, both
/// on 2 threads, best of 10 alternating rounds, then 2²⁰ random rays; also the kd-tree under
/// other settings (`KD_VARIANTS=K_I:λ:depth,…`): `cargo test --release --test kdtree -- --ignored --nocapture`.
#[test]
#[ignore]
fn bunny_speed_against_the_bvh() {
    use std::time::Instant;
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let rays = Camera::default_view(&mesh.bounds(), 1024, 1024).primary_rays();
    pool.install(|| {
        let mut all: Vec<Entrant> = vec![bvh_entrant(&mesh)];
        // Variants as K_I:λ:max_depth, comma-separated (0 = the automatic depth cap).
        let variants =
            std::env::var("KD_VARIANTS").unwrap_or_else(|_| "1.5:0.8:0,1:0.8:0,2:0.8:0".into());
        for v in variants.split(',') {
            let f: Vec<f32> = v.split(':').map(|x| x.parse().unwrap()).collect();
            let opts = KdOptions {
                intersection_cost: f[0],
                empty_bonus: f[1],
                max_depth: (f[2] > 0.0).then_some(f[2] as usize),
                ..KdOptions::default()
            };
            let t = Instant::now();
            let tree = KdTree::build(&mesh, &opts).unwrap();
            let b = t.elapsed().as_secs_f64();
            println!("kd {v}: {:?}", tree.stats());
            all.push((format!("kd K_I:λ:depth {v}"), Box::new(tree), b));
        }
        let mut rng = Rng::new(17);
        let incoherent = random_rays(&mut rng, 1 << 20, &mesh);
        let sets = [
            ("primary 1024²", &rays[..]),
            ("random 2²⁰", &incoherent[..]),
        ];
        race(&all, &sets, 10, |b| format!("{b:.3} s"));
    });
}
