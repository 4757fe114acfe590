//! Judging any acceleration structure (`&dyn Accel`): against the f64 oracle, against the
//! BVH, and against a brute-force pass with the tracers' own f32 test and tie rule; and a
//! plane of quads whose shared edges and vertices rays must not leak through.

use glam::Vec3;
use lancer::accel::bvh::BuildOptions;
use lancer::accel::{build, Accel, AccelKind};
use lancer::geometry::{intersect_triangle_bounded, Hit, Ray, Triangle, WatertightRay};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{judge, judge_any, Truths, Verdict};
use lancer::{Query, Robustness};

/// Judges closest and any-hit answers of `accel` for every ray; fails on any wrong one.
/// Returns (agree, ties) of the closest-hit answers.
pub fn check(name: &str, mesh: &Mesh, accel: &dyn Accel, rays: &[Ray]) -> (usize, usize) {
    check_against(name, &Truths::new(mesh, rays), accel)
}

/// [`check`] on the rays of `truths`, the oracle's search done once for every structure
/// judged on them.
pub fn check_against(name: &str, truths: &Truths, accel: &dyn Accel) -> (usize, usize) {
    let (mesh, rays) = (truths.mesh(), truths.rays());
    let rob = Robustness::default();
    let mut counts = (0, 0);
    for query in [Query::Closest, Query::Any] {
        let (hits, _) = accel.trace_batch(rays, query, &rob);
        let (mut agree, mut tie, mut wrong) = (0, 0, Vec::new());
        for (i, (r, h)) in rays.iter().zip(&hits).enumerate() {
            let v = match query {
                Query::Closest => truths.judge(i, h),
                Query::Any => judge_any(mesh, r, h),
            };
            match v {
                Verdict::Agree => agree += 1,
                Verdict::Tie(_) => tie += 1,
                Verdict::Wrong(w) => wrong.push(format!("{r:?}: {w}")),
            }
        }
        println!(
            "{name} ({query:?}): {agree} agree, {tie} ties, {} wrong",
            wrong.len()
        );
        assert!(
            wrong.is_empty(),
            "{name} {query:?}: {} wrong, first: {}",
            wrong.len(),
            wrong[0]
        );
        if query == Query::Closest {
            counts = (agree, tie);
        }
    }
    counts
}

/// `accel`'s closest hits equal the BVH's, bit for bit, except where the oracle names a
/// genuine tie for one of the two answers, or `accel` agrees with the oracle and the BVH
/// does not (counted and printed: a BVH bug). Returns that count.
pub fn same_as_bvh(name: &str, mesh: &Mesh, accel: &dyn Accel, rays: &[Ray]) -> usize {
    let rob = Robustness::default();
    let bvh = build(
        AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        mesh,
        &BuildOptions::default(),
    )
    .unwrap();
    let (a, _) = accel.trace_batch(rays, Query::Closest, &rob);
    let (b, _) = bvh.trace_batch(rays, Query::Closest, &rob);
    let (mut differ, mut bvh_wrong) = (0, 0);
    for ((r, x), y) in rays.iter().zip(&a).zip(&b) {
        if x == y {
            continue;
        }
        differ += 1;
        assert!(
            x.prim != y.prim,
            "{name}: same prim {} but {x:?} ≠ bvh {y:?}",
            x.prim
        );
        let (vx, vy) = (judge(mesh, r, x), judge(mesh, r, y));
        if vx == Verdict::Agree && matches!(vy, Verdict::Wrong(_)) {
            bvh_wrong += 1;
            if bvh_wrong == 1 {
                println!("{name}: the BVH is wrong on {r:?}: {vy:?}; the structure gives {x:?}");
            }
            continue;
        }
        assert!(
            matches!(vx, Verdict::Tie(_)) || matches!(vy, Verdict::Tie(_)),
            "{name}: {r:?}: {x:?} ({vx:?}) ≠ bvh {y:?} ({vy:?}) and the oracle names no tie"
        );
    }
    println!(
        "{name}: = bvh on {} of {} rays ({bvh_wrong} where only the BVH is wrong)",
        rays.len() - differ,
        rays.len()
    );
    bvh_wrong
}

/// Every triangle tested in index order with the tracers' own f32 test and tie rule (and
/// their near-hit rejection): the answer a traversal must give bit for bit.
pub fn brute_force(mesh: &Mesh, rays: &[Ray]) -> Vec<Hit> {
    let rob = Robustness::default();
    rays.iter()
        .map(|r| {
            let mut best = Hit::miss(r.tmax);
            if !r.is_valid() {
                return best;
            }
            let wr = WatertightRay::new(r.dir);
            for i in mesh.included() {
                let tri = &mesh.triangles[i as usize];
                let h = intersect_triangle_bounded(rob.triangle_test, tri, r, &wr, r.tmin, best.t);
                if let Some(h) = h {
                    if Hit::beats(h.t, i, best.t, best.prim)
                        && !(rob.rejects_near_hits_of(r) && h.maybe_behind_origin())
                    {
                        best = Hit {
                            t: h.t,
                            prim: i,
                            u: h.u,
                            v: h.v,
                        };
                    }
                }
            }
            best
        })
        .collect()
}

/// An n×n grid of quads (two triangles each) in the plane z = 0 over [0, n·step]², with
/// irregular f32 coordinates; and points on its shared vertices and edges (diagonals too).
pub fn quad_plane(n: usize, step: f32) -> (Mesh, Vec<Vec3>) {
    let p = |i: usize, j: usize| Vec3::new(i as f32 * step, j as f32 * step * 1.1, 0.0);
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            tris.push(Triangle::new(a, b, c));
            tris.push(Triangle::new(a, c, d));
        }
    }
    let mut targets = Vec::new();
    for i in 1..n {
        for j in 1..n {
            targets.push(p(i, j));
            targets.push(0.5 * (p(i, j) + p(i + 1, j + 1)));
            targets.push(0.5 * (p(i, j) + p(i + 1, j)));
            targets.push(0.5 * (p(i, j) + p(i, j + 1)));
        }
    }
    (Mesh::from_triangles(tris), targets)
}
