//! The CPU twin of `dfs_distance.wgsl`, step for step: both children's boxes tested at an
//! inner node, the nearer entered first (the first child on equal entries), the farther
//! pushed with its entry distance and culled on the pop against the prune bound.

use std::mem::MaybeUninit;

use super::{DfsDistance, DfsNode};
use crate::accel::bvh::layouts::dfs_sign::DfsNodeRay;
use crate::accel::bvh::MAX_DEPTH;
use crate::accel::leaf_tri::{walk_accel_methods, LeafRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness};

impl Accel for DfsDistance {
    fn bounds(&self) -> Aabb {
        self.flat.bounds()
    }

    walk_accel_methods!();
}

impl DfsDistance {
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
        let mut prune = prune_bound(best.t);
        if !ray.is_valid() {
            return (best, prune);
        }
        let nodes = self.nodes();
        let boxes = DfsNodeRay::new(ray, robustness);
        let leaf = LeafRay::new(ray, robustness, mask);
        // Node i's box for the ray, one node load (WGSL dfs_distance_load + slab_interval).
        let interval = |n: &DfsNode, prune: f32| boxes.interval(n, prune);
        let mut node = &nodes[0];
        stats.nodes += 1;
        let (enter, exit) = interval(node, prune);
        // Written as the WGSL does: NaN bounds are a miss.
        let enters = enter <= exit;
        if !enters {
            return (best, prune);
        }
        // Left uninitialised (only pushed entries are read): zeroing it for every ray is a
        // few percent of a short trace.
        let mut stack = [MaybeUninit::<(u32, f32)>::uninit(); MAX_DEPTH];
        let mut sp = 0usize;
        let mut index = 0usize;
        loop {
            if !node.is_leaf() {
                // The first child follows its parent: its index travels with the node.
                let (a, b) = (index + 1, node.a as usize);
                let (na, nb) = (&nodes[a], &nodes[b]);
                stats.nodes += 2;
                let (ea, xa) = interval(na, prune);
                let (eb, xb) = interval(nb, prune);
                match (ea <= xa, eb <= xb) {
                    (true, true) => {
                        // Equal entries: the first child first.
                        let (near, far, far_enter) = if eb < ea { (b, a, ea) } else { (a, b, eb) };
                        stack[sp] = MaybeUninit::new((far as u32, far_enter));
                        sp += 1;
                        (index, node) = (near, &nodes[near]);
                        continue;
                    }
                    (true, false) => {
                        (index, node) = (a, na);
                        continue;
                    }
                    (false, true) => {
                        (index, node) = (b, nb);
                        continue;
                    }
                    (false, false) => {}
                }
            } else {
                let first = node.a as usize;
                let tris = &self.flat.tris[first..first + node.count() as usize];
                if leaf.test_leaf::<TEST>(tris, query == Query::Any, &mut best, &mut prune, stats) {
                    return (best, prune);
                }
            }
            // Pop the next child whose box the ray enters before the best hit (with slack).
            loop {
                if sp == 0 {
                    return (best, prune);
                }
                sp -= 1;
                // SAFETY: every entry below the old `sp` was written by a push above.
                let (i, enter) = unsafe { stack[sp].assume_init() };
                if enter <= prune {
                    index = i as usize;
                    node = &nodes[index];
                    stats.nodes += 1;
                    break;
                }
            }
        }
    }
}
