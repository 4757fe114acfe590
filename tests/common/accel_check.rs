//! Judging any acceleration structure (`&dyn Accel`): against the f64 oracle, against the
//! BVH, and against a brute-force pass with the tracers' own f32 test and tie rule; and the
//! tie rule on coincident triangles (the smallest index at the nearest t).

use lancer::accel::bvh::BuildOptions;
use lancer::accel::{build, Accel, AccelKind};
use lancer::geometry::{intersect_triangle_bounded, Hit, Ray, WatertightRay};
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
    let rob = Robustness::default();
    let mut counts = (0, 0);
    for query in [Query::Closest, Query::Any] {
        let (hits, _) = accel.trace_batch(truths.rays(), query, &rob);
        let judged = judge_hits(name, truths, query, &hits);
        if query == Query::Closest {
            counts = judged;
        }
    }
    counts
}

/// Judges `hits`, one `query` answer per ray of `truths`, however they were traced; prints
/// the counts and fails on any wrong one. Returns (agree, ties): [`check_against`]'s
/// judging, for callers that trace the batch themselves (to test more of it).
pub fn judge_hits(name: &str, truths: &Truths, query: Query, hits: &[Hit]) -> (usize, usize) {
    let (mesh, rays) = (truths.mesh(), truths.rays());
    let (mut agree, mut tie, mut wrong) = (0, 0, Vec::new());
    for (i, (r, h)) in rays.iter().zip(hits).enumerate() {
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
    (agree, tie)
}

/// The tie rule on coincident triangles: every closest hit in `hits` (one per ray of
/// `truths`) is the oracle's smallest index at the nearest t, or a genuine tie the oracle
/// names (not two hits at exactly equal t, where the smaller index must win); `who` names
/// the structure in the failure. Returns how many are exactly the oracle's index.
pub fn smallest_index_at_nearest_t(who: &str, truths: &Truths, hits: &[Hit]) -> usize {
    let mut exact = 0;
    for (i, (r, h)) in truths.rays().iter().zip(hits).enumerate() {
        let Some((_, prim)) = truths.closest(i) else {
            continue;
        };
        if h.prim == prim {
            exact += 1;
            continue;
        }
        let v = truths.judge(i, h);
        assert!(
            matches!(v, Verdict::Tie(_)) && v != Verdict::Tie("two hits at equal t"),
            "{who}: {r:?} reports {} but the oracle's smallest index at the nearest t is \
             {prim} ({v:?})",
            h.prim
        );
    }
    exact
}

/// `accel`'s closest hits equal the [`brute_force`] pass's, bit for bit (equal t goes to the
/// smaller index, whichever leaf or cell each sits in); names the first ray that differs.
pub fn assert_closest_is_brute_force(name: &str, mesh: &Mesh, accel: &dyn Accel, rays: &[Ray]) {
    let (hits, _) = accel.trace_batch(rays, Query::Closest, &Robustness::default());
    let want = brute_force(mesh, rays);
    let differ: Vec<usize> = (0..rays.len()).filter(|&i| hits[i] != want[i]).collect();
    assert!(
        differ.is_empty(),
        "{name}: {} rays differ from the brute force; first {:?}: {:?} vs {:?}",
        differ.len(),
        rays[differ[0]],
        hits[differ[0]],
        want[differ[0]]
    );
}

/// `accel`'s closest hits equal the BVH's, bit for bit, except where the oracle names a
/// genuine tie for one of the two answers, or `accel` agrees with the oracle and the BVH
/// does not (counted and printed: a BVH bug). Returns that count.
pub fn same_as_bvh(name: &str, mesh: &Mesh, accel: &dyn Accel, rays: &[Ray]) -> usize {
    let rob = Robustness::default();
    let bvh = default_bvh(mesh);
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

/// The BVH every other structure is compared with: the default build in the dfs-sign layout.
pub fn default_bvh(mesh: &Mesh) -> Box<dyn Accel> {
    build(
        AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        mesh,
        &BuildOptions::default(),
    )
    .unwrap()
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

/// Rays at the shared edges and vertices of a plane of triangles (`hard::edge_rays` at
/// `hard::grid`'s targets) never leak: no closest or any-hit answer misses; the oracle
/// judges every answer; and the closest hits are the brute force's (equal t at a shared
/// edge goes to the smaller index, whichever leaf or cell each triangle sits in).
pub fn no_leaks_at_shared_edges(name: &str, mesh: &Mesh, accel: &dyn Accel, rays: &[Ray]) {
    let rob = Robustness::default();
    for query in [Query::Closest, Query::Any] {
        let (hits, _) = accel.trace_batch(rays, query, &rob);
        let leaks = hits.iter().filter(|h| !h.is_hit()).count();
        println!("{name} {query:?}: {} rays, {leaks} leaks", rays.len());
        assert_eq!(
            leaks, 0,
            "{name} {query:?}: rays through shared edges and vertices leaked"
        );
    }
    check(name, mesh, accel, rays);
    assert_closest_is_brute_force(name, mesh, accel, rays);
}
