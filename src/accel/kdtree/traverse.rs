//! Front-to-back stack traversal of the kd-tree (Havran's "TA_B^rec" without recursion, as
//! in pbrt): each node carries the ray's [near, far] interval in its cell; at an inner node
//! the distance d to the split plane decides — the near child only, the far child only, or
//! both, near first — with the near side given by the sign of the direction on the split
//! axis.
//!
//! Robust by construction (the interval ends and the ray's scaling are shared with the BIH,
//! `accel::plane_ray`):
//! - every interval end is one computed plane distance (or tmin/tmax), never a sum, so its
//!   error stays within γ(3) of its value, and is kept widened outward by `TIE_SLACK` of
//!   its magnitude (`widen_lo`, `widen_hi`); d is compared with the widened ends, so a
//!   cell the ray truly reaches is never skipped, d exactly on near or far included (both
//!   children are then visited);
//! - an axis the ray is parallel to (|1/d| ≥ [`PARALLEL_INV`], the slab test's own rule)
//!   is decided by the origin's side alone, both sides when the origin lies on the plane;
//! - distances are clamped to ±f32::MAX (no ∞, no NaN from ∞ − ∞), and measured along the
//!   direction scaled by a power of two to a largest component in [1, 2) (exact), so a
//!   tiny or huge direction is traversed like its unit twin.
//!
//! The tie rule: a popped node is skipped only when its entry lies beyond the best t plus
//! its error bound plus `TIE_SLACK` (the BVH's `prune_bound`), so a triangle at exactly the
//! best t in a later leaf — a coincident copy, a triangle split across the plane — is still
//! tested, and equal t goes to the smaller original index ([`Hit::beats`]).
//!
//! Empty leaves are flagged in their parent and never visited.
//!
//! Mailboxing: the last [`MAILBOX`] references tested are remembered per ray and not tested
//! again. A skipped test could only repeat an answer already weighed (its interval was then
//! at least as long), so correctness does not depend on it.

use super::{KdTree, MAX_KD_DEPTH};
use crate::accel::plane_ray::{widen_hi, widen_lo, PlaneRay};
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{
    intersect_triangle_bounded, Aabb, Hit, Ray, Robustness, Triangle, TriangleTest, WatertightRay,
    PARALLEL_INV,
};

/// Triangle ids remembered per ray.
const MAILBOX: usize = 8;

impl Accel for KdTree {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    #[inline]
    fn intersect(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        // One specialised loop per triangle test (the choice is not re-made per triangle).
        match robustness.triangle_test {
            TriangleTest::Watertight => self.walk::<false>(ray, query, robustness, stats),
            TriangleTest::MollerTrumbore => self.walk::<true>(ray, query, robustness, stats),
        }
    }
}

impl KdTree {
    /// The traversal, with Möller–Trumbore when `MT`, else the watertight test.
    // `!(d < lo)` is meant: a NaN d (parallel, origin on the plane) visits both children.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn walk<const MT: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        if !ray.is_valid() || self.tris.is_empty() {
            return best;
        }
        let test = if MT {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        // Plane distances in the units of the direction scaled to a largest component in
        // [1, 2) (PlaneRay); an axis the ray is parallel to gets 1/d = ±∞, sign kept.
        let pr = PlaneRay::new(ray);
        let inv = pr.inv.map(|r| {
            if r.abs() >= PARALLEL_INV {
                f32::INFINITY.copysign(r)
            } else {
                r
            }
        });
        let (o, tmax) = (pr.o, pr.tmax);
        // [lo, hi]: the ray's interval in the current cell, widened (widen_lo, widen_hi).
        let Some((mut lo, mut hi)) = pr.root_interval(&self.bounds) else {
            stats.nodes += 1;
            return best;
        };
        let wr = WatertightRay::new(ray.dir);
        let reject_near = robustness.rejects_near_hits();
        let mut prune = tmax;
        let mut stack = [(0u32, 0.0f32, 0.0f32); MAX_KD_DEPTH];
        let mut sp = 0usize;
        let mut idx = 0usize;
        let mut mailbox = [u32::MAX; MAILBOX];
        let mut slot = 0usize;
        loop {
            let node = self.nodes[idx];
            stats.nodes += 1;
            if !node.is_leaf() {
                let (k, s) = (node.axis(), node.split());
                let (below, above) = (idx + 1, node.above());
                let (below_empty, above_empty) = node.empty_children();
                // ±∞ past f32's range or on an axis the ray is parallel to (inv = ±∞); NaN
                // when parallel with the origin on the plane, which visits both children.
                let d = (s - o[k]) * inv[k];
                let (near, far, near_empty, far_empty) = if inv[k] > 0.0 {
                    (below, above, below_empty, above_empty)
                } else {
                    (above, below, above_empty, below_empty)
                };
                // Empty leaves are not visited: they hold nothing to test.
                let visit_near = !(d < lo) && !near_empty;
                let visit_far = !(d > hi) && !far_empty;
                // max/min written so that a NaN d leaves the interval as it is.
                if visit_near {
                    if visit_far {
                        let dl = widen_lo(d);
                        stack[sp] = (far as u32, if dl > lo { dl } else { lo }, hi);
                        sp += 1;
                        let dh = widen_hi(d);
                        if dh < hi {
                            hi = dh;
                        }
                    }
                    idx = near;
                    continue;
                }
                if visit_far {
                    let dl = widen_lo(d);
                    if dl > lo {
                        lo = dl;
                    }
                    idx = far;
                    continue;
                }
                // Nothing to visit below this node; on to the stack.
            } else {
                let first = node.first();
                for &r in &self.refs[first..first + node.count()] {
                    if mailbox.contains(&r) {
                        continue;
                    }
                    mailbox[slot] = r;
                    slot = (slot + 1) % MAILBOX;
                    stats.tris += 1;
                    let kt = &self.tris[r as usize];
                    let tri = Triangle { v: kt.v };
                    let h = intersect_triangle_bounded(test, &tri, ray, &wr, ray.tmin, best.t);
                    let Some(h) = h else { continue };
                    if !Hit::beats(h.t, kt.prim, best.t, best.prim) {
                        continue;
                    }
                    // As the BVH: a hit that may lie behind the origin (the surface a
                    // secondary ray leaves) is no hit under the error-bound offset.
                    if reject_near && h.maybe_behind_origin() {
                        continue;
                    }
                    best = Hit {
                        t: h.t,
                        prim: kt.prim,
                        u: h.u,
                        v: h.v,
                    };
                    if query == Query::Any {
                        return best;
                    }
                    prune = pr.scaled(h.prune());
                }
            }
            // Next: the nearest pending node whose entry is not beyond the best hit.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (i, l, h) = stack[sp];
                if l <= prune {
                    (idx, lo, hi) = (i as usize, l, h);
                    break;
                }
            }
        }
    }
}
