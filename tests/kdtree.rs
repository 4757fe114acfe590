//! The kd-tree (src/accel/kdtree) against the f64 oracle and the BVH: every answer agrees
//! or is a genuine tie the oracle names; rays through shared edges and vertices never leak;
//! axis-parallel rays on split planes; coincident triangles keep the tie rule; the memory
//! cap refuses instead of aborting; the stats add up.

mod common;

use common::accel_check::{brute_force, check, same_as_bvh};
use common::hard::{
    coincident_stacks, corner_rays, extreme_rays, grid, invalid_rays, shrinking_corner,
    soup_on_a_grid, split_plane_rays, stack_rays,
};
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::BuildOptions;
use lancer::accel::kdtree::{KdOptions, KdTree, MAX_KD_DEPTH};
use lancer::accel::{build, Accel, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::{Hit, Ray, Triangle, TriangleTest};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, judge, Verdict};
use lancer::{Query, RayStats, Robustness};

fn kd(mesh: &Mesh) -> KdTree {
    KdTree::build(mesh, &KdOptions::default()).expect("kd-tree builds")
}

#[test]
fn random_soups_against_the_oracle_and_the_bvh() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        let tree = kd(&mesh);
        let (agree, _) = check(&format!("soup {seed}"), &mesh, &tree, &rays);
        assert!(agree > 2500);
        assert_eq!(same_as_bvh(&format!("soup {seed}"), &mesh, &tree, &rays), 0);
        let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
        assert_eq!(
            hits,
            brute_force(&mesh, &rays),
            "soup {seed}: kd ≠ brute force"
        );
    }
}

#[test]
fn models_primary_and_random_rays() {
    // The oracle and the brute force test every triangle per ray: fewer rays on the bunny
    // (69,451 triangles) than on the teapot; the BVH comparison takes many more.
    for (name, judged, side) in [("teapot.obj", 1000, 32), ("stanford-bunny.obj", 200, 16)] {
        let Some(mesh) = load_model(name) else { return };
        let tree = kd(&mesh);
        println!("{name}: {:?}", tree.stats());
        let mut rng = Rng::new(7);
        let rays = random_rays(&mut rng, 3000, &mesh);
        check(&format!("{name} random"), &mesh, &tree, &rays[..judged]);
        same_as_bvh(&format!("{name} random"), &mesh, &tree, &rays);
        let cam = Camera::default_view(&mesh.bounds(), side, side);
        let (agree, _) = check(
            &format!("{name} primary"),
            &mesh,
            &tree,
            &cam.primary_rays(),
        );
        assert!(agree > (side * side / 2) as usize);
        let cam = Camera::default_view(&mesh.bounds(), 96, 96);
        let primary = cam.primary_rays();
        assert_eq!(
            same_as_bvh(&format!("{name} primary"), &mesh, &tree, &primary),
            0
        );
        let some: Vec<Ray> = primary
            .iter()
            .step_by(9)
            .copied()
            .take(2 * judged)
            .collect();
        let (hits, _) = tree.trace_batch(&some, Query::Closest, &Robustness::default());
        assert_eq!(hits, brute_force(&mesh, &some), "{name}: kd ≠ brute force");
    }
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
fn rays_at_shared_edges_and_vertices_never_leak() {
    let (mesh, targets) = grid(24, 0.37);
    let tree = kd(&mesh);
    assert!(tree.stats().nodes > 1, "the grid is split");
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let mut rays = Vec::new();
    for &t in &targets {
        // From above and below at random angles, and straight down the z axis.
        for _ in 0..2 {
            let mut o = c + rng.dir() * 20.0;
            if rng.f32() < 0.5 {
                o.z = -o.z.abs() - 1.0;
            } else {
                o.z = o.z.abs() + 1.0;
            }
            rays.push(Ray::new(o, (t - o).normalize(), 0.0, 3.4e38));
        }
        rays.push(Ray::new(t + Vec3::Z * 5.0, -Vec3::Z, 0.0, 3.4e38));
        rays.push(Ray::new(t - Vec3::Z * 5.0, Vec3::Z, 0.0, f32::INFINITY));
    }
    let rob = Robustness::default();
    for query in [Query::Closest, Query::Any] {
        let (hits, _) = tree.trace_batch(&rays, query, &rob);
        let leaks = hits.iter().filter(|h| !h.is_hit()).count();
        println!("grid {query:?}: {} rays, {leaks} leaks", rays.len());
        assert_eq!(leaks, 0, "rays through shared edges and vertices leaked");
    }
    check("grid edges", &mesh, &tree, &rays);
    // Where two triangles meet at the ray, equal t goes to the smaller index even when the
    // two sit in different leaves (one on each side of a split plane).
    let (hits, _) = tree.trace_batch(&rays, Query::Closest, &rob);
    assert_eq!(hits, brute_force(&mesh, &rays), "grid: kd ≠ brute force");
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
    let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
    assert_eq!(
        hits,
        brute_force(&mesh, &rays),
        "axis-parallel: kd ≠ brute force"
    );
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
        let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
        let mut exact = 0;
        for (r, h) in rays.iter().zip(&hits) {
            let Some((_, prim)) = oracle::closest(&mesh, r) else {
                continue;
            };
            if h.prim == prim {
                exact += 1;
                continue;
            }
            let v = judge(&mesh, r, h);
            assert!(
                matches!(v, Verdict::Tie(_)) && v != Verdict::Tie("two hits at equal t"),
                "{r:?}: kd-tree reports {} but the oracle's smallest index at the nearest t is \
                 {prim} ({v:?})",
                h.prim
            );
        }
        println!(
            "coincident: {exact} of {} rays exactly the oracle's index",
            rays.len()
        );
        assert!(exact > 1800);
        check("coincident", &mesh, &tree, &rays);
        assert_eq!(
            hits,
            brute_force(&mesh, &rays),
            "coincident: kd ≠ brute force"
        );
    }
}

#[test]
fn invalid_and_extreme_rays_neither_hang_nor_panic() {
    let mut rng = Rng::new(41);
    let mesh = soup(&mut rng, 500, 0.3);
    let tree = kd(&mesh);
    let rob = Robustness::default();
    let invalid = invalid_rays();
    for r in &invalid {
        let mut s = RayStats::default();
        let h = tree.intersect(r, Query::Closest, &rob, &mut s);
        assert!(!h.is_hit());
        assert_eq!(s, RayStats::default(), "{r:?}");
    }
    let rays = extreme_rays(&mut rng, 3000);
    check("extreme rays", &mesh, &tree, &rays);
    let mut mt = rob;
    mt.triangle_test = TriangleTest::MollerTrumbore;
    let _ = tree.trace_batch(&rays, Query::Closest, &mt);
}

#[test]
fn empty_mesh_and_single_triangle() {
    let tree = kd(&Mesh::default());
    assert_eq!(tree.stats().references, 0);
    assert!(tree.bounds().is_empty());
    let r = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 1.0);
    let mut s = RayStats::default();
    assert!(!tree
        .intersect(&r, Query::Closest, &Robustness::default(), &mut s)
        .is_hit());
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )]);
    let tree = kd(&one);
    let h = tree.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
    assert_eq!((h.prim, h.t), (0, 1.0));
}

#[test]
fn a_tree_at_the_depth_cap_traces_within_its_stack() {
    // Triangles shrinking geometrically (to 1e-7) towards a corner, with clutter: the SAH keeps
    // splitting towards the corner until the cap, 64 levels asked for (more are refused).
    let mut rng = Rng::new(71);
    let mesh = shrinking_corner(&mut rng);
    let opts = KdOptions {
        max_depth: Some(200),
        intersection_cost: 20.0,
        ..KdOptions::default()
    };
    let tree = KdTree::build(&mesh, &opts).unwrap();
    let s = tree.stats();
    println!("deep: {s:?}");
    assert_eq!(s.depth_cap, MAX_KD_DEPTH);
    assert!(s.max_depth > 40 && s.max_depth <= MAX_KD_DEPTH, "{s:?}");
    let rays = corner_rays(&mut rng, &mesh);
    let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
    check("deep", &mesh, &tree, &rays);
    assert_eq!(hits, brute_force(&mesh, &rays), "deep: kd ≠ brute force");
}

/// `n` needles: thin triangles across the whole scene in random directions, which every
/// split duplicates.
fn needles(rng: &mut Rng, n: usize) -> Mesh {
    let tris = (0..n)
        .map(|_| {
            let a = rng.vec3(-1.0, 1.0);
            let b = -a + rng.vec3(-0.1, 0.1);
            Triangle::new(a, b, b + rng.vec3(-0.06, 0.06))
        })
        .collect();
    Mesh::from_triangles(tris)
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
    let rob = Robustness::default();
    pool.install(|| {
        let mut all: Vec<(String, Box<dyn Accel>, f64)> = Vec::new();
        let t = Instant::now();
        let bvh = build(
            AccelKind::Bvh(lancer::LayoutKind::DfsSign),
            &mesh,
            &BuildOptions::default(),
        )
        .unwrap();
        all.push(("bvh".into(), bvh, t.elapsed().as_secs_f64()));
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
        for (what, rays) in [("primary 1024²", &rays), ("random 2²⁰", &incoherent)] {
            let mut best = vec![0.0f64; all.len()];
            let mut work = vec![(0.0, 0.0); all.len()];
            for _ in 0..10 {
                for (i, (_, a, _)) in all.iter().enumerate() {
                    let t = Instant::now();
                    let (_, stats) = a.trace_batch(rays, Query::Closest, &rob);
                    let m = rays.len() as f64 / t.elapsed().as_secs_f64() / 1e6;
                    best[i] = best[i].max(m);
                    work[i] = RayStats::means(&stats);
                }
            }
            for (i, (name, _, b)) in all.iter().enumerate() {
                println!(
                    "{what}, {name}: {:.2} Mrays/s ({:.2}× the BVH), {:.1} nodes, {:.2} \
                     triangle tests per ray; build {b:.3} s",
                    best[i],
                    best[i] / best[0],
                    work[i].0,
                    work[i].1
                );
            }
        }
    });
}
