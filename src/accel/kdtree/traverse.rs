//! Front-to-back stack traversal of the kd-tree (Havran's "TA_B^rec" without recursion, as
//! in pbrt): each node carries the ray's [near, far] interval in its cell; at an inner node
//! the distance d to the split plane decides — the near child only, the far child only, or
//! both, near first — with the near side given by the sign of the direction on the split
//! axis.
//!
//! It is also the CPU twin of the GPU traversal, `kdtree.wgsl`, which walks the same node and
//! triangle arrays (see `gpu.rs`) with the same operations in the same order, so hits and
//! statistics agree bit for bit; every helper below names its WGSL twin.
//!
//! Robust by construction, and with no NaN and no ∞ kept anywhere (runtime ∞/NaN are
//! indeterminate in WGSL; a product that overflows is clamped at once, as the slab test's
//! distances are):
//! - every interval end is one computed plane distance (or tmin/tmax), never a sum, so its
//!   error stays within γ(3) of its value, and is kept widened outward by [`TIE_SLACK`](crate::geometry::TIE_SLACK) of
//!   its magnitude ([`widen_lo`], [`widen_hi`]); d is compared with the widened ends, so a
//!   cell the ray truly reaches is never skipped, d exactly on near or far included (both
//!   children are then visited);
//! - an axis the ray is parallel to (|1/d| ≥
//!   [`PARALLEL_INV`](crate::geometry::PARALLEL_INV), the slab test's own rule) is decided
//!   by the origin's side alone, both sides when the origin lies on the plane, and leaves
//!   the interval as it is;
//! - distances are clamped to ±f32::MAX ([`finite`]), and measured along the direction
//!   scaled by a power of two to a largest component in [1, 2) (exact), so a tiny or huge
//!   direction is traversed like its unit twin.
//!
//! The tie rule: a popped node is skipped only when its entry lies beyond the best t plus
//! its error bound plus [`TIE_SLACK`](crate::geometry::TIE_SLACK) (the BVH's `prune_bound`), so a triangle at exactly the
//! best t in a later leaf — a coincident copy, a triangle split across the plane — is still
//! tested, and equal t goes to the smaller original index ([`Hit::beats`]).
//!
//! Empty leaves are flagged in their parent and never visited.
//!
//! Mailboxing: the last [`MAILBOX`] triangles tested (by original index) are remembered per
//! ray and not tested again. A test's answer does not depend on the cell it is made in, so
//! a repeated test could only repeat an answer already weighed: hits do not depend on it,
//! only the triangle-test count does (the GPU keeps the same mailbox, so its counts are the
//! CPU's).

use super::{KdTree, MAX_KD_DEPTH};
use crate::accel::plane_ray::{finite, widen_hi, widen_lo, PlaneRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{
    intersect_triangle_bounded, Aabb, Hit, Ray, Robustness, TriangleTest, WatertightRay, MISS,
};

/// Triangles remembered per ray (kdtree.wgsl holds them in two `vec4<u32>`).
pub(crate) const MAILBOX: usize = 8;

impl Accel for KdTree {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    #[inline]
    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        // One specialised loop per triangle test (the choice is not re-made per triangle).
        match robustness.triangle_test {
            TriangleTest::Watertight => self.walk::<false>(ray, query, robustness, mask, stats),
            TriangleTest::MollerTrumbore => self.walk::<true>(ray, query, robustness, mask, stats),
        }
    }
}

impl KdTree {
    /// The traversal, with Möller–Trumbore when `MT`, else the watertight test.
    #[inline(always)]
    fn walk<const MT: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        // An empty tree is a single empty leaf.
        if !ray.is_valid() || self.nodes[0].is_empty_leaf() {
            return best;
        }
        let test = if MT {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        // The traversal runs on t' = t / 2^k for the direction scaled by 2^k so that its
        // largest component lies in [1, 2): exact (a power of two), and it makes "parallel"
        // mean a component below 2e-30 of the largest, so a ray whose direction is tiny (or
        // huge) overall is traversed like its unit twin. Triangles see the ray unscaled.
        let pr = PlaneRay::new(ray);
        // [lo, hi]: the ray's interval in the current cell, widened (widen_lo, widen_hi).
        let Some((mut lo, mut hi)) = pr.root_interval(&self.bounds) else {
            stats.nodes += 1;
            return best;
        };
        let wr = WatertightRay::new(ray.dir);
        let reject_near = robustness.rejects_near_hits_of(ray);
        let mut prune = pr.tmax;
        // Pending far children with their intervals: at most one per level.
        let mut stack = [(0u32, 0.0f32, 0.0f32); MAX_KD_DEPTH];
        let mut sp = 0usize;
        let mut idx = 0usize;
        let mut mailbox = [MISS; MAILBOX];
        let mut slot = 0usize;
        loop {
            let node = self.nodes[idx];
            stats.nodes += 1;
            if !node.is_leaf() {
                let (k, s) = (node.axis(), node.split());
                let (below, above) = (idx + 1, node.above());
                let (below_empty, above_empty) = node.empty_children();
                let (o, inv) = (pr.o[k], pr.inv[k]);
                let (near, far, near_empty, far_empty) = if inv > 0.0 {
                    (below, above, below_empty, above_empty)
                } else {
                    (above, below, above_empty, below_empty)
                };
                // Which children the interval reaches, and the plane's widened distance
                // (dl, dh) to cut it with. On an axis the ray is parallel to, the origin's
                // side decides (both sides when it lies on the plane), the interval stays.
                let (reach_near, reach_far, dl, dh) = if pr.parallel(k) {
                    let (on_below, on_above) = (o <= s, o >= s);
                    if inv > 0.0 {
                        (on_below, on_above, lo, hi)
                    } else {
                        (on_above, on_below, lo, hi)
                    }
                } else {
                    let d = finite((s - o) * inv);
                    (d >= lo, d <= hi, widen_lo(d), widen_hi(d))
                };
                // Empty leaves are not visited: they hold nothing to test.
                let visit_near = reach_near && !near_empty;
                let visit_far = reach_far && !far_empty;
                if visit_near {
                    if visit_far {
                        stack[sp] = (far as u32, if dl > lo { dl } else { lo }, hi);
                        sp += 1;
                        if dh < hi {
                            hi = dh;
                        }
                    }
                    idx = near;
                    continue;
                }
                if visit_far {
                    if dl > lo {
                        lo = dl;
                    }
                    idx = far;
                    continue;
                }
                // Nothing to visit below this node; on to the stack.
            } else {
                let first = node.first();
                for lt in &self.tris[first..first + node.count()] {
                    if mailbox.contains(&lt.prim) {
                        continue;
                    }
                    mailbox[slot] = lt.prim;
                    slot = (slot + 1) % MAILBOX;
                    stats.tris += 1;
                    let tri = lt.triangle();
                    let h = intersect_triangle_bounded(test, &tri, ray, &wr, ray.tmin, best.t);
                    let Some(h) = h else { continue };
                    if !Hit::beats(h.t, lt.prim, best.t, best.prim) {
                        continue;
                    }
                    // As the BVH: a hit that may lie behind the origin (the surface a
                    // secondary ray leaves) is no hit under the error-bound offset.
                    if reject_near && h.maybe_behind_origin() {
                        continue;
                    }
                    if mask.is_some_and(|m| !m.keeps(lt.prim, h.u, h.v)) {
                        continue;
                    }
                    best = Hit {
                        t: h.t,
                        prim: lt.prim,
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
