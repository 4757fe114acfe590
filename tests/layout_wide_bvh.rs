//! The `bvh4` and `bvh8` layouts (src/accel/bvh/layouts/wide_bvh), each test run for both widths: the
//! CPU twin against the f64 oracle (closest and any hit) and against `dfs-sign` (closest hits are independent of traversal order under the
//! tie rule, so they must be equal bit for bit) on the bunny, random soups, rays through
//! shared edges and vertices, axis-parallel rays on box planes and coincident triangles;
//! a tree built to fill the traversal stack exactly (twin and GPU); and `validate`
//! refusing corrupted trees.

mod common;

use std::sync::Arc;

use common::accel_check::{judge_hits, smallest_index_at_nearest_t};
use common::hard::{coincident_stacks, extreme_rays_up_to, grid, stack_rays};
use common::{gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions, Bvh, Node, MAX_DEPTH};
use lancer::accel::GpuForm;
use lancer::camera::Camera;
use lancer::geometry::{Aabb, Hit, Precision, Ray, Triangle};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, Truths};
use lancer::{Device, Query, RayStats, Robustness, Tracer, TracerOptions};

fn layout(kind: LayoutKind, mesh: &Mesh) -> Box<dyn GpuForm> {
    flatten(kind, &build(mesh, &BuildOptions::default()), mesh)
}

/// Judges the twin's closest and any-hit answers for every ray and fails on a wrong one;
/// returns the closest hits and their work.
fn check(name: &str, mesh: &Mesh, wide: &dyn GpuForm, rays: &[Ray]) -> (Vec<Hit>, Vec<RayStats>) {
    let rob = Robustness::default();
    let truths = Truths::new(mesh, rays);
    let mut closest = None;
    for query in [Query::Closest, Query::Any] {
        let (hits, stats) = wide.trace_batch(rays, query, &rob);
        // The batch without work records (what the tracer runs without --stats) is the
        // same traversal.
        assert!(
            hits.iter()
                .zip(wide.trace_hits(rays, query, &rob))
                .all(|(a, b)| *a == b),
            "{name}: trace_hits differs from trace_batch"
        );
        judge_hits(name, &truths, query, &hits);
        if query == Query::Closest {
            closest = Some((hits, stats));
        }
    }
    closest.unwrap_or_default()
}

/// The twin's closest hits equal dfs-sign's twin's, bit for bit.
fn same_as_dfs_sign(name: &str, mesh: &Mesh, wide: &dyn GpuForm, rays: &[Ray]) {
    let rob = Robustness::default();
    let dfs = layout(LayoutKind::DfsSign, mesh);
    let (a, _) = wide.trace_batch(rays, Query::Closest, &rob);
    let (b, _) = dfs.trace_batch(rays, Query::Closest, &rob);
    let differ: Vec<_> = (rays.iter().zip(a.iter().zip(&b)))
        .filter(|(_, (x, y))| bytemuck::bytes_of(*x) != bytemuck::bytes_of(*y))
        .collect();
    assert!(
        differ.is_empty(),
        "{name}: {} of {} rays differ from dfs-sign; first: {:?}",
        differ.len(),
        rays.len(),
        differ[0]
    );
}

fn random_soups(kind: LayoutKind) {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        let wide = layout(kind, &mesh);
        wide.validate().unwrap();
        let name = format!("soup {seed}");
        let (hits, _) = check(&name, &mesh, wide.as_ref(), &rays);
        assert!(hits.iter().filter(|h| h.is_hit()).count() > 1500);
        same_as_dfs_sign(&name, &mesh, wide.as_ref(), &rays);
    }
}

fn bunny_random_and_primary_rays(kind: LayoutKind) {
    // The oracle tests every triangle per ray: few rays judged, many compared.
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let wide = layout(kind, &mesh);
    let dfs = layout(LayoutKind::DfsSign, &mesh);
    wide.validate().unwrap();
    assert_eq!(wide.triangles(), mesh.len());
    let tris = wide.triangles() as f64;
    for l in [&wide, &dfs] {
        let nodes = l.arrays().nodes.len();
        println!(
            "bunny {}: {} nodes, {:.1} node bytes + 48 triangle bytes per triangle",
            l.name(),
            nodes / l.node_bytes(),
            nodes as f64 / tris
        );
    }
    let mut rng = Rng::new(7);
    let rays = random_rays(&mut rng, 3000, &mesh);
    check("bunny random", &mesh, wide.as_ref(), &rays[..150]);
    same_as_dfs_sign("bunny random", &mesh, wide.as_ref(), &rays);
    let cam = Camera::default_view(&mesh.bounds(), 24, 24);
    let (hits, _) = check("bunny primary", &mesh, wide.as_ref(), &cam.primary_rays());
    assert!(hits.iter().filter(|h| h.is_hit()).count() > 100);
    let primary = Camera::default_view(&mesh.bounds(), 96, 96).primary_rays();
    same_as_dfs_sign("bunny primary", &mesh, wide.as_ref(), &primary);
    let rob = Robustness::default();
    for (what, rays) in [("primary 96²", &primary), ("random", &rays)] {
        let (_, a) = wide.trace_batch(rays, Query::Closest, &rob);
        let (_, b) = dfs.trace_batch(rays, Query::Closest, &rob);
        let ((an, at), (bn, bt)) = (RayStats::means(&a), RayStats::means(&b));
        println!(
            "bunny {what}: {kind} {an:.1} nodes, {at:.1} triangles per ray; dfs-sign {bn:.1} \
             nodes, {bt:.1} triangles"
        );
    }
}

fn f64_precision_gives_the_oracles_answers(kind: LayoutKind) {
    // The shared leaf step's f64 test behind the wide layout's boxes: every closest hit is the
    // oracle's own (t rounded to f32, and its triangle), the misses its misses.
    let mut rng = Rng::new(51);
    let mesh = soup(&mut rng, 1500, 0.2);
    let rays = random_rays(&mut rng, 2000, &mesh);
    let f64 = Robustness {
        precision: Precision::F64,
        ..Robustness::default()
    };
    let (hits, _) = layout(kind, &mesh).trace_batch(&rays, Query::Closest, &f64);
    let unlike: Vec<_> = (rays.iter().zip(&hits))
        .filter(|(r, h)| match oracle::closest(&mesh, r) {
            None => h.is_hit(),
            Some((t, p)) => h.prim != p || h.t != t as f32,
        })
        .collect();
    let n_hits = hits.iter().filter(|h| h.is_hit()).count();
    assert!(n_hits > rays.len() / 4, "{n_hits} hits: too few to compare");
    assert!(
        unlike.is_empty(),
        "{} unlike the oracle, first {:?}",
        unlike.len(),
        unlike[0]
    );
}

fn rays_at_shared_edges_and_vertices_never_leak(kind: LayoutKind) {
    let (mesh, targets) = grid(24, 0.37);
    let wide = layout(kind, &mesh);
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let mut rays = Vec::new();
    for &t in &targets {
        let mut o = c + rng.dir() * 20.0;
        o.z = if rng.f32() < 0.5 { -1.0 } else { 1.0 } * (o.z.abs() + 1.0);
        rays.push(Ray::new(o, (t - o).normalize(), 0.0, 3.4e38));
        rays.push(Ray::new(t + Vec3::Z * 5.0, -Vec3::Z, 0.0, 3.4e38));
    }
    for query in [Query::Closest, Query::Any] {
        let (hits, _) = wide.trace_batch(&rays, query, &Robustness::default());
        let leaks = hits.iter().filter(|h| !h.is_hit()).count();
        assert_eq!(
            leaks, 0,
            "{query:?}: rays through shared edges and vertices leaked"
        );
    }
    check("grid edges", &mesh, wide.as_ref(), &rays);
    same_as_dfs_sign("grid edges", &mesh, wide.as_ref(), &rays);
}

fn axis_parallel_rays_on_box_planes(kind: LayoutKind) {
    // Node boxes are unions of triangle boxes: origins on vertex coordinates lie on box
    // planes. Directions with zero (and −0.0, and tiny) components take the slab test's
    // parallel-axis rule.
    let mut rng = Rng::new(21);
    let mut tris = soup(&mut rng, 1500, 0.25).triangles;
    tris.extend(grid(8, 0.25).0.triangles);
    let mesh = Mesh::from_triangles(tris);
    let wide = layout(kind, &mesh);
    let b = mesh.bounds();
    let mut rays = Vec::new();
    for i in 0..4000 {
        let v = mesh.triangles[rng.u64() as usize % mesh.len()].v[i % 3];
        let axis = (i / 3) % 3;
        let mut o = b.lo + (b.hi - b.lo) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
        o += rng.vec3(-0.3, 0.3) * (i % 2) as f32;
        o[axis] = v[axis];
        let mut d = Vec3::ZERO;
        match i % 4 {
            0 => d[(axis + 1 + (i / 4) % 2) % 3] = if rng.f32() < 0.5 { 1.0 } else { -1.0 },
            1 => d[axis] = if rng.f32() < 0.5 { 2.0 } else { -0.5 },
            2 => {
                d = rng.dir();
                d[axis] = [0.0, -0.0, 1e-31, -3e-30][(i / 4) % 4];
            }
            _ => {
                let w = mesh.triangles[rng.u64() as usize % mesh.len()].v[0];
                let a2 = (axis + 1) % 3;
                o[a2] = w[a2];
                d[rng.u64() as usize % 3] = 1.0;
            }
        }
        rays.push(Ray::new(o, d, 0.0, 3.4e38));
    }
    check("axis-parallel", &mesh, wide.as_ref(), &rays);
    same_as_dfs_sign("axis-parallel", &mesh, wide.as_ref(), &rays);
}

fn coincident_triangles_keep_the_tie_rule(kind: LayoutKind) {
    // Copies of one triangle at several depths, indices interleaved, among random
    // triangles: the answer is the smallest index at the nearest t, whichever child the
    // traversal visits first.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    // Small leaves: the copies spread over many leaves and nodes.
    let opts = BuildOptions {
        max_leaf: 2,
        ..BuildOptions::default()
    };
    let wide = flatten(kind, &build(&mesh, &opts), &mesh);
    let rays = stack_rays(&mut rng, 2000);
    let (hits, _) = check("coincident", &mesh, wide.as_ref(), &rays);
    let exact = smallest_index_at_nearest_t(&kind.to_string(), &Truths::new(&mesh, &rays), &hits);
    println!(
        "coincident: {exact} of {} rays exactly the oracle's index",
        rays.len()
    );
    assert!(exact > 1800);
    same_as_dfs_sign("coincident", &mesh, wide.as_ref(), &rays);
}

fn invalid_and_extreme_rays_neither_hang_nor_panic(kind: LayoutKind) {
    let mut rng = Rng::new(41);
    let mesh = soup(&mut rng, 500, 0.3);
    let wide = layout(kind, &mesh);
    let rob = Robustness::default();
    let invalid = [
        Ray::new(Vec3::NAN, Vec3::X, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::splat(1e-21), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 0.0, f32::NAN),
        Ray::new(Vec3::splat(1e13), -Vec3::ONE, 0.0, 1e30),
        Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0), 0.0, 1.0),
    ];
    for r in &invalid {
        let mut s = RayStats::default();
        let h = wide.intersect(r, Query::Closest, &rob, &mut s);
        assert!(!h.is_hit(), "{r:?}");
        assert_eq!(s, RayStats::default(), "{r:?}");
    }
    // Short directions among them, the largest component just above limits::MIN_DIR (the
    // shortest valid one: tests/hard_cases.rs checks that limit in every layout).
    let rays = extreme_rays_up_to(&mut rng, 3000, f32::MAX);
    check("extreme rays", &mesh, wide.as_ref(), &rays);
    same_as_dfs_sign("extreme rays", &mesh, wide.as_ref(), &rays);
}

fn empty_mesh_and_single_triangle(kind: LayoutKind) {
    let empty = layout(kind, &Mesh::default());
    empty.validate().unwrap();
    assert!(empty.bounds().is_empty());
    let r = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 1.0);
    let mut s = RayStats::default();
    let rob = Robustness::default();
    assert!(!empty.intersect(&r, Query::Closest, &rob, &mut s).is_hit());
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )]);
    let one = layout(kind, &one);
    one.validate().unwrap();
    let h = one.intersect(&r, Query::Closest, &rob, &mut s);
    assert_eq!((h.prim, h.t), (0, 1.0));
}

fn inner(a: Node, b: Node) -> Node {
    Node::parent(0, [a, b])
}

fn leaf(tris: &mut Vec<Triangle>, t: Triangle) -> Node {
    copies(tris, t, 1)
}

/// A leaf of `count` copies of `t`.
fn copies(tris: &mut Vec<Triangle>, t: Triangle, count: u32) -> Node {
    tris.extend(std::iter::repeat_n(t, count as usize));
    Node::Leaf {
        bbox: t.bbox(),
        start: tris.len() as u32 - count,
        count,
    }
}

/// A binary tree with leaves down to `depth`: a chain of inner nodes, each with the next
/// chain node and a sibling subtree of two or three leaves, all of whose boxes hold the
/// line y = z = 0.001, x ≥ 0; a ray along +x enters the chain's boxes first (at x = 0) and
/// the siblings' later (they lie at growing x). Every W-wide node on the chain then pushes
/// W − 1 entries. The chain's boxes are thin in x, so each sibling subtree is larger than
/// the chain node beside it, and the leaves of the three-leaf siblings hold five triangles
/// (too many to merge): the SAH collapse would keep one chain node per wide node, too
/// deep for the stack, and so would the greedy SAH choice alone; the greedy collapse's depth
/// rule pulls up log2(W) chain levels per wide node (with their siblings: 1 + log2(W)
/// slots), and its area rule spreads the largest siblings over the other slots (for bvh4 one
/// sibling's two parts; for bvh8 the two nearer siblings' three leaves each). The innermost
/// sibling has `innermost` leaves (2 or 3), of one triangle each: bvh4's deepest node holds
/// two binary levels, so 2; bvh8's three, so 3 (its 8 leaves fill the node).
fn stack_filler(depth: usize, innermost: usize) -> (Mesh, Bvh) {
    let (mesh, bvh) = stack_filler_tree(depth, innermost);
    (mesh, bvh.unwrap())
}

/// [`stack_filler`]'s tree as `Bvh::new` takes or refuses it.
fn stack_filler_tree(depth: usize, innermost: usize) -> (Mesh, lancer::Result<Bvh>) {
    let mut tris = Vec::new();
    let (mut x, mut y) = (1.0f32, 100.0f32);
    let first = leaf(
        &mut tris,
        Triangle::new(Vec3::ZERO, Vec3::new(x, y, 0.0), Vec3::new(0.0, 0.0, y)),
    );
    // n leaves of `count` copies of one triangle each, whose boxes are the slab x ∈ [x, 1.1x],
    // y, z ∈ [0, 1.1y].
    let mut slab = |tris: &mut Vec<Triangle>, n: usize, count: u32| {
        let (x0, x1, y1) = (x, 1.1 * x, 1.1 * y);
        (x, y) = (x1, y1);
        let v = |x, y, z| Vec3::new(x, y, z);
        let shapes = [
            [v(x0, 0.0, 0.0), v(x1, y1, 0.0), v(x0, 0.0, y1)],
            [v(x1, 0.0, 0.0), v(x0, y1, 0.0), v(x1, 0.0, y1)],
            [v(x0, 0.0, 0.0), v(x1, 0.0, y1), v(x0, y1, 0.0)],
        ];
        (shapes[..n].iter())
            .map(|&[a, b, c]| copies(tris, Triangle::new(a, b, c), count))
            .collect::<Vec<_>>()
    };
    // The innermost chain node has two leaves, at `depth`, its sibling `innermost`.
    let [a] = slab(&mut tris, 1, 1).try_into().unwrap();
    let mut node = inner(first, a);
    let sibling = match &slab(&mut tris, innermost, 1)[..] {
        [a, b] => inner(a.clone(), b.clone()),
        [a, b, c] => inner(inner(a.clone(), b.clone()), c.clone()),
        _ => unreachable!("2 or 3 leaves"),
    };
    node = inner(node, sibling);
    for _ in 0..depth - 2 {
        let [a, b, c] = slab(&mut tris, 3, 5).try_into().unwrap();
        node = inner(node, inner(inner(a, b), c));
    }
    let order = (0..tris.len() as u32).collect();
    let mesh = Mesh::from_triangles(tris);
    let bvh = Bvh::new(node, order, &mesh);
    (mesh, bvh)
}

fn a_tree_that_fills_the_stack_traces_on_twin_and_gpu(kind: LayoutKind) {
    // A binary chain of leaves at depth L·k ≤ MAX_DEPTH (L = log2(W) binary levels per
    // wide node), as deep as the builders allow with every wide node whole: k wide levels
    // from binary depths 0, L, …, each pushing W − 1 entries, 32 levels of 3 for bvh4 and
    // 21 of 7 for bvh8. The kernel's stack, sized to the tree's depth, is then full (96 and
    // 147 entries). validate bounds any tree by wide depth 63 / L (31 for bvh4, 21 for
    // bvh8; 96 and 154 entries); a chain one wide level deeper is refused.
    let l = match kind {
        LayoutKind::Bvh4 => 2,
        _ => 3,
    };
    let levels = MAX_DEPTH / l;
    let (mesh, bvh) = stack_filler(l * levels, l);
    let wide: Arc<dyn GpuForm> = flatten(kind, &bvh, &mesh).into();
    wide.validate().unwrap();
    let mut rays = Vec::new();
    for i in 0..64 {
        let o = Vec3::new(-0.5 - i as f32, 0.001, 0.001 + 0.01 * i as f32);
        rays.push(Ray::new(o, Vec3::X, 0.0, 3.4e38));
        rays.push(Ray::new(o, Vec3::new(1.0, 1e-6, -0.0), 0.0, 3.4e38));
        rays.push(Ray::new(o, Vec3::new(1.0, 1e-7, 1e-6), 0.0, 3.4e38));
    }
    let (hits, stats) = check("stack filler", &mesh, wide.as_ref(), &rays);
    for ((r, h), s) in rays.iter().zip(&hits).zip(&stats) {
        // The chain is walked to its end before any triangle is tested, the innermost
        // triangle hit first, and then every pushed entry is cut.
        assert_eq!(h.prim, 0, "{r:?}");
        assert_eq!((s.nodes, s.tris), (levels as u32, 1), "{r:?}");
    }
    same_as_dfs_sign("stack filler", &mesh, wide.as_ref(), &rays);
    // Rays from inside the chain's boxes, past the innermost triangle: the chain is walked
    // to its end as before (its boxes hold the origin, the siblings' lie ahead), but the
    // first hit lies in a pushed sibling, which the pops must find.
    let mut inside = Vec::new();
    for i in 0..64 {
        let o = Vec3::new(0.5, 0.001, 0.001 + 0.01 * i as f32);
        inside.push(Ray::new(o, Vec3::X, 0.0, 3.4e38));
        inside.push(Ray::new(o, Vec3::new(1.0, 1e-6, -0.0), 0.0, 3.4e38));
    }
    let (hits, stats) = check("stack filler, inside", &mesh, wide.as_ref(), &inside);
    for ((r, h), s) in inside.iter().zip(&hits).zip(&stats) {
        assert!(h.is_hit() && h.prim != 0, "{r:?}: {h:?}");
        assert!(s.nodes >= levels as u32, "{r:?}: {s:?}");
    }
    same_as_dfs_sign("stack filler, inside", &mesh, wide.as_ref(), &inside);
    rays.extend(inside);
    // The same walks on the GPU, its stack filled to the last entry: the twin's answers and
    // work (a kernel stack one entry short loses an entry the inside rays need).
    for query in [Query::Closest, Query::Any] {
        let options = TracerOptions {
            stats: true,
            ..TracerOptions::default()
        };
        let g = Tracer::with_layout(gpu_device(), wide.clone(), &options)
            .unwrap()
            .trace(&rays, query)
            .unwrap();
        let c = Tracer::with_layout(&Device::cpu(), wide.clone(), &options)
            .unwrap()
            .trace(&rays, query)
            .unwrap();
        assert_eq!(g.cpu_retraced, 0);
        assert_eq!(g.hits, c.hits, "{query:?}");
        assert_eq!(g.stats, c.stats, "{query:?}");
    }
    // The chain one wide level deeper (binary depth L · (63 / L + 1) + 1) is refused before
    // any flatten, as deeper than the stacks; a layout that deep from a file is refused by
    // validate, at exactly that wide depth (the layouts' unit test
    // `validate_refuses_a_layout_deeper_than_its_traversal_stack`).
    let deepest = (MAX_DEPTH - 1) / l + 1;
    let e = stack_filler_tree(l * deepest + 1, l)
        .1
        .unwrap_err()
        .to_string();
    assert!(e.contains(&format!("deeper than {MAX_DEPTH}")), "{e}");
}

fn validate_refuses_corrupted_trees(kind: LayoutKind) {
    let (mesh, bvh) = stack_filler(3, 2);
    let n = mesh.len() as u32;
    // Boxes are the layout's to check: a tree of any boxes is taken, its flattening refused.
    let refuse = |root: Node, order: Vec<u32>, want: &str| {
        let e = flatten(kind, &Bvh::new(root, order, &mesh).unwrap(), &mesh)
            .validate()
            .unwrap_err();
        assert!(e.contains(want), "{e}");
    };
    // The shape is the tree's: refused before any flatten.
    let misshapen = |root: Node, order: Vec<u32>, want: &str| {
        let e = Bvh::new(root, order, &mesh).unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    };
    let tri = mesh.triangles[0];
    let at = |start: u32, count: u32, bbox: Aabb| Node::Leaf { bbox, start, count };
    let good = bvh.root().clone();
    // A leaf past the end of the triangles.
    misshapen(
        inner(good.clone(), at(n, 2, tri.bbox())),
        (0..n).collect(),
        &format!("holds positions {n}..{} of an order of {n}", n + 2),
    );
    // A triangle outside its leaf's box.
    let far = Aabb {
        lo: Vec3::splat(5.0),
        hi: Vec3::splat(6.0),
    };
    refuse(at(0, n, far), (0..n).collect(), "lies outside the box");
    // A non-finite box.
    let nan = Aabb {
        lo: Vec3::NAN,
        hi: Vec3::ONE,
    };
    refuse(at(0, n, nan), (0..n).collect(), "non-finite box");
    // Positions in two leaves, and in none.
    let all = mesh.bounds();
    misshapen(
        inner(at(0, 2, all), at(1, 2, all)),
        (0..n).collect(),
        "the leaves before it end at 2",
    );
    misshapen(
        inner(at(0, 1, all), at(2, n - 2, all)),
        (0..n).collect(),
        "the leaves before it end at 1",
    );
    // And the good tree passes.
    flatten(kind, &bvh, &mesh).validate().unwrap();
}

/// Each test above as two tests, one per width: `bvh4::name` and `bvh8::name`.
macro_rules! for_both_widths {
    ($($name:ident),* $(,)?) => {
        mod bvh4 {
            $(#[test]
            fn $name() {
                super::$name(lancer::accel::bvh::layouts::LayoutKind::Bvh4);
            })*
        }
        mod bvh8 {
            $(#[test]
            fn $name() {
                super::$name(lancer::accel::bvh::layouts::LayoutKind::Bvh8);
            })*
        }
    };
}

for_both_widths!(
    random_soups,
    bunny_random_and_primary_rays,
    f64_precision_gives_the_oracles_answers,
    rays_at_shared_edges_and_vertices_never_leak,
    axis_parallel_rays_on_box_planes,
    coincident_triangles_keep_the_tie_rule,
    invalid_and_extreme_rays_neither_hang_nor_panic,
    empty_mesh_and_single_triangle,
    a_tree_that_fills_the_stack_traces_on_twin_and_gpu,
    validate_refuses_corrupted_trees,
);
