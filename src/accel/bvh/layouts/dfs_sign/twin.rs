//! The CPU twin of `dfs_sign.wgsl`, step for step: the same stack discipline (push the far
//! child, descend into the near one), the same ray-sign child order, the same slab and
//! triangle tests in the same operation order, and the same tie rule, all in f32.

use std::mem::MaybeUninit;

use super::{DfsNodeRay, DfsSign};
use crate::accel::bvh::MAX_DEPTH;
use crate::accel::leaf_tri::{walk_accel_methods, LeafRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, MISS};

impl Accel for DfsSign {
    fn bounds(&self) -> Aabb {
        if self.tris.is_empty() {
            Aabb::EMPTY
        } else {
            self.nodes[0].bbox()
        }
    }

    walk_accel_methods!();
}

impl DfsSign {
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
        // Left uninitialised (only pushed entries are read): zeroing it for every ray is a
        // few percent of a short trace.
        let mut stack = [MaybeUninit::<u32>::uninit(); MAX_DEPTH];
        let mut sp = 0usize;
        let mut idx = 0usize;
        loop {
            let node = &self.nodes[idx];
            stats.nodes += 1;
            let enter = boxes.enters(node, prune);
            if enter {
                if !node.is_leaf() {
                    let (first, second) = (idx + 1, node.a as usize);
                    let (near, far) = if ray.dir[node.axis()] < 0.0 {
                        (second, first)
                    } else {
                        (first, second)
                    };
                    stack[sp] = MaybeUninit::new(far as u32);
                    sp += 1;
                    idx = near;
                    continue;
                }
                let first = node.a as usize;
                let tris = &self.tris[first..first + node.count() as usize];
                if leaf.test_leaf::<TEST>(tris, query == Query::Any, &mut best, &mut prune, stats) {
                    return (best, prune);
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written by a push above.
            idx = unsafe { stack[sp].assume_init() } as usize;
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        (best, prune)
    }
}
