//! The CPU twin of `threaded.wgsl`, step for step: the copy of the ray's octant, walked in
//! array order (a missed inner node jumps to its skip index), the same slab and triangle
//! tests in the same operation order, and the same tie rule, all in f32. It visits the nodes
//! dfs-sign's twin visits, in the same order.

use super::{octant, Threaded};
use crate::accel::bvh::layouts::dfs_sign::DfsNodeRay;
use crate::accel::leaf_tri::{walk_accel_methods, LeafRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, MISS};

impl Accel for Threaded {
    fn bounds(&self) -> Aabb {
        if self.tris.is_empty() {
            Aabb::EMPTY
        } else {
            self.nodes[0].bbox()
        }
    }

    walk_accel_methods!();
}

impl Threaded {
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
        if !ray.is_valid() {
            return (best, prune);
        }
        let boxes = DfsNodeRay::new(ray, robustness);
        let leaf = LeafRay::new(ray, robustness, mask);
        let n = self.copy_len();
        let mut idx = octant(ray.dir) * n;
        let end = idx + n;
        while idx < end {
            let node = &self.nodes[idx];
            stats.nodes += 1;
            let enter = boxes.enters(node, prune);
            if enter {
                if node.is_leaf() {
                    let first = node.a as usize;
                    let tris = &self.tris[first..first + node.count() as usize];
                    if leaf.test_leaf::<TEST>(
                        tris,
                        query == Query::Any,
                        &mut best,
                        &mut prune,
                        stats,
                    ) {
                        return (best, prune);
                    }
                }
                idx += 1;
            } else if node.is_leaf() {
                idx += 1;
            } else {
                // Never backwards, as the WGSL (validate() ensures it anyway).
                idx = (node.a as usize).max(idx + 1);
            }
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        (best, prune)
    }
}
