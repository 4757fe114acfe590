//! The `cwbvh` layout (src/accel/bvh/layouts/cwbvh): its CPU twin against the f64 oracle and against
//! `dfs-sign` (closest and any hit) on the bunny, soups, shared edges and vertices,
//! coincident triangles, binary leaves bigger than a wide node and a deep tree; every
//! dequantised child box contains its exact box (and is not loose); `validate` refuses
//! corrupted arrays. Hand-made chains whose stacks fill to their depth trace alike on the
//! GPU and the twin (the kernel sizes its stack to the tree). GPU ≡ twin on everything else
//! is tests/gpu_vs_cpu.rs (every layout).

mod common;

use std::sync::Arc;

use common::accel_check::check;
use common::gpu_twin::same_on_gpu;
use common::hard::height_field;
use common::{gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::{CwChild, Cwbvh, DfsSign};
use lancer::accel::bvh::{build, BuildOptions, Bvh, Node, MAX_DEPTH};
use lancer::accel::Accel;
use lancer::accel::{GpuArrays, GpuForm};
use lancer::camera::Camera;
use lancer::geometry::{Aabb, Hit, Precision, Ray, SlabTest, Triangle, TriangleTest, MISS};
use lancer::gpu::BvhMemory;
use lancer::mesh::Mesh;
use lancer::trace::oracle::{judge, judge_any, Verdict};
use lancer::{Query, RayStats, Robustness, Tracer, TracerOptions, TraversalMode};

fn cwbvh(mesh: &Mesh, opts: &BuildOptions) -> Cwbvh {
    let layout = Cwbvh::flatten(&build(mesh, opts), mesh);
    layout
        .validate()
        .unwrap_or_else(|e| panic!("invalid layout: {e}"));
    layout
}

/// The closest hits equal dfs-sign's bit for bit (the same triangle test on the same ray),
/// except where the oracle names a tie for one of the two answers. Returns the differences.
fn same_as_dfs_sign(name: &str, mesh: &Mesh, layout: &Cwbvh, rays: &[Ray]) -> usize {
    let rob = Robustness::default();
    let dfs = DfsSign::flatten(&build(mesh, &BuildOptions::default()), mesh);
    let (a, sa) = layout.trace_batch(rays, Query::Closest, &rob);
    let (b, sb) = dfs.trace_batch(rays, Query::Closest, &rob);
    let mut differ = 0;
    for ((r, x), y) in rays.iter().zip(&a).zip(&b) {
        if bytemuck::bytes_of(x) == bytemuck::bytes_of(y) {
            continue;
        }
        differ += 1;
        let (vx, vy) = (judge(mesh, r, x), judge(mesh, r, y));
        assert!(
            x.prim != y.prim && (matches!(vx, Verdict::Tie(_)) || matches!(vy, Verdict::Tie(_))),
            "{name}: {r:?}: cwbvh {x:?} ({vx:?}) ≠ dfs-sign {y:?} ({vy:?})"
        );
    }
    let (na, ta) = RayStats::means(&sa);
    let (nb, tb) = RayStats::means(&sb);
    println!(
        "{name}: {differ} of {} differ from dfs-sign (ties); nodes/ray {na:.1} vs {nb:.1}, \
         triangles/ray {ta:.1} vs {tb:.1}",
        rays.len()
    );
    differ
}

#[test]
fn bunny_against_the_oracle_and_dfs_sign() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let layout = cwbvh(&mesh, &BuildOptions::default());
    let bytes = layout.bytes() as f64 / mesh.len() as f64;
    println!(
        "bunny: {} nodes, {} triangles, {bytes:.1} bytes/triangle",
        layout.node_count(),
        layout.triangles()
    );
    let mut rng = Rng::new(7);
    let rays = random_rays(&mut rng, 3000, &mesh);
    check("bunny random", &mesh, &layout, &rays[..200]);
    same_as_dfs_sign("bunny random", &mesh, &layout, &rays);
    let primary = Camera::default_view(&mesh.bounds(), 96, 96).primary_rays();
    let (agree, _) = check(
        "bunny primary",
        &mesh,
        &layout,
        &primary.iter().step_by(37).copied().collect::<Vec<_>>(),
    );
    assert!(agree > 100);
    same_as_dfs_sign("bunny primary", &mesh, &layout, &primary);
}

#[test]
fn random_soups_against_the_oracle_and_dfs_sign() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        let layout = cwbvh(&mesh, &BuildOptions::default());
        let (agree, _) = check(&format!("soup {seed}"), &mesh, &layout, &rays);
        assert!(agree > 2500);
        same_as_dfs_sign(&format!("soup {seed}"), &mesh, &layout, &rays);
    }
}

/// The layout is the same on one thread as on all (big subtrees are split, decided and
/// written side by side) and from the tree consumed (the tracer's flattening, which frees
/// the tree's nodes early), on trees with spatial splits (clipped leaves), with binary leaves
/// bigger than a wide leaf, and on one triangle.
#[test]
fn one_thread_and_all_threads_write_the_same_layout() {
    use lancer::accel::bvh::Builder;
    let mut rng = Rng::new(41);
    // 20,000 triangles: over the 16,384 from which subtrees go side by side.
    let mut meshes = vec![soup(&mut rng, 20_000, 0.4), soup(&mut rng, 1, 0.4)];
    meshes.extend(load_model("teapot.obj"));
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for mesh in &meshes {
        for (builder, max_leaf) in [
            (Builder::Sweep, 16),
            (Builder::Sbvh, 16),
            (Builder::Median, 8),
        ] {
            let opts = BuildOptions {
                builder,
                max_leaf,
                ..BuildOptions::default()
            };
            let bvh = build(mesh, &opts);
            let all = Cwbvh::flatten(&bvh, mesh);
            let serial = one_thread.install(|| Cwbvh::flatten(&bvh, mesh));
            let what = format!("{builder:?}, {} triangles", mesh.len());
            assert!(all == serial, "{what}: one thread differs");
            assert!(
                all == Cwbvh::flatten_owned(bvh, mesh),
                "{what}: owned differs"
            );
            all.validate().unwrap();
        }
    }
}

#[test]
fn no_ray_leaks_through_shared_edges_or_vertices() {
    let n = 16;
    let mesh = height_field(n);
    let layout = cwbvh(&mesh, &BuildOptions::default());
    let mut rays = Vec::new();
    // Through every vertex and along every edge line at quarter steps, from oblique and
    // axis-parallel directions: each ray crosses the height field inside its footprint.
    for i in 1..4 * n {
        for j in 1..4 * n {
            let (x, y) = (i as f32 / (4 * n) as f32, j as f32 / (4 * n) as f32);
            for d in [
                Vec3::new(0.1, 0.2, -1.0),
                Vec3::new(-0.3, 0.05, -1.0),
                Vec3::NEG_Z,
            ] {
                let target = Vec3::new(x, y, 0.3 * (x * n as f32 * 0.37).sin());
                rays.push(Ray::new(target - d * 5.0, d.normalize(), 0.0, 100.0));
            }
        }
    }
    let (hits, _) = layout.trace_batch(&rays, Query::Closest, &Robustness::default());
    let leaks = hits.iter().filter(|h| !h.is_hit()).count();
    assert_eq!(
        leaks,
        0,
        "{leaks} of {} rays leaked through the grid",
        rays.len()
    );
    check("grid", &mesh, &layout, &rays[..2000]);
}

/// `copies` copies of one triangle spanning [0, 1]² at z = 0.
fn copies(copies: usize) -> Mesh {
    let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    Mesh::from_triangles(vec![t; copies])
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // 60 copies fit one binary leaf with max_leaf 64: split into 20 wide leaves over three
    // nodes. 300 copies make a tree. Every hit must name copy 0, in any traversal order.
    for (n, max_leaf) in [(60, 64), (300, 16)] {
        let mesh = copies(n);
        let opts = BuildOptions {
            max_leaf,
            ..BuildOptions::default()
        };
        let layout = cwbvh(&mesh, &opts);
        let rays = Camera::default_view(&mesh.bounds(), 32, 24).primary_rays();
        let (hits, _) = layout.trace_batch(&rays, Query::Closest, &Robustness::default());
        let hit = hits.iter().filter(|h| h.is_hit()).count();
        assert!(hit > 100, "{n} copies: only {hit} hits");
        let wrong: Vec<u32> = (hits.iter())
            .filter(|h| h.is_hit() && h.prim != 0)
            .map(|h| h.prim)
            .collect();
        assert!(wrong.is_empty(), "{n} copies: hits on {wrong:?}");
        check(&format!("{n} copies"), &mesh, &layout, &rays);
    }
}

/// Deepest leaf of a binary tree, and its largest leaf.
fn depth_and_biggest_leaf(node: &Node, depth: usize) -> (usize, u32) {
    match node {
        Node::Leaf { count, .. } => (depth, *count),
        Node::Inner { children, .. } => {
            let (a, b) = depth_and_biggest_leaf(&children[0], depth + 1);
            let (c, d) = depth_and_biggest_leaf(&children[1], depth + 1);
            (a.max(c), b.max(d))
        }
    }
}

/// Wide depth (root = 0) of every node, from the layout's own child lists.
fn wide_depth(layout: &Cwbvh) -> usize {
    let mut stack = vec![(0usize, 0usize)];
    let mut deepest = 0;
    while let Some((i, d)) = stack.pop() {
        deepest = deepest.max(d);
        for (_, _, c) in layout.children(i) {
            if let CwChild::Node(c) = c {
                stack.push((c as usize, d + 1));
            }
        }
    }
    deepest
}

#[test]
fn binary_leaves_bigger_than_a_node_are_split() {
    // A high node cost makes the SAH keep up to 200 triangles in a leaf.
    let mut rng = Rng::new(91);
    let mesh = soup(&mut rng, 3000, 0.1);
    let opts = BuildOptions {
        max_leaf: 200,
        t_cube: 40.0,
        ..BuildOptions::default()
    };
    let bvh: Bvh = build(&mesh, &opts);
    let (_, biggest) = depth_and_biggest_leaf(bvh.root(), 0);
    assert!(
        biggest > 24,
        "the biggest binary leaf holds {biggest} triangles"
    );
    let layout = Cwbvh::flatten(&bvh, &mesh);
    layout.validate().unwrap();
    for i in 0..layout.node_count() {
        let mut in_node = 0;
        for (_, _, c) in layout.children(i) {
            if let CwChild::Tris { count, .. } = c {
                assert!((1..=3).contains(&count), "node {i}: a leaf of {count}");
                in_node += count;
            }
        }
        assert!(in_node <= 24, "node {i} holds {in_node} triangles");
    }
    let rays = random_rays(&mut rng, 2000, &mesh);
    check("big leaves", &mesh, &layout, &rays);
}

/// Triangles shrinking towards the origin by 0.78 each (the last ~1e-7 of the first: the
/// f64 oracle cannot judge much smaller ones from afar).
fn shrinking(n: i32) -> Vec<Triangle> {
    (0..n)
        .map(|i| {
            let s = 0.78f32.powi(i);
            let c = Vec3::splat(s);
            Triangle::new(
                c,
                c + Vec3::new(0.3 * s, 0.0, 0.0),
                c + Vec3::new(0.0, 0.3 * s, 0.1 * s),
            )
        })
        .collect()
}

#[test]
fn a_binary_chain_at_the_depth_cap_collapses_and_traces() {
    // Built by hand: leaf i (triangle i) beside the chain of the rest, leaves 63 and 64 at
    // depth MAX_DEPTH = 64, the deepest tree a builder may hand over.
    let tris = shrinking(65);
    let mesh = Mesh::from_triangles(tris.clone());
    let leaf = |i: usize| Node::Leaf {
        bbox: tris[i].bbox(),
        start: i as u32,
        count: 1,
    };
    let mut root = leaf(64);
    for i in (0..64).rev() {
        root = Node::parent(0, [leaf(i), root]);
    }
    let bvh = Bvh::new(root, (0..65).collect(), &mesh).unwrap();
    assert_eq!(depth_and_biggest_leaf(bvh.root(), 0).0, MAX_DEPTH);
    let layout = Cwbvh::flatten(&bvh, &mesh);
    layout.validate().unwrap();
    let wide = wide_depth(&layout);
    println!("chain: binary depth {MAX_DEPTH}, wide depth {wide}");
    assert!(wide < MAX_DEPTH / 2, "wide depth {wide}");
    let mut rng = Rng::new(71);
    let mut rays = random_rays(&mut rng, 500, &mesh);
    // Rays at the small triangles from every side, from nearby.
    for i in 0..1000 {
        let s = 0.78f32.powi(i % 65);
        let target = Vec3::splat(s * 1.05);
        let o = target + rng.dir() * 4.0 * s;
        rays.push(Ray::new(o, (target - o).normalize(), 0.0, 3.4e38));
    }
    let (agree, _) = check("chain", &mesh, &layout, &rays);
    assert!(agree > 500);
}

/// One raw node record (mod.rs CwNode): frame origin 0, step 1 on every axis, every
/// occupied slot's box [0, 255]³.
fn raw_node(imask: u8, child_base: u32, tri_base: u32, meta: [u8; 8]) -> Vec<u8> {
    let mut n = vec![0u8; NODE];
    n[12..15].copy_from_slice(&[127; 3]);
    n[IMASK] = imask;
    n[CHILD_BASE..CHILD_BASE + 4].copy_from_slice(&child_base.to_le_bytes());
    n[TRI_BASE..TRI_BASE + 4].copy_from_slice(&tri_base.to_le_bytes());
    n[META..META + 8].copy_from_slice(&meta);
    for (s, &m) in meta.iter().enumerate() {
        if m != 0 {
            for axis in 0..3 {
                n[Q_HI + 8 * axis + s] = 255;
            }
        }
    }
    n
}

/// A chain of `levels` nodes, each with two internal children in slots 0 and 1: the next
/// chain node and a side node holding one triangle (the last chain node holds one too).
/// Every box contains every triangle, so a ray visits all nodes; one whose direction has
/// x ≥ 0 descends the chain first and stacks one group per level. The side triangles cover
/// the chain's whole square, or with `banded` a strip each: side k (at z = k) spans
/// x ∈ [3(k − 1), 3k], so a ray from below along such a strip meets that side first.
fn raw_chain(levels: usize, banded: bool) -> (Mesh, Vec<u8>, Vec<u8>) {
    const INNER: u8 = 1 << 5 | 24;
    const ONE_TRI: u8 = 1 << 5;
    let mut nodes = Vec::new();
    let mut tris = Vec::new();
    let mut mesh = Vec::new();
    let mut tri = |z: f32, x: Option<f32>| {
        let t = match x {
            None => Triangle::new(
                Vec3::new(0.0, 0.0, z),
                Vec3::new(200.0, 0.0, z),
                Vec3::new(0.0, 200.0, z),
            ),
            Some(x) => Triangle::new(
                Vec3::new(x, 0.0, z),
                Vec3::new(x + 3.0, 0.0, z),
                Vec3::new(x, 200.0, z),
            ),
        };
        let prim = mesh.len() as u32;
        mesh.push(t);
        tris.extend_from_slice(bytemuck::bytes_of(&lancer::accel::LeafTri {
            v0: t.v[0].into(),
            prim,
            v1: t.v[1].into(),
            pad1: 0,
            v2: t.v[2].into(),
            pad2: 0,
        }));
        prim
    };
    // Chain node k at 2k − 1 (k ≥ 1), its children (chain k + 1, side k) at 2k + 1, 2k + 2.
    let mut side_tris = Vec::new();
    for k in 0..levels - 1 {
        side_tris.push(tri(1.0 + k as f32, banded.then_some(3.0 * k as f32)));
    }
    let last = tri(100.0, None);
    for k in 0..levels {
        if k + 1 < levels {
            let base = 2 * k as u32 + 1;
            nodes.extend(raw_node(
                0b11,
                base,
                0,
                [INNER, INNER + 1, 0, 0, 0, 0, 0, 0],
            ));
        } else {
            nodes.extend(raw_node(0, 0, last, [ONE_TRI, 0, 0, 0, 0, 0, 0, 0]));
        }
        if k >= 1 {
            let t = side_tris[k - 1];
            nodes.extend(raw_node(0, 0, t, [ONE_TRI, 0, 0, 0, 0, 0, 0, 0]));
        }
    }
    (Mesh::from_triangles(mesh), nodes, tris)
}

#[test]
fn the_group_stack_holds_one_group_per_level_and_no_more() {
    // Deepest nodes at depth 64: accepted, and traced with a full stack.
    let (mesh, nodes, tris) = raw_chain(MAX_DEPTH + 1, false);
    let layout = Cwbvh::from_arrays(GpuArrays::new(&nodes, &tris)).unwrap();
    assert_eq!(layout.node_count(), 2 * MAX_DEPTH + 1);
    let rob = Robustness::default();
    for dir in [Vec3::new(0.01, 0.02, -1.0), Vec3::new(-0.01, 0.02, -1.0)] {
        let r = Ray::new(Vec3::new(10.0, 10.0, 250.0), dir.normalize(), 0.0, 1e30);
        for query in [Query::Closest, Query::Any] {
            let mut s = RayStats::default();
            let h = layout.intersect(&r, query, &rob, &mut s);
            let v = match query {
                Query::Closest => judge(&mesh, &r, &h),
                Query::Any => judge_any(&mesh, &r, &h),
            };
            assert_eq!(v, Verdict::Agree, "{dir} {query:?}: {h:?}");
            if query == Query::Closest {
                assert_eq!(h.prim, mesh.len() as u32 - 1);
                assert_eq!(s.nodes as usize, layout.node_count());
            }
        }
    }
    // One level more: refused.
    let (_, nodes, tris) = raw_chain(MAX_DEPTH + 2, false);
    let e = Cwbvh::from_arrays(GpuArrays::new(&nodes, &tris)).unwrap_err();
    assert!(e.contains("depth 65"), "{e}");
}

#[test]
fn chains_fill_the_kernels_stack_to_their_depth_on_the_gpu() {
    // The kernel keeps four groups in variables and sizes its array for the rest to the
    // tree's depth: chains whose stacks end at, just past and far past the four, and at the
    // cap. The GPU must give the twin's hits and work ray for ray, with and without bounds
    // checks (a trusted module relies on the size; a short array loses or overwrites the
    // deepest groups, and the rays then skip the side leaves they wait for).
    for levels in [4, 5, 6, 7, 12, MAX_DEPTH + 1] {
        let (mesh, nodes, tris) = raw_chain(levels, true);
        let arrays = GpuArrays::new(&nodes, &tris);
        let cw = Cwbvh::from_arrays(arrays).unwrap();
        // From below, up along each side's strip (x ≥ 0: the chain first): each ray's
        // closest hit is its strip's side, at the depth of its level's group.
        let mut rng = Rng::new(levels as u64);
        let rays: Vec<Ray> = (0..8 * levels)
            .map(|i| {
                let x = 3.0 * (i % (levels - 1)) as f32 + rng.range(0.3, 1.5);
                let o = Vec3::new(x, rng.range(10.0, 80.0), -20.0);
                let dir = Vec3::new(rng.range(0.0, 1e-3), rng.range(-1e-3, 1e-3), 1.0);
                Ray::new(o, dir.normalize(), 0.0, 1e30)
            })
            .collect();
        // The twin visits every node and finds each ray's own strip's side.
        let (hits, stats) = cw.trace_batch(&rays, Query::Closest, &Robustness::default());
        let all = cw.node_count() as u32;
        assert!(
            stats.iter().all(|s| s.nodes == all),
            "{levels} levels: {stats:?}"
        );
        for (r, h) in rays.iter().zip(&hits) {
            assert_eq!(judge(&mesh, r, h), Verdict::Agree, "{levels} levels: {r:?}");
            let strip = (h.t - 20.0 - (h.prim + 1) as f32).abs() < 0.1;
            assert!(strip, "{levels} levels: {r:?} {h:?}");
        }
        // The GPU: the same hits and work, ray for ray, both memories, both queries.
        let layout: Arc<dyn GpuForm> = Arc::new(cw);
        for checked_module in [true, false] {
            let rob = Robustness {
                checked_module,
                ..Robustness::default()
            };
            let name = format!("{levels} levels, checked {checked_module}");
            same_on_gpu(&name, &layout, &rays, rob);
            // The subgroup kernel keeps the same stack for the union of its lanes' walks,
            // which fills it at least as deep: the twin's closest hits, bit for bit.
            for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
                let options = TracerOptions {
                    memory,
                    mode: TraversalMode::Subgroup,
                    robustness: rob,
                    ..TracerOptions::default()
                };
                let mut gpu = Tracer::with_layout(gpu_device(), layout.clone(), &options).unwrap();
                let got = gpu.trace(&rays, Query::Closest).unwrap();
                let what = format!("{name} {memory:?} subgroup");
                assert_eq!(got.mode, TraversalMode::Subgroup, "{what}");
                assert_eq!(got.cpu_retraced, 0, "{what}: rays cut short by the driver");
                assert!(
                    bits(&hits) == bits(&got.hits),
                    "{what}: hits differ from the twin's"
                );
            }
        }
    }
}

/// Exact box of every node's subtree (union of its triangles' boxes), by node index.
fn exact_boxes(layout: &Cwbvh) -> Vec<Aabb> {
    fn walk(layout: &Cwbvh, i: usize, out: &mut Vec<Aabb>) -> Aabb {
        let mut b = Aabb::EMPTY;
        for (_, _, c) in layout.children(i) {
            b = b.union(exact_child(layout, c, out));
        }
        out[i] = b;
        b
    }
    fn exact_child(layout: &Cwbvh, c: CwChild, out: &mut Vec<Aabb>) -> Aabb {
        match c {
            CwChild::Node(n) => walk(layout, n as usize, out),
            CwChild::Tris { first, count } => (layout.leaf_tris()
                [first as usize..(first + count) as usize])
                .iter()
                .fold(Aabb::EMPTY, |b, t| b.union(t.triangle().bbox())),
        }
    }
    let mut out = vec![Aabb::EMPTY; layout.node_count()];
    walk(layout, 0, &mut out);
    out
}

/// Every dequantised child box contains the exact box of the child's triangles, and on
/// each side lies within two steps of it (a step is at most 2/255 of the parent's extent).
fn check_quantised_boxes(name: &str, layout: &Cwbvh) -> usize {
    let exact = exact_boxes(layout);
    let mut children = 0;
    for (i, parent) in exact.iter().enumerate() {
        let slack = parent.extent() * (4.0 / 255.0) + parent.lo.abs().max(parent.hi.abs()) * 1e-6;
        for (s, q, c) in layout.children(i) {
            let e = match c {
                CwChild::Node(n) => exact[n as usize],
                CwChild::Tris { first, count } => (layout.leaf_tris()
                    [first as usize..(first + count) as usize])
                    .iter()
                    .fold(Aabb::EMPTY, |b, t| b.union(t.triangle().bbox())),
            };
            assert!(
                q.contains(&e),
                "{name}: node {i} slot {s}: quantised {q:?} does not contain {e:?}"
            );
            assert!(
                (e.lo - q.lo).cmple(slack).all() && (q.hi - e.hi).cmple(slack).all(),
                "{name}: node {i} slot {s}: quantised {q:?} is loose around {e:?}"
            );
            children += 1;
        }
    }
    children
}

#[test]
fn every_quantised_child_box_contains_its_exact_box() {
    let mut meshes = Vec::new();
    if let Some(bunny) = load_model("stanford-bunny.obj") {
        meshes.push(("bunny", bunny));
    }
    let mut rng = Rng::new(5);
    meshes.push(("soup", soup(&mut rng, 3000, 0.2)));
    // Far from the origin, small triangles: deep nodes' steps near the f32 spacing there.
    let far = soup(&mut rng, 2000, 0.05).triangles.into_iter();
    let far = far.map(|t| Triangle::new(t.v[0] + 3e3, t.v[1] + 3e3, t.v[2] + 3e3));
    meshes.push(("far", Mesh::from_triangles(far.collect())));
    // Flat in z and spanning negative and positive coordinates, some zero-extent axes.
    meshes.push(("grid", height_field(24)));
    let axis = (0..500).map(|i| {
        let x = i as f32 * 0.01 - 2.5;
        Triangle::new(
            Vec3::new(x, 0.0, 0.0),
            Vec3::new(x + 0.005, 0.0, 0.0),
            Vec3::new(x, 0.0, 1.0),
        )
    });
    meshes.push(("axis-aligned", Mesh::from_triangles(axis.collect())));
    for (name, mesh) in &meshes {
        let layout = cwbvh(mesh, &BuildOptions::default());
        let n = check_quantised_boxes(name, &layout);
        println!("{name}: {n} child boxes checked");
        assert!(n >= mesh.included().len() / 3);
    }
    let mut rng = Rng::new(6);
    let far = &meshes.iter().find(|(n, _)| *n == "far").unwrap().1;
    let rays = random_rays(&mut rng, 1000, far);
    check("far", far, &cwbvh(far, &BuildOptions::default()), &rays);
}

#[test]
fn the_triangles_are_a_permutation_keeping_original_indices() {
    let mut rng = Rng::new(12);
    let mut tris = soup(&mut rng, 1000, 0.2).triangles;
    tris[7] = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::X); // degenerate: left out
    let mesh = Mesh::from_triangles(tris);
    let layout = cwbvh(&mesh, &BuildOptions::default());
    let mut prims: Vec<u32> = layout.leaf_tris().iter().map(|t| t.prim).collect();
    prims.sort_unstable();
    let want: Vec<u32> = (0..1000).filter(|&i| i != 7).collect();
    assert_eq!(prims, want);
    for t in layout.leaf_tris() {
        assert_eq!(t.triangle(), mesh.triangles[t.prim as usize]);
    }
    assert_eq!(layout.bounds(), mesh.bounds());
}

#[test]
fn empty_mesh_single_triangle_and_invalid_rays() {
    let empty = cwbvh(&Mesh::default(), &BuildOptions::default());
    assert!(empty.bounds().is_empty());
    let rob = Robustness::default();
    let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, 0.0, 10.0);
    let mut s = RayStats::default();
    assert!(!empty.intersect(&r, Query::Closest, &rob, &mut s).is_hit());
    assert_eq!(s, RayStats { nodes: 1, tris: 0 });
    let one = cwbvh(&copies(1), &BuildOptions::default());
    let h = one.intersect(&r, Query::Closest, &rob, &mut s);
    assert_eq!((h.prim, h.t, h.u, h.v), (0, 1.0, 0.25, 0.25));
    let mut rng = Rng::new(2);
    let mesh = soup(&mut rng, 500, 0.2);
    let layout = cwbvh(&mesh, &BuildOptions::default());
    for r in [
        Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X, 0.0, 10.0),
        Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 10.0),
        Ray::new(Vec3::ZERO, Vec3::X, 5.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0), 0.0, 10.0),
    ] {
        let mut s = RayStats::default();
        let h: Hit = layout.intersect(&r, Query::Closest, &rob, &mut s);
        assert!(!h.is_hit() && s == RayStats::default(), "{r:?}");
    }
}

/// Byte offsets in a node record (mod.rs CwNode).
const NODE: usize = 80;
const CHILD_BASE: usize = 16;
const TRI_BASE: usize = 20;
const META: usize = 24;
const IMASK: usize = 15;
const Q_HI: usize = 56;

#[test]
fn validate_refuses_corrupted_arrays() {
    let mut rng = Rng::new(33);
    let mesh = soup(&mut rng, 2000, 0.2);
    let layout = cwbvh(&mesh, &BuildOptions::default());
    let a = layout.arrays();
    let (nodes, tris) = (a.nodes.to_vec(), a.tris.to_vec());
    let back = Cwbvh::from_arrays(GpuArrays::new(&nodes, &tris)).unwrap();
    assert_eq!(back.arrays().nodes, a.nodes);
    // A node with a leaf slot and one with an internal slot.
    let (leaf_node, leaf_slot) = (0..layout.node_count())
        .find_map(|i| {
            let c = layout.children(i);
            let s = c.iter().find(|(_, _, c)| matches!(c, CwChild::Tris { .. }));
            s.map(|&(s, _, _)| (i, s))
        })
        .unwrap();
    let refuse = |what: &str, nodes: &[u8], tris: &[u8]| {
        let e = Cwbvh::from_arrays(GpuArrays::new(nodes, tris))
            .err()
            .unwrap_or_else(|| panic!("{what}: accepted"));
        println!("{what}: {e}");
    };
    let with = |at: usize, bytes: &[u8]| {
        let mut n = nodes.clone();
        n[at..at + bytes.len()].copy_from_slice(bytes);
        n
    };
    refuse(
        "root's children at 0",
        &with(CHILD_BASE, &0u32.to_le_bytes()),
        &tris,
    );
    refuse(
        "children past the end",
        &with(CHILD_BASE, &(layout.node_count() as u32).to_le_bytes()),
        &tris,
    );
    let at = leaf_node * NODE;
    refuse(
        "triangles past the end",
        &with(at + TRI_BASE, &(tris.len() as u32 / 48).to_le_bytes()),
        &tris,
    );
    refuse(
        "a non-unary count",
        &with(at + META + leaf_slot, &[0b010_00000]),
        &tris,
    );
    let imask = nodes[at + IMASK] | 1 << leaf_slot;
    refuse("a leaf marked internal", &with(at + IMASK, &[imask]), &tris);
    refuse("a torn node", &nodes[..nodes.len() - 1], &tris);
    refuse("a missing triangle", &nodes, &tris[..tris.len() - 48]);
    refuse("no nodes", &[], &tris);
}

/// Hits as bytes: equal means bit for bit.
fn bits(hits: &[Hit]) -> Vec<u8> {
    hits.iter()
        .flat_map(|h| bytemuck::bytes_of(h).to_vec())
        .collect()
}

#[test]
fn batch_walks_answer_as_single_walks() {
    // `trace_hits` walks two rays at a time (and in AVX2 lanes where the CPU has them);
    // `trace_batch` walks each alone. Random, primary, axis-parallel and invalid rays, both
    // queries, every triangle test.
    let mut rng = Rng::new(11);
    let mut meshes = vec![("soup", soup(&mut rng, 2000, 0.2))];
    if let Some(bunny) = load_model("stanford-bunny.obj") {
        meshes.push(("bunny", bunny));
    }
    for (name, mesh) in &meshes {
        let layout = cwbvh(mesh, &BuildOptions::default());
        let mut rays = random_rays(&mut rng, 2000, mesh);
        rays.extend(Camera::default_view(&mesh.bounds(), 48, 48).primary_rays());
        let c = mesh.bounds().center();
        for (k, d) in [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(1.0, 1.0, 0.0)]
            .iter()
            .enumerate()
        {
            let origin = c - 3.0 * *d + Vec3::new(0.01, 0.02, 0.0) * k as f32;
            rays.push(Ray::new(origin, *d, 0.0, 1e6));
        }
        rays.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, 1e6));
        rays.push(Ray::new(c, Vec3::ZERO, 0.0, 1e6));
        let robust = Robustness::default();
        let settings = [
            ("robust", robust),
            (
                "moller-trumbore",
                Robustness {
                    triangle_test: TriangleTest::MollerTrumbore,
                    ..robust
                },
            ),
            (
                "plain slabs",
                Robustness {
                    slab_test: SlabTest::Plain,
                    ..robust
                },
            ),
            (
                "f64",
                Robustness {
                    precision: Precision::F64,
                    ..robust
                },
            ),
        ];
        for (test, rob) in settings {
            for query in [Query::Closest, Query::Any] {
                let (single, _) = layout.trace_batch(&rays, query, &rob);
                let batch = layout.trace_hits(&rays, query, &rob);
                let hit = single.iter().filter(|h| h.prim != MISS);
                println!("{name} {test} {query:?}: {} hits", hit.count());
                assert!(
                    bits(&single) == bits(&batch),
                    "{name} {test} {query:?}: batch and single walks differ"
                );
            }
        }
    }
}
