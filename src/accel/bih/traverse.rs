//! Front-to-back stack traversal of the BIH, the kd-tree's walk with two planes: each node
//! carries the ray's [near, far] interval; at an inner node the near child (the left one
//! when the direction is positive on the axis) keeps t up to its own plane, the far child
//! keeps t from its plane; either, both (near first, far pushed) or neither is visited.
//!
//! It is also the CPU twin of the GPU traversal, `bih.wgsl`, which walks the same node and
//! triangle arrays (see `gpu.rs`) with the same operations in the same order, so hits and
//! statistics agree bit for bit; the leaf step is every layout's (`LeafRay::test_leaf`,
//! WGSL `test_leaf`). No ∞ or NaN is formed (an axis the ray is parallel to is a branch,
//! not a 1/0), the stack holds (node, near, far) and never more than [`MAX_BIH_DEPTH`]
//! entries (the builder's cap), and the interval ends are [`prune_bound`](crate::geometry::prune_bound) and its mirror.
//!
//! Robust as the kd-tree (`accel::plane_ray`): every interval end is one computed plane
//! distance (or tmin/tmax), kept widened outward by `TIE_SLACK` of its magnitude, and a
//! child is visited when its plane distance is not beyond the widened end — a plane
//! exactly at the interval's end included. The clip planes are vertex coordinates, so a
//! triangle lies within its child's half-space exactly. On an axis the ray is parallel to,
//! the origin's side decides (both children when it lies between or on the planes).
//!
//! The tie rule: a child whose entry lies beyond the best t plus its error bound plus
//! `TIE_SLACK` (`TriHit::prune`) is not visited, never one whose entry equals the best t,
//! so a triangle at exactly the best t in a later leaf is still tested and equal t goes to
//! the smaller original index ([`Hit::beats`]). Triangles are referenced once: no mailbox.

use super::{Bih, MAX_BIH_DEPTH};
use crate::accel::leaf_tri::{with_leaf_test, LeafRay};
use crate::accel::plane_ray::{finite, widen_hi, widen_lo, PlaneRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{Aabb, Hit, Ray, Robustness};

impl Accel for Bih {
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
        with_leaf_test!(robustness, self.walk(ray, query, robustness, mask, stats))
    }
}

impl Bih {
    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        if !ray.is_valid() || self.tris.is_empty() {
            return best;
        }
        // Plane distances in the units of the direction scaled to a largest component in
        // [1, 2) (exact); triangles see the ray unscaled.
        let pr = PlaneRay::new(ray);
        // [lo, hi]: the ray's interval in the current node, widened.
        let Some((mut lo, mut hi)) = pr.root_interval(&self.bounds) else {
            stats.nodes += 1;
            return best;
        };
        let leaf = LeafRay::new(ray, robustness, mask);
        // Nodes entered beyond this are cut: the best hit's prune bound, in scaled units
        // (the leaf step keeps it unscaled in `hit_prune`).
        let mut hit_prune = ray.tmax.min(f32::MAX);
        let mut prune = pr.scaled(hit_prune);
        let mut stack = [(0u32, 0.0f32, 0.0f32); MAX_BIH_DEPTH];
        let mut sp = 0usize;
        let mut idx = 0usize;
        loop {
            let node = self.nodes[idx];
            stats.nodes += 1;
            if !node.is_leaf() {
                let k = node.axis();
                let (o, inv) = (pr.o[k], pr.inv[k]);
                // The near child is entered first along the ray: the left one (x ≤ its
                // maximum) when the direction is positive on the axis. Its own plane is
                // where the ray leaves it; the far child's own plane is where the ray
                // enters that one.
                let positive = inv > 0.0;
                let (near, far, near_plane, far_plane) = if positive {
                    (idx + 1, node.index(), node.clip[0], node.clip[1])
                } else {
                    (node.index(), idx + 1, node.clip[1], node.clip[0])
                };
                let (visit_near, mut visit_far, near_hi, far_lo);
                if pr.parallel(k) {
                    // The origin's side decides; the interval is unchanged.
                    (visit_near, visit_far) = if positive {
                        (o <= near_plane, o >= far_plane)
                    } else {
                        (o >= near_plane, o <= far_plane)
                    };
                    (near_hi, far_lo) = (hi, lo);
                } else {
                    let t_near = finite((near_plane - o) * inv);
                    let t_far = finite((far_plane - o) * inv);
                    visit_near = t_near >= lo;
                    visit_far = t_far <= hi;
                    near_hi = hi.min(widen_hi(t_near));
                    far_lo = lo.max(widen_lo(t_far));
                }
                visit_far = visit_far && far_lo <= prune;
                if visit_near {
                    if visit_far {
                        stack[sp] = (far as u32, far_lo, hi);
                        sp += 1;
                    }
                    (idx, hi) = (near, near_hi);
                    continue;
                }
                if visit_far {
                    (idx, lo) = (far, far_lo);
                    continue;
                }
                // Neither child: on to the stack.
            } else {
                let first = node.index();
                let tris = &self.tris[first..first + node.count as usize];
                if leaf.test_leaf::<TEST>(
                    tris,
                    query == Query::Any,
                    &mut best,
                    &mut hit_prune,
                    stats,
                ) {
                    return best;
                }
                prune = pr.scaled(hit_prune);
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
