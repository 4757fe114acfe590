//! The CPU twin of `bvh2_wide_node.wgsl`, step for step: the root box tested once from the
//! header, both child boxes of a record tested with the shared slab test, the hit children
//! visited nearest first (equal entries → the first child), only the far one pushed, leaf
//! ranges tested in order with the shared triangle test and tie rule, all in f32.

use glam::{Vec3, Vec3A};

use super::{is_leaf, Bvh2WideNode, ChildRef, COUNT_SHIFT};
use crate::accel::bvh::MAX_DEPTH;
use crate::accel::leaf_tri::{walk_accel_methods, LeafRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, MISS, PARALLEL_INV};

impl Accel for Bvh2WideNode {
    fn bounds(&self) -> Aabb {
        match self.nodes.first() {
            Some(head) if !self.tris.is_empty() => head.box0(),
            _ => Aabb::EMPTY,
        }
    }

    walk_accel_methods!();
}

impl Bvh2WideNode {
    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        let mut best = Hit::miss(ray.tmax);
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        let Some(head) = self.nodes.first() else {
            return (best, prune);
        };
        if !ray.is_valid() {
            return (best, prune);
        }
        let widen = robustness.far_widen();
        let leaf = LeafRay::new(ray, robustness, mask);
        let inv = ray.inv_dir();
        let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
        let (origin_a, inv_a) = (Vec3A::from(ray.origin), Vec3A::from(inv));
        // The shared slab test: the scalar one (parallel-axis rule) for a ray parallel to
        // an axis, else its SIMD form, which equals it on such rays.
        let box_interval = |lo: [f32; 3], hi: [f32; 3], tmax: f32| {
            if parallel {
                let b = Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                };
                b.slab_interval(ray.origin, inv, ray.tmin, tmax, widen)
            } else {
                Aabb::slab_interval_nonparallel(
                    Vec3A::from_array(lo),
                    Vec3A::from_array(hi),
                    origin_a,
                    inv_a,
                    ray.tmin,
                    tmax,
                    widen,
                )
            }
        };
        // The root box, once, from the header.
        stats.nodes += 1;
        let (enter, exit) = box_interval(head.lo0, head.hi0, prune);
        let enters = enter <= exit; // false for NaN, as in the WGSL
        if !enters {
            return (best, prune);
        }
        let mut stack: [ChildRef; MAX_DEPTH] = [(0, 0); MAX_DEPTH];
        let mut sp = 0usize;
        let mut cur = head.child0();
        loop {
            if is_leaf(cur) {
                let first = cur.0 as usize;
                let count = (cur.1 >> COUNT_SHIFT) as usize;
                let tris = &self.tris[first..first + count];
                if leaf.test_leaf::<TEST>(tris, query == Query::Any, &mut best, &mut prune, stats) {
                    return (best, prune);
                }
            } else {
                let node = &self.nodes[cur.0 as usize];
                stats.nodes += 1;
                let (e0, x0) = box_interval(node.lo0, node.hi0, prune);
                let (e1, x1) = box_interval(node.lo1, node.hi1, prune);
                let (hit0, hit1) = (e0 <= x0, e1 <= x1);
                if hit0 && hit1 {
                    // Nearer entry first; equal entries: child 0 first.
                    let (near, far) = if e1 < e0 {
                        (node.child1(), node.child0())
                    } else {
                        (node.child0(), node.child1())
                    };
                    stack[sp] = far;
                    sp += 1;
                    cur = near;
                    continue;
                }
                if hit0 {
                    cur = node.child0();
                    continue;
                }
                if hit1 {
                    cur = node.child1();
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            cur = stack[sp];
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        (best, prune)
    }
}
