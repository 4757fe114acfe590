//! The three grids — uniform, two-level, hashed — against the f64 oracle (closest hit with
//! `judge`, any hit with `judge_any`) and against the BVH: random soups, the models, rays
//! aimed at shared edges and vertices, axis-parallel rays from cell boundaries, coincident
//! triangles (the tie rule), a small teapot in a big sparse stadium, rays that must neither
//! hang nor panic, and the memory cap. `bench_bunny` (ignored) prints build stats and
//! Mrays/s beside the BVH: `cargo test --release --test grids -- --ignored --nocapture`.

mod common;

use std::collections::HashMap;
use std::time::Instant;

use common::accel_check::default_bvh;
use common::speed::{bvh_entrant, thread_cpu_ns};
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::grid::{GridOptions, GridStats, HashedGrid, TwoLevelGrid, UniformGrid};
use lancer::camera::Camera;
use lancer::geometry::{Hit, Ray, Triangle, TriangleTest};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, judge, judge_any, Verdict};
use lancer::{Accel, Query, RayStats, Robustness};
use rayon::prelude::*;

/// A built grid, its name and its stats.
struct Built {
    name: &'static str,
    accel: Box<dyn Accel>,
    stats: GridStats,
}

fn grids(mesh: &Mesh, opts: &GridOptions) -> Vec<Built> {
    let u = UniformGrid::build(mesh, opts).expect("uniform grid builds");
    let t = TwoLevelGrid::build(mesh, opts).expect("two-level grid builds");
    let h = HashedGrid::build(mesh, opts).expect("hashed grid builds");
    vec![
        Built {
            name: "uniform",
            stats: u.stats(),
            accel: Box::new(u),
        },
        Built {
            name: "two-level",
            stats: t.stats(),
            accel: Box::new(t),
        },
        Built {
            name: "hashed",
            stats: h.stats(),
            accel: Box::new(h),
        },
    ]
}

/// Verdicts on distinct answers `(ray, prim, t bits)`, computed once each, in parallel.
fn verdicts(
    mesh: &Mesh,
    rays: &[Ray],
    answers: impl IntoIterator<Item = (usize, Hit)>,
    any: bool,
) -> HashMap<(usize, u32, u32), Verdict> {
    let mut keys: Vec<(usize, u32, u32)> = answers
        .into_iter()
        .map(|(i, h)| (i, h.prim, h.t.to_bits()))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    keys.into_par_iter()
        .map(|k| {
            let (r, h) = (&rays[k.0], Hit::miss(0.0));
            let h = Hit {
                t: f32::from_bits(k.2),
                prim: k.1,
                ..h
            };
            let v = if any {
                judge_any(mesh, r, &h)
            } else {
                judge(mesh, r, &h)
            };
            (k, v)
        })
        .collect()
}

fn key(i: usize, h: &Hit) -> (usize, u32, u32) {
    (i, h.prim, h.t.to_bits())
}

/// Per grid: answers judged right, answers that are genuine ties, rays where it and the BVH
/// differ (each a tie the oracle names), and its closest-hit stats.
#[derive(Debug, Default)]
struct Counts {
    agree: usize,
    ties: usize,
    bvh_differ: usize,
    hits: Vec<Hit>,
    stats: Vec<RayStats>,
}

/// Traces `rays` through the BVH and every grid (closest and any hit), judges every answer
/// against the oracle, fails on a wrong one or on a difference from the BVH that is not a
/// tie, and prints the counts.
fn check_with(name: &str, mesh: &Mesh, rays: &[Ray], opts: &GridOptions) -> Vec<Counts> {
    let rob = Robustness::default();
    let bvh = default_bvh(mesh);
    let (bvh_hits, _) = bvh.trace_batch(rays, Query::Closest, &rob);
    let built = grids(mesh, opts);
    let traced: Vec<_> = built
        .iter()
        .map(|g| {
            let (c, s) = g.accel.trace_batch(rays, Query::Closest, &rob);
            let (a, _) = g.accel.trace_batch(rays, Query::Any, &rob);
            (c, s, a)
        })
        .collect();
    let closest = verdicts(
        mesh,
        rays,
        traced
            .iter()
            .flat_map(|(c, _, _)| c.iter().copied().enumerate())
            .chain(bvh_hits.iter().copied().enumerate()),
        false,
    );
    let any = verdicts(
        mesh,
        rays,
        traced
            .iter()
            .flat_map(|(_, _, a)| a.iter().copied().enumerate()),
        true,
    );
    let mut out = Vec::new();
    for (g, (c, s, a)) in built.iter().zip(traced) {
        let mut n = Counts::default();
        let mut wrong = Vec::new();
        for (i, r) in rays.iter().enumerate() {
            for (h, table, what) in [(&c[i], &closest, "closest"), (&a[i], &any, "any")] {
                match &table[&key(i, h)] {
                    Verdict::Agree => n.agree += 1,
                    Verdict::Tie(_) => n.ties += 1,
                    Verdict::Wrong(w) => wrong.push(format!("{what} {r:?}: {w}")),
                }
            }
            let b = &bvh_hits[i];
            if b.prim != c[i].prim || b.t.to_bits() != c[i].t.to_bits() {
                n.bvh_differ += 1;
                let tie = |h: &Hit| matches!(closest[&key(i, h)], Verdict::Tie(_));
                if !tie(&c[i]) && !tie(b) {
                    wrong.push(format!(
                        "{r:?}: {} {:?} but the BVH {:?}, no tie",
                        g.name, c[i], b
                    ));
                }
            }
        }
        let (nodes, tris) = RayStats::means(&s);
        println!(
            "{name} / {}: {} agree, {} ties, {} differ from the BVH (ties), {} wrong; \
             {nodes:.1} cells, {tris:.1} triangles per ray; {:?}",
            g.name,
            n.agree,
            n.ties,
            n.bvh_differ,
            wrong.len(),
            g.stats
        );
        assert!(
            wrong.is_empty(),
            "{name} / {}: {} wrong, first: {}",
            g.name,
            wrong.len(),
            wrong[0]
        );
        n.hits = c;
        n.stats = s;
        out.push(n);
    }
    out
}

fn check(name: &str, mesh: &Mesh, rays: &[Ray]) -> Vec<Counts> {
    check_with(name, mesh, rays, &GridOptions::default())
}

#[test]
fn random_soups() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 2000, &mesh);
        for n in check(&format!("soup {seed}"), &mesh, &rays) {
            assert!(n.agree > 3000);
        }
    }
    // Big triangles: many cells each (duplicated references, the mailbox at work).
    let mut rng = Rng::new(7);
    let mesh = soup(&mut rng, 300, 1.0);
    let rays = random_rays(&mut rng, 2000, &mesh);
    check("big-triangle soup", &mesh, &rays);
}

#[test]
fn option_extremes() {
    let mut rng = Rng::new(11);
    let mesh = soup(&mut rng, 800, 0.3);
    let rays = random_rays(&mut rng, 800, &mesh);
    let one_cell = GridOptions {
        max_cells: 1,
        ..GridOptions::default()
    };
    check_with("one cell", &mesh, &rays, &one_cell);
    let fine = GridOptions {
        density: 40.0,
        top_density: 2.0,
        sub_density: 20.0,
        hashed_density: 200.0,
        ..GridOptions::default()
    };
    check_with("fine cells", &mesh, &rays, &fine);
    let coarse = GridOptions {
        density: 0.01,
        top_density: 0.001,
        sub_density: 0.01,
        hashed_density: 0.01,
        ..GridOptions::default()
    };
    check_with("coarse cells", &mesh, &rays, &coarse);
    let flat = GridOptions {
        max_resolution: 2,
        ..GridOptions::default()
    };
    check_with("two cells an axis", &mesh, &rays, &flat);
    // Möller–Trumbore through the grids: judged too (its leaks are ties at edges).
    let mt = Robustness {
        triangle_test: TriangleTest::MollerTrumbore,
        ..Robustness::default()
    };
    for g in grids(&mesh, &GridOptions::default()) {
        let (hits, _) = g.accel.trace_batch(&rays, Query::Closest, &mt);
        for (r, h) in rays.iter().zip(&hits) {
            let v = judge(&mesh, r, h);
            assert!(
                !matches!(v, Verdict::Wrong(_)),
                "{} MT {r:?}: {v:?}",
                g.name
            );
        }
    }
}

#[test]
fn models_primary_and_random_rays() {
    for (name, side, random) in [("teapot.obj", 40, 800), ("stanford-bunny.obj", 20, 250)] {
        let Some(mesh) = load_model(name) else { return };
        let mut rng = Rng::new(5);
        let mut rays = Camera::default_view(&mesh.bounds(), side, side).primary_rays();
        rays.extend(random_rays(&mut rng, random, &mesh));
        for n in check(name, &mesh, &rays) {
            assert!(n.agree > rays.len());
        }
    }
}

/// A grid of n×n unit quads (two triangles each) in the plane z = h(x, y).
fn quads(n: usize, h: &dyn Fn(f32, f32) -> f32) -> Mesh {
    let p = |x: usize, y: usize| {
        let (x, y) = (x as f32, y as f32);
        Vec3::new(x, y, h(x, y))
    };
    let mut tris = Vec::new();
    for y in 0..n {
        for x in 0..n {
            tris.push(Triangle::new(p(x, y), p(x + 1, y), p(x + 1, y + 1)));
            tris.push(Triangle::new(p(x, y), p(x + 1, y + 1), p(x, y + 1)));
        }
    }
    Mesh::from_triangles(tris)
}

#[test]
fn rays_at_shared_edges_and_vertices_never_leak() {
    let n = 12;
    let flat = |_: f32, _: f32| 0.0;
    let tilted = |x: f32, y: f32| 0.37 * x + 0.21 * y;
    type Height<'a> = &'a dyn Fn(f32, f32) -> f32;
    let shapes: [(&str, Height); 2] = [("flat quads", &flat), ("tilted quads", &tilted)];
    for (label, h) in shapes {
        let mesh = quads(n, h);
        let mut rng = Rng::new(21);
        let mut rays = Vec::new();
        // The mesh's vertices, computed as `quads` does; edge midpoints from them.
        let vertex = |x: usize, y: usize| Vec3::new(x as f32, y as f32, h(x as f32, y as f32));
        for _ in 0..2500 {
            // Interior vertices, edge midpoints (horizontal, vertical, diagonal).
            let x = 1 + (rng.u64() % (n as u64 - 1)) as usize;
            let y = 1 + (rng.u64() % (n as u64 - 1)) as usize;
            let other = match rng.u64() % 4 {
                0 => vertex(x, y),
                1 => vertex(x + 1, y),
                2 => vertex(x, y + 1),
                _ => vertex(x + 1, y + 1),
            };
            let target = 0.5 * (vertex(x, y) + other);
            let above = if rng.u64().is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            let o = target + Vec3::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0), 10.0 * above);
            rays.push(Ray::new(o, (target - o).normalize(), 0.0, 3.4e38));
            // Straight down (or up) onto the point, with a −0 component.
            let o = Vec3::new(target.x, target.y, target.z + 5.0 * above);
            rays.push(Ray::new(o, Vec3::new(-0.0, 0.0, -above), 0.0, 3.4e38));
        }
        let counts = check(label, &mesh, &rays);
        for (g, c) in ["uniform", "two-level", "hashed"].iter().zip(&counts) {
            let leaks = c.hits.iter().filter(|h| !h.is_hit()).count();
            assert_eq!(leaks, 0, "{label} / {g}: {leaks} rays leaked");
        }
    }
}

#[test]
fn axis_parallel_rays_from_cell_boundaries() {
    let mut rng = Rng::new(31);
    let mesh = soup(&mut rng, 1500, 0.25);
    let opts = GridOptions::default();
    let u = UniformGrid::build(&mesh, &opts).unwrap();
    let t = TwoLevelGrid::build(&mesh, &opts).unwrap();
    let h = HashedGrid::build(&mesh, &opts).unwrap();
    type Planes = Box<dyn Fn(usize, u32) -> f32>;
    let sets: [([u32; 3], Planes); 3] = [
        (u.resolution(), Box::new(move |a, k| u.boundary(a, k))),
        (t.resolution(), Box::new(move |a, k| t.boundary(a, k))),
        (h.resolution(), Box::new(move |a, k| h.boundary(a, k))),
    ];
    let mut rays = Vec::new();
    for (res, plane) in &sets {
        let pick = |rng: &mut Rng, a: usize| plane(a, (rng.u64() % (res[a] as u64 + 1)) as u32);
        for _ in 0..700 {
            let axis = (rng.u64() % 3) as usize;
            let sign = if rng.u64().is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            let mut dir = Vec3::ZERO;
            dir[axis] = sign;
            // The other components ±0.
            for a in 0..3 {
                if a != axis && rng.u64().is_multiple_of(2) {
                    dir[a] = -0.0;
                }
            }
            let mut o = Vec3::new(pick(&mut rng, 0), pick(&mut rng, 1), pick(&mut rng, 2));
            match rng.u64() % 3 {
                // From outside the grid, on the boundary lines of the other two axes.
                0 => o[axis] = -3.0 * sign,
                // From a cell face inside, heading either way.
                1 => {}
                // Off the boundaries along the ray, still on them across it.
                _ => o[axis] = rng.range(-1.2, 1.2),
            }
            rays.push(Ray::new(o, dir, 0.0, 3.4e38));
            // In a boundary plane but not along an axis.
            let mut d2 = rng.dir();
            d2[axis] = if rng.u64().is_multiple_of(2) {
                0.0
            } else {
                -0.0
            };
            rays.push(Ray::new(o, d2, 0.0, 3.4e38));
        }
    }
    let counts = check("axis-parallel from boundaries", &mesh, &rays);
    assert!(counts[0].agree > 1000);
}

#[test]
fn coincident_triangles_go_to_the_smallest_index_at_the_nearest_t() {
    let mut rng = Rng::new(41);
    // Copies of one big triangle at three depths, indices shuffled, inside a soup.
    let base = |z: f32| {
        Triangle::new(
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(3.0, -1.0, z),
            Vec3::new(-1.0, 3.0, z),
        )
    };
    let mut tris: Vec<Triangle> = soup(&mut rng, 400, 0.2).triangles;
    for z in [-0.5f32, 0.25, 0.9] {
        for _ in 0..6 {
            tris.push(base(z));
        }
    }
    for i in (1..tris.len()).rev() {
        let j = (rng.u64() % (i as u64 + 1)) as usize;
        tris.swap(i, j);
    }
    let mesh = Mesh::from_triangles(tris);
    let mut rays = Vec::new();
    for _ in 0..1500 {
        // Targets well inside the triangle, rays from above and below at any slant.
        let (a, b) = (rng.range(0.05, 0.9), rng.range(0.05, 0.9));
        let (a, b) = if a + b > 0.95 {
            (0.95 - b, 0.95 - a)
        } else {
            (a, b)
        };
        let z = [-0.5f32, 0.25, 0.9][(rng.u64() % 3) as usize];
        let target = Vec3::new(-1.0 + 4.0 * a, -1.0 + 4.0 * b, z);
        let side = if rng.u64().is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        let o = target + Vec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 4.0 * side);
        rays.push(Ray::new(o, (target - o).normalize(), 0.0, 3.4e38));
    }
    let counts = check("coincident copies", &mesh, &rays);
    for (g, c) in ["uniform", "two-level", "hashed"].iter().zip(&counts) {
        for (r, h) in rays.iter().zip(&c.hits) {
            let truth = oracle::closest(&mesh, r).map(|x| x.1);
            assert_eq!(Some(h.prim), truth, "{g}: {r:?}");
        }
    }
}

#[test]
fn coplanar_triangles_at_exactly_equal_t() {
    // Overlapping coplanar triangles of different sizes in the plane z = 2 (the grid's
    // middle face), integer vertices: rays along ±z from dyadic points compute the same t
    // exactly for all of them, so the smallest index must win, in whichever cell it is met.
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let tris = vec![
        Triangle::new(p(0.0, 0.0, 0.0), p(8.0, 0.0, 0.0), p(0.0, 8.0, 0.0)),
        Triangle::new(p(0.0, 0.0, 4.0), p(8.0, 0.0, 4.0), p(0.0, 8.0, 4.0)),
        Triangle::new(p(0.0, 0.0, 2.0), p(8.0, 0.0, 2.0), p(0.0, 8.0, 2.0)), // 2: big
        Triangle::new(p(1.0, 1.0, 2.0), p(3.0, 1.0, 2.0), p(1.0, 3.0, 2.0)), // 3: small
        Triangle::new(p(0.0, 0.0, 2.0), p(6.0, 0.0, 2.0), p(0.0, 6.0, 2.0)), // 4: middle
        Triangle::new(p(1.0, 1.0, 2.0), p(1.0, 3.0, 2.0), p(3.0, 1.0, 2.0)), // 5: small, flipped
        Triangle::new(p(0.5, 0.5, 2.0), p(7.0, 0.5, 2.0), p(0.5, 7.0, 2.0)), // 6
    ];
    let mesh = Mesh::from_triangles(tris);
    let mut rng = Rng::new(51);
    let mut rays = Vec::new();
    for _ in 0..1500 {
        let x = (rng.u64() % 64) as f32 / 8.0 + 1.0 / 16.0;
        let y = (rng.u64() % 64) as f32 / 8.0 + 1.0 / 16.0;
        let up = rng.u64().is_multiple_of(2);
        let (z, dz) = if up { (1.0, 1.0) } else { (3.0, -1.0) };
        let dz = dz * [1.0, 2.0, 0.5][(rng.u64() % 3) as usize];
        rays.push(Ray::new(p(x, y, z), p(0.0, 0.0, dz), 0.0, 3.4e38));
        rays.push(Ray::new(
            p(x, y, z + 2.5 * dz.signum()),
            p(0.0, -0.0, -dz),
            0.0,
            3.4e38,
        ));
    }
    let counts = check("coplanar at equal t", &mesh, &rays);
    for (g, c) in ["uniform", "two-level", "hashed"].iter().zip(&counts) {
        for (r, h) in rays.iter().zip(&c.hits) {
            let truth = oracle::closest(&mesh, r);
            assert_eq!(h.is_hit(), truth.is_some(), "{g}: {r:?}");
            if let Some((t, prim)) = truth {
                assert_eq!((h.t as f64, h.prim), (t, prim), "{g}: {r:?}");
            }
        }
    }
}

#[test]
fn teapot_in_a_stadium() {
    let Some(teapot) = load_model("teapot.obj") else {
        return;
    };
    // The teapot scaled to about one unit, in a 1000-unit box of 12 big triangles.
    let b = teapot.bounds();
    let s = 1.0 / b.extent().max_element();
    let mut tris: Vec<Triangle> = teapot
        .triangles
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| (p - b.center()) * s),
        })
        .collect();
    let c = |i: u32| {
        Vec3::new(
            if i & 1 == 0 { -500.0 } else { 500.0 },
            if i & 2 == 0 { -500.0 } else { 500.0 },
            if i & 4 == 0 { -500.0 } else { 500.0 },
        )
    };
    for face in [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ] {
        let q = face.map(c);
        tris.push(Triangle::new(q[0], q[1], q[2]));
        tris.push(Triangle::new(q[0], q[2], q[3]));
    }
    let mesh = Mesh::from_triangles(tris);
    let mut rng = Rng::new(61);
    let mut rays = Vec::new();
    let tb = lancer::geometry::Aabb {
        lo: Vec3::splat(-0.5),
        hi: Vec3::splat(0.5),
    };
    rays.extend(Camera::default_view(&tb, 24, 24).primary_rays());
    for _ in 0..600 {
        // From anywhere in the stadium at the teapot's vertices, and in any direction.
        let o = rng.vec3(-450.0, 450.0);
        let t = &mesh.triangles[(rng.u64() % teapot.len() as u64) as usize];
        let target = t.v[(rng.u64() % 3) as usize];
        rays.push(Ray::new(o, (target - o).normalize(), 0.0, 3.4e38));
        let o = rng.vec3(-2.0, 2.0);
        rays.push(Ray::new(o, rng.dir(), 0.0, 3.4e38));
    }
    let counts = check("teapot in a stadium", &mesh, &rays);
    for c in &counts {
        assert!(c.hits.iter().all(|h| h.is_hit()), "the stadium is closed");
    }
}

#[test]
fn odd_rays_never_hang_or_panic() {
    let mut rng = Rng::new(71);
    let mesh = soup(&mut rng, 500, 0.3);
    let inf = f32::INFINITY;
    let nan = f32::NAN;
    let invalid = [
        Ray::new(Vec3::new(nan, 0.0, 0.0), Vec3::X, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(0.0, inf, 0.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(nan, 1.0, 0.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(-0.0, 0.0, -0.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, nan, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 0.0, nan),
        Ray::new(Vec3::splat(2e12), -Vec3::ONE, 0.0, 3.4e38),
    ];
    let valid = [
        Ray::new(Vec3::ZERO, Vec3::X, 0.0, inf),
        Ray::new(Vec3::ZERO, Vec3::Y, -3.4e38, 3.4e38),
        Ray::new(Vec3::ZERO, Vec3::Z, 0.5, 0.5),
        Ray::new(Vec3::ZERO, Vec3::new(1e-29, 1.0, -1e-29), 0.0, 3.4e38),
        Ray::new(Vec3::ZERO, Vec3::new(1e-38, 0.0, 0.0), 0.0, 3.4e38),
        Ray::new(Vec3::ZERO, Vec3::new(3e38, -3e38, 1.0), 0.0, 3.4e38),
        Ray::new(Vec3::new(5.0, 0.0, 0.0), Vec3::X, 0.0, 3.4e38),
        Ray::new(
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(1.0, 1e-30, 0.0),
            0.0,
            3.4e38,
        ),
        Ray::new(Vec3::splat(9e11), -Vec3::ONE, 0.0, 3.4e38),
        Ray::new(Vec3::splat(-9e11), Vec3::ONE, 0.0, 3.4e38),
        Ray::new(
            Vec3::new(0.0, 0.0, 1e12),
            Vec3::new(0.0, 0.0, -1.0),
            0.0,
            3.4e38,
        ),
        Ray::new(Vec3::splat(1.3), -Vec3::ONE, 0.0, 3.4e38),
        Ray::new(Vec3::splat(1.3), Vec3::ONE, 0.0, 3.4e38),
        Ray::new(Vec3::ZERO, Vec3::splat(1e-20), 0.0, 3.4e38),
    ];
    for g in grids(&mesh, &GridOptions::default()) {
        for q in [Query::Closest, Query::Any] {
            for r in &invalid {
                let mut s = RayStats::default();
                let h = g.accel.intersect(r, q, &Robustness::default(), &mut s);
                assert!(!h.is_hit(), "{} {r:?}", g.name);
                assert_eq!(s, RayStats::default(), "{} {r:?}", g.name);
            }
            for r in &valid {
                let mut s = RayStats::default();
                let h = g.accel.intersect(r, q, &Robustness::default(), &mut s);
                let cells: u32 = [200, 200, 200].iter().sum();
                assert!(s.nodes <= 3 * cells, "{} {r:?}: {s:?}", g.name);
                // 1e-38 is parallel to every axis by the library's rule: not judged.
                if r.dir.x != 1e-38 && q == Query::Closest {
                    let v = judge(&mesh, r, &h);
                    assert!(!matches!(v, Verdict::Wrong(_)), "{} {r:?}: {v:?}", g.name);
                }
            }
        }
    }
}

#[test]
fn empty_mesh_and_stats() {
    let empty = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X)]);
    for g in grids(&empty, &GridOptions::default()) {
        let mut s = RayStats::default();
        let r = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, 3.4e38);
        let h = g
            .accel
            .intersect(&r, Query::Closest, &Robustness::default(), &mut s);
        assert!(!h.is_hit() && s == RayStats::default(), "{}", g.name);
        assert!(g.accel.bounds().is_empty());
        assert_eq!(g.stats.references, 0);
    }
    let mut rng = Rng::new(81);
    let mesh = soup(&mut rng, 1000, 0.2);
    for g in grids(&mesh, &GridOptions::default()) {
        let st = g.stats;
        assert_eq!(g.accel.bounds(), mesh.bounds(), "{}", g.name);
        assert_eq!(st.triangles, 1000);
        assert_eq!(st.duplicated, st.references - st.triangles);
        assert!(st.references >= 1000 && st.non_empty_cells > 0 && st.non_empty_cells <= st.cells);
        assert!(st.bytes >= st.references * 4, "{}: {st:?}", g.name);
        // A ray that misses the grid's box visits no cell.
        let mut s = RayStats::default();
        let r = Ray::new(Vec3::splat(5.0), Vec3::X, 0.0, 3.4e38);
        g.accel
            .intersect(&r, Query::Closest, &Robustness::default(), &mut s);
        assert_eq!(s, RayStats::default());
    }
    // The mailbox: a ray along one big triangle's cells tests it once.
    let big = Mesh::from_triangles(vec![
        Triangle::new(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
        ),
        Triangle::new(
            Vec3::splat(9.0),
            Vec3::splat(10.0),
            Vec3::new(9.0, 10.0, 9.5),
        ),
    ]);
    let opts = GridOptions {
        density: 2000.0,
        hashed_density: 2000.0,
        top_density: 50.0,
        sub_density: 50.0,
        ..GridOptions::default()
    };
    for g in grids(&big, &opts) {
        let mut s = RayStats::default();
        // Along the triangle's plane, just above it: through every cell of its layer.
        let r = Ray::new(
            Vec3::new(0.5, 0.5, 0.01),
            Vec3::new(1.0, 1.0, 0.0),
            0.0,
            3.4e38,
        );
        let h = g
            .accel
            .intersect(&r, Query::Closest, &Robustness::default(), &mut s);
        assert!(s.nodes > 3, "{}: {s:?}", g.name);
        assert!(s.tris <= 3, "{}: {s:?} (mailbox)", g.name);
        assert!(!matches!(judge(&big, &r, &h), Verdict::Wrong(_)));
    }
}

#[test]
fn the_memory_cap_refuses_with_an_error() {
    let mut rng = Rng::new(91);
    let mesh = soup(&mut rng, 400, 1.0);
    let small = GridOptions {
        max_bytes: Some(64 << 10),
        ..GridOptions::default()
    };
    let errors = [
        UniformGrid::build(&mesh, &small).err(),
        TwoLevelGrid::build(&mesh, &small).err(),
        HashedGrid::build(&mesh, &small).err(),
    ];
    for e in errors {
        let msg = e.expect("refused").to_string();
        println!("{msg}");
        assert!(msg.contains("limit") && msg.contains("KiB"), "{msg}");
    }
    // Far past any machine: refused up front (sizes in the u128 range), never an abort.
    let absurd = GridOptions {
        density: 1e9,
        top_density: 1e9,
        sub_density: 1e9,
        hashed_density: 1e9,
        max_cells: u64::MAX,
        max_resolution: u32::MAX,
        max_bytes: None,
    };
    let sub_only = GridOptions {
        top_density: 1.0 / 16.0,
        ..absurd
    };
    let errors = [
        UniformGrid::build(&mesh, &absurd).err(),
        TwoLevelGrid::build(&mesh, &absurd).err(),
        TwoLevelGrid::build(&mesh, &sub_only).err(),
        HashedGrid::build(&mesh, &absurd).err(),
    ];
    for e in errors {
        let msg = e.expect("refused").to_string();
        println!("{msg}");
        assert!(msg.contains("limit"), "{msg}");
    }
}

/// Build time, stats and primary-ray speed on the bunny, beside the BVH, on 2 threads.
#[test]
#[ignore]
fn bench_bunny() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let rays = Camera::default_view(&mesh.bounds(), 1024, 1024).primary_rays();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    pool.install(|| {
        let opts = GridOptions::default();
        let rob = Robustness::default();
        let mut accels: Vec<(&str, Box<dyn Accel>, f64)> = Vec::new();
        let (_, bvh, secs) = bvh_entrant(&mesh);
        accels.push(("bvh (dfs-sign)", bvh, secs));
        let t = Instant::now();
        let u = UniformGrid::build(&mesh, &opts).unwrap();
        let tu = t.elapsed().as_secs_f64();
        println!("uniform: {:?}", u.stats());
        accels.push(("uniform", Box::new(u), tu));
        let t = Instant::now();
        let tl = TwoLevelGrid::build(&mesh, &opts).unwrap();
        let tt = t.elapsed().as_secs_f64();
        println!("two-level: {:?}", tl.stats());
        accels.push(("two-level", Box::new(tl), tt));
        let t = Instant::now();
        let h = HashedGrid::build(&mesh, &opts).unwrap();
        let th = t.elapsed().as_secs_f64();
        println!("hashed: {:?}", h.stats());
        accels.push(("hashed", Box::new(h), th));
        println!(
            "| structure | build | Mrays/s (2 threads, median of 3) | Mrays/CPU-s (1 thread) \
             | cells/ray | tris/ray |"
        );
        println!("|---|---|---|---|---|---|");
        for (name, a, build_s) in &accels {
            let mut times = Vec::new();
            let mut means = (0.0, 0.0);
            for _ in 0..3 {
                let t = Instant::now();
                let (hits, stats) = a.trace_batch(&rays, Query::Closest, &rob);
                times.push(t.elapsed().as_secs_f64());
                means = RayStats::means(&stats);
                assert_eq!(hits.len(), rays.len());
            }
            times.sort_by(f64::total_cmp);
            // The same rays on this thread alone, timed by the thread's own CPU time (what
            // other processes on a shared machine change least).
            let cpu0 = thread_cpu_ns();
            let mut s = RayStats::default();
            for r in &rays {
                std::hint::black_box(a.intersect(r, Query::Closest, &rob, &mut s));
            }
            let cpu = (thread_cpu_ns() - cpu0) as f64 * 1e-9;
            println!(
                "| {name} | {:.1} ms | {:.2} | {:.2} | {:.1} | {:.1} |",
                build_s * 1e3,
                rays.len() as f64 / times[1] / 1e6,
                rays.len() as f64 / cpu / 1e6,
                means.0,
                means.1
            );
        }
    });
}
