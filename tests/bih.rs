//! The BIH's own options and invariants (src/accel/bih); what every structure must do is in
//! tests/conformance.rs. Here: soups at every leaf size against the oracle, the BVH and brute
//! force; rays through shared edges on clip planes; axis-parallel rays on clip planes;
//! coincident triangles in leaves of one; the depth cap holds on inputs the global heuristic
//! would split deeper; the memory cap refuses instead of aborting; the arrays are what the
//! GPU will read (each triangle once, clip planes exactly the children's extents); the stats
//! add up.

#[path = "../benches/common.rs"]
mod bench_common;
mod common;

use common::accel_check::{
    assert_closest_is_brute_force, check, check_against, no_leaks_at_shared_edges, same_as_bvh,
    smallest_index_at_nearest_t,
};
use common::hard::{
    chain_centres, coincident_stacks, corner_cascade, edge_rays, grid, soup_on_a_grid,
    split_plane_rays, stack_rays,
};
use common::speed::{bvh_entrant, race, Entrant};
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bih::{Bih, BihNode, BihOptions, BIH_LEAF_TAG, MAX_BIH_DEPTH};
use lancer::accel::bvh::BuildOptions;
use lancer::accel::{build, Accel, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::{Aabb, Hit, Ray, Triangle};
use lancer::mesh::Mesh;
use lancer::trace::oracle::Truths;
use lancer::{Query, RayStats, Robustness};

fn bih(mesh: &Mesh) -> Bih {
    Bih::build(mesh, &BihOptions::default()).expect("BIH builds")
}

/// The BIH of `mesh` with the default options but leaves of at most `max_leaf` triangles.
fn bih_with_leaves(mesh: &Mesh, max_leaf: usize) -> Bih {
    let opts = BihOptions {
        max_leaf,
        ..BihOptions::default()
    };
    Bih::build(mesh, &opts).unwrap()
}

/// Checks the arrays' invariants: depth-first order (left child next, right child after
/// the left subtree), leaves covering the triangle array in order with 1..=`max_leaf`
/// triangles, each inner node's planes exactly the max / min of its children's triangles
/// on its axis (one-sided nodes: their child's, and ∓f32::MAX), depth within the cap, each
/// included triangle exactly once.
fn validate(mesh: &Mesh, tree: &Bih, max_leaf: usize) {
    let (nodes, tris) = (tree.nodes(), tree.triangles());
    let s = tree.stats();
    // Returns (index after the subtree, box of its triangles, next triangle position).
    fn walk(
        nodes: &[BihNode],
        tris: &[lancer::accel::LeafTri],
        i: usize,
        depth: usize,
        next_tri: usize,
        out: &mut (usize, usize, usize),
    ) -> (usize, Aabb, usize) {
        let n = nodes[i];
        out.0 = out.0.max(depth);
        if n.link & 3 == BIH_LEAF_TAG {
            let (first, count) = ((n.link >> 2) as usize, n.count as usize);
            assert_eq!(first, next_tri, "leaves cover the triangles in order");
            assert!(count >= 1);
            out.1 = out.1.max(count);
            let b = tris[first..first + count]
                .iter()
                .fold(Aabb::EMPTY, |b, t| b.union(t.triangle().bbox()));
            return (i + 1, b, first + count);
        }
        let k = n.axis();
        if n.index() == i + 1 {
            // One-sided: the child's extent on the kept side, ∓f32::MAX on the other.
            let (end, b, t) = walk(nodes, tris, i + 1, depth + 1, next_tri, out);
            out.2 += 1;
            match n.clip {
                [l, r] if r == f32::MAX => assert_eq!(l, b.hi[k], "node {i}: cut at the maximum"),
                [l, r] if l == -f32::MAX => assert_eq!(r, b.lo[k], "node {i}: cut at the minimum"),
                c => panic!("node {i}: a one-sided node with planes {c:?}"),
            }
            assert_eq!(n.count, 0);
            return (end, b, t);
        }
        let (end_left, lb, t) = walk(nodes, tris, i + 1, depth + 1, next_tri, out);
        assert_eq!(
            n.index(),
            end_left,
            "node {i}: right child after the left subtree"
        );
        let (end, rb, t) = walk(nodes, tris, end_left, depth + 1, t, out);
        assert_eq!(
            n.clip[0], lb.hi[k],
            "node {i}: left plane = left child's maximum"
        );
        assert_eq!(
            n.clip[1], rb.lo[k],
            "node {i}: right plane = right child's minimum"
        );
        assert_eq!(n.count, 0);
        (end, lb.union(rb), t)
    }
    if tris.is_empty() {
        assert_eq!(
            nodes,
            &[BihNode {
                clip: [0.0; 2],
                link: BIH_LEAF_TAG,
                count: 0
            }]
        );
        return;
    }
    let mut shape = (0, 0, 0);
    let (end, b, t) = walk(nodes, tris, 0, 0, 0, &mut shape);
    assert_eq!((end, t), (nodes.len(), tris.len()));
    assert_eq!(b, tree.bounds());
    assert_eq!(shape, (s.max_depth, s.largest_leaf, s.cuts));
    assert!(s.max_depth <= s.depth_cap && s.depth_cap <= MAX_BIH_DEPTH);
    assert!(s.largest_leaf <= max_leaf.max(1), "{s:?}");
    let mut prims: Vec<u32> = tris.iter().map(|t| t.prim).collect();
    prims.sort_unstable();
    assert_eq!(
        prims,
        mesh.included(),
        "each included triangle exactly once"
    );
    for t in tris {
        assert_eq!(t.triangle(), mesh.triangles[t.prim as usize]);
    }
    assert_eq!(
        s.nodes,
        2 * s.leaves - 1 + s.cuts,
        "a full binary tree and the cuts"
    );
    assert_eq!(s.triangles, tris.len());
    assert_eq!(s.bytes, nodes.len() * 16 + tris.len() * 48);
}

#[test]
fn random_soups_against_the_oracle_and_the_bvh() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        for max_leaf in [1, 4] {
            let tree = bih_with_leaves(&mesh, max_leaf);
            validate(&mesh, &tree, max_leaf);
            let name = format!("soup {seed}, leaves ≤ {max_leaf}");
            let (agree, _) = check(&name, &mesh, &tree, &rays);
            assert!(agree > 2500);
            assert_eq!(same_as_bvh(&name, &mesh, &tree, &rays), 0);
            assert_closest_is_brute_force(&name, &mesh, &tree, &rays);
        }
    }
}

#[test]
fn parallel_build_equals_serial_build() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let par = bih(&mesh);
    let ser = Bih::build(
        &mesh,
        &BihOptions {
            parallel: false,
            ..BihOptions::default()
        },
    )
    .unwrap();
    assert_eq!(par.stats(), ser.stats());
    assert_eq!(par.nodes(), ser.nodes());
    assert_eq!(par.triangles(), ser.triangles());
}

#[test]
fn rays_at_shared_edges_and_vertices_never_leak() {
    let (mesh, targets) = grid(24, 0.37);
    for max_leaf in [1, 4] {
        let tree = bih_with_leaves(&mesh, max_leaf);
        assert!(tree.stats().nodes > 100, "the plane is split");
        let mut rng = Rng::new(11);
        let c = mesh.bounds().center();
        let rays = edge_rays(&mut rng, c, &targets);
        // Where two triangles meet at the ray, equal t goes to the smaller index even when
        // the two sit in different leaves.
        no_leaks_at_shared_edges("plane edges", &mesh, &tree, &rays);
    }
}

#[test]
fn axis_parallel_rays_on_clip_planes() {
    let mut rng = Rng::new(21);
    let mesh = soup_on_a_grid(&mut rng);
    let tree = bih(&mesh);
    // Both planes of every node: the left child's maximum and the right child's minimum.
    let planes: Vec<(usize, f32)> = tree
        .clip_planes()
        .into_iter()
        .flat_map(|(k, l, r)| [(k, l), (k, r)])
        .collect();
    assert!(planes.len() > 200);
    let rays = split_plane_rays(&mut rng, &mesh, &planes, 4000);
    check("axis-parallel on clip planes", &mesh, &tree, &rays);
    same_as_bvh("axis-parallel on clip planes", &mesh, &tree, &rays);
    assert_closest_is_brute_force("axis-parallel on clip planes", &mesh, &tree, &rays);
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // k copies of one triangle at several depths, indices interleaved between the stacks,
    // among random triangles: the answer must be the smallest index at the nearest t.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    // Leaves of one triangle put every copy in a leaf of its own (median splits).
    for max_leaf in [1, 4] {
        let tree = bih_with_leaves(&mesh, max_leaf);
        validate(&mesh, &tree, max_leaf);
        let rays = stack_rays(&mut rng, 2000);
        let truths = Truths::new(&mesh, &rays);
        let (hits, _) = tree.trace_batch(&rays, Query::Closest, &Robustness::default());
        let exact = smallest_index_at_nearest_t("the BIH", &truths, &hits);
        println!(
            "coincident, leaves ≤ {max_leaf}: {exact} of {} rays exactly the oracle's index",
            rays.len()
        );
        assert!(exact > 1800);
        check_against("coincident", &truths, &tree);
        assert_closest_is_brute_force("coincident", &mesh, &tree, &rays);
    }
}

#[test]
fn the_depth_cap_holds_and_keeps_leaves_small() {
    let mut rng = Rng::new(71);
    let mesh = corner_cascade(&mut rng);
    let mut rays = random_rays(&mut rng, 1000, &mesh);
    // Rays at the small triangles from every side, from nearby (at a distance like their
    // size: from afar, f32 cannot aim at a triangle 1e-11 across).
    let chain = chain_centres();
    for i in 0..600 {
        let (c, a) = if i % 2 == 0 {
            let s = 0.85f32.powi((i % 300) as i32 / 3);
            (Vec3::splat(1.1 * s), s)
        } else {
            chain[i % chain.len()]
        };
        let o = c + rng.dir() * 4.0 * a;
        rays.push(Ray::new(o, (c - o).normalize(), 0.0, 3.4e38));
    }
    for (max_depth, max_leaf) in [(None, 1), (Some(200), 4), (Some(12), 2), (Some(5), 4)] {
        let opts = BihOptions {
            max_depth,
            max_leaf,
            ..BihOptions::default()
        };
        let tree = Bih::build(&mesh, &opts).unwrap();
        let s = tree.stats();
        println!("cascade, cap {max_depth:?}, leaves ≤ {max_leaf}: {s:?}");
        assert_eq!(s.depth_cap, max_depth.unwrap_or(64).min(MAX_BIH_DEPTH));
        assert!(s.max_depth <= s.depth_cap, "{s:?}");
        if max_depth == Some(5) {
            // A cap too low for leaves of max_leaf: the leaves at the cap hold more.
            assert_eq!(s.max_depth, 5);
            assert!(s.largest_leaf > max_leaf);
        } else {
            validate(&mesh, &tree, max_leaf);
            assert!(s.median_splits > 0, "the cap forced median splits: {s:?}");
            assert!(s.max_depth > s.depth_cap - 8, "{s:?}");
        }
        let name = format!("cascade, cap {max_depth:?}");
        let (agree, _) = check(&name, &mesh, &tree, &rays);
        assert!(agree > 1000);
        assert_closest_is_brute_force(&name, &mesh, &tree, &rays);
    }
}

#[test]
fn a_million_identical_triangles() {
    // Centres that halving cannot separate: every split is a median split, the tree stays
    // within the cap with leaves of max_leaf, and the answer is still the smallest index.
    let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let mesh = Mesh::from_triangles(vec![t; 1_000_000]);
    let start = std::time::Instant::now();
    let tree = bih(&mesh);
    let s = tree.stats();
    println!("1M identical: {s:?}, built in {:?}", start.elapsed());
    assert_eq!(s.triangles, 1_000_000);
    assert_eq!(s.median_splits, s.nodes - s.leaves);
    assert!(s.largest_leaf <= 4 && s.max_depth <= 20, "{s:?}");
    assert_eq!((s.nodes, s.cuts), (2 * s.leaves - 1, 0));
    let r = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 0.0, 10.0);
    let mut st = RayStats::default();
    let h = tree.intersect(&r, Query::Closest, &Robustness::default(), &mut st);
    assert_eq!((h.prim, h.t), (0, 1.0));
    // Every copy is at the same t: none may be cut, each is tested once.
    assert_eq!(st.tris, 1_000_000);
    assert_eq!(st.nodes as usize, s.nodes);
    let mut st = RayStats::default();
    let h = tree.intersect(&r, Query::Any, &Robustness::default(), &mut st);
    assert!(h.is_hit() && st.tris <= 4);
}

#[test]
fn the_memory_cap_refuses_with_an_error() {
    let mut rng = Rng::new(51);
    let mesh = soup(&mut rng, 2000, 0.3);
    let tiny = BihOptions {
        max_memory: Some(1024),
        ..BihOptions::default()
    };
    let e = Bih::build(&mesh, &tiny).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("2000 triangles") && e.contains("1.0 KiB") && e.contains("max_memory"),
        "{e}"
    );
    // The estimate is the limit: exactly it builds, a byte less is refused.
    let peak = BihOptions::peak_bytes(2000) as u64;
    let at = |m: u64| {
        Bih::build(
            &mesh,
            &BihOptions {
                max_memory: Some(m),
                ..BihOptions::default()
            },
        )
    };
    assert!(at(peak).is_ok());
    assert!(at(peak - 1).is_err());
    // The estimate covers the tree built.
    let s = at(peak).unwrap().stats();
    assert!(s.bytes as u64 <= peak, "{s:?} vs {peak}");
}

#[test]
fn stats_add_up() {
    let Some(mesh) = load_model("teapot.obj") else {
        return;
    };
    let tree = bih(&mesh);
    let s = tree.stats();
    let mut rng = Rng::new(61);
    let mut rays = Camera::default_view(&mesh.bounds(), 32, 32).primary_rays();
    rays.extend(random_rays(&mut rng, 1000, &mesh));
    for query in [Query::Closest, Query::Any] {
        let (hits, stats) = tree.trace_batch(&rays, query, &Robustness::default());
        for ((r, h), st) in rays.iter().zip(&hits).zip(&stats) {
            assert!(st.nodes >= 1, "the root's box test counts: {r:?}");
            // A tree: each node visited at most once, each triangle tested at most once.
            assert!(st.nodes as usize <= s.nodes && st.tris as usize <= s.triangles);
            if h.is_hit() {
                assert!(st.tris >= 1);
            }
            let mut one = RayStats::default();
            let h1: Hit = tree.intersect(r, query, &Robustness::default(), &mut one);
            assert_eq!(
                (h1, one),
                (*h, *st),
                "a single ray's stats match the batch's"
            );
        }
        let (n, t) = RayStats::means(&stats);
        println!("teapot {query:?}: {n:.1} nodes, {t:.1} triangle tests per ray");
    }
    // One leaf: every ray that meets the box visits one node and tests every triangle.
    let opts = BihOptions {
        max_leaf: usize::MAX,
        ..BihOptions::default()
    };
    let flat = Bih::build(&mesh, &opts).unwrap();
    assert_eq!(flat.stats().nodes, 1);
    let (_, stats) = flat.trace_batch(&rays, Query::Closest, &Robustness::default());
    for st in stats {
        assert!(st.nodes == 1 && (st.tris == 0 || st.tris as usize == s.triangles));
    }
    // Excluded triangles are left out; indices stay the original ones.
    let mut tris = soup(&mut rng, 300, 0.2).triangles;
    tris[5] = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::X);
    tris[17].v[1] = Vec3::NAN;
    let mesh = Mesh::from_triangles(tris);
    let tree = bih(&mesh);
    validate(&mesh, &tree, 4);
    assert_eq!(tree.stats().triangles, 298);
    assert_eq!(tree.bounds(), mesh.bounds());
    let rays = random_rays(&mut rng, 1000, &mesh);
    check("with excluded triangles", &mesh, &tree, &rays);
}

#[test]
fn registered_as_an_accel_kind() {
    assert!(AccelKind::ALL.contains(&AccelKind::Bih));
    assert_eq!(AccelKind::Bih.name(), "bih");
    let mut rng = Rng::new(81);
    let mesh = soup(&mut rng, 300, 0.2);
    let a = build(AccelKind::Bih, &mesh, &BuildOptions::default()).unwrap();
    let rays = random_rays(&mut rng, 300, &mesh);
    let rob = Robustness::default();
    assert_eq!(
        a.trace_batch(&rays, Query::Closest, &rob),
        bih(&mesh).trace_batch(&rays, Query::Closest, &rob)
    );
}

/// Mrays/s of the BIH beside the BVH and the kd-tree on the bunny's 1024² default view and
/// 2²⁰ random rays, 2 threads, best of 5 alternating rounds, for several leaf sizes (`BIH_LEAVES=1,2,4,8`);
/// then build time on 10⁶-triangle meshes:
/// `cargo test --release --test bih -- --ignored --nocapture`.
#[test]
#[ignore]
fn bunny_speed_and_million_builds() {
    use lancer::accel::kdtree::KdTree;
    use std::time::Instant;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    pool.install(|| {
        if let Some(mesh) = load_model("stanford-bunny.obj") {
            let rays = Camera::default_view(&mesh.bounds(), 1024, 1024).primary_rays();
            let mut all: Vec<Entrant> = vec![bvh_entrant(&mesh)];
            let t = Instant::now();
            let kd = KdTree::build(&mesh, &Default::default()).unwrap();
            all.push(("kdtree".into(), Box::new(kd), t.elapsed().as_secs_f64()));
            let leaves = std::env::var("BIH_LEAVES").unwrap_or_else(|_| "1,2,4,8".into());
            for l in leaves.split(',') {
                let opts = BihOptions {
                    max_leaf: l.parse().unwrap(),
                    ..BihOptions::default()
                };
                let t = Instant::now();
                let tree = Bih::build(&mesh, &opts).unwrap();
                let b = t.elapsed().as_secs_f64();
                println!("bih, leaves ≤ {l}: {:?}", tree.stats());
                all.push((format!("bih, leaves ≤ {l}"), Box::new(tree), b));
            }
            let mut rng = Rng::new(17);
            let incoherent = random_rays(&mut rng, 1 << 20, &mesh);
            let sets = [
                ("primary 1024²", &rays[..]),
                ("random 2²⁰", &incoherent[..]),
            ];
            race(&all, &sets, 5, |b| format!("{:.1} ms", b * 1e3));
        }
        let mut rng = Rng::new(5);
        for (name, mesh) in [
            ("soup 10⁶", soup(&mut rng, 1_000_000, 0.01)),
            ("terrain 10⁶", bench_common::terrain(1_000_000)),
        ] {
            for parallel in [false, true] {
                let opts = BihOptions {
                    parallel,
                    ..BihOptions::default()
                };
                let t = Instant::now();
                let tree = Bih::build(&mesh, &opts).unwrap();
                println!(
                    "{name}, parallel {parallel}: build {:.1} ms, estimate {:.1} MiB, {:?}",
                    t.elapsed().as_secs_f64() * 1e3,
                    BihOptions::peak_bytes(mesh.len()) as f64 / (1 << 20) as f64,
                    tree.stats()
                );
            }
            let (_, bvh, secs) = bvh_entrant(&mesh);
            println!(
                "{name}: the default BVH builds (and flattens) in {:.1} ms",
                secs * 1e3,
            );
            drop(bvh);
        }
    });
}
