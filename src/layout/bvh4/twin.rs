//! The CPU twin of `bvh4.wgsl`, step for step: the used slots' boxes through the shared slab
//! test (`Aabb::slab_interval`; for a ray with no parallel axis all four at once in SIMD
//! lanes, `SlabRay4`, which equals it), the same child order (entry distance, then slot),
//! the same stack of (node and slot, entry) entries popped only while their entry is within
//! the prune bound, and the shared leaf step (`LeafRay::test_leaf`: triangle test, tie rule).

use std::mem::MaybeUninit;

use glam::{UVec4, Vec3, Vec4};

use super::{Bvh4, Bvh4Node, INNER, SLOT_BITS, SLOT_MASK, STACK_SIZE, WIDTH};
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, SlabRay4, MISS, PARALLEL_INV};
use crate::layout::leaf_tri::{with_leaf_test, LeafRay};

/// A pushed child: its node and slot (`node << SLOT_BITS | slot`), and the entry distance its box
/// was entered at (WGSL `Bvh4Entry`). 8 bytes, not the child and kind themselves (12): a
/// popped entry reads them again from the node, and the kernels' stack stays small.
#[derive(Clone, Copy, Debug)]
struct Entry {
    slot: u32,
    enter: f32,
}

impl Accel for Bvh4 {
    fn bounds(&self) -> Aabb {
        let root = &self.nodes[0];
        (0..WIDTH)
            .filter(|&k| root.kind[k] != 0)
            .fold(Aabb::EMPTY, |b, k| b.union(root.bbox(k)))
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
        with_leaf_test!(robustness, self.walk(ray, query, robustness, stats))
    }
}

/// The order hit children are visited in: `rank[k]` = how many children of the bit set
/// `hit` come before slot k by (entry distance, slot). Slots not hit get no rank.
#[inline(always)]
fn ranks(hit: u32, enter: [f32; WIDTH]) -> [u32; WIDTH] {
    let mut rank = [0u32; WIDTH];
    for j in 0..WIDTH {
        if hit >> j & 1 != 0 {
            for (k, r) in rank.iter_mut().enumerate() {
                *r += (enter[j] < enter[k] || (enter[j] == enter[k] && j < k)) as u32;
            }
        }
    }
    rank
}

impl Bvh4 {
    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        if !ray.is_valid() {
            return Hit::miss(ray.tmax);
        }
        // The shared slab test: the scalar one (parallel-axis rule) for a ray parallel to
        // an axis, one slot at a time; else all four slots in SIMD lanes, which equal it.
        // Two loops, so that the common one has no choice to make per node.
        let inv = ray.inv_dir();
        let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
        match parallel {
            true => self.walk_in::<TEST, true>(ray, inv, query, robustness, stats),
            false => self.walk_in::<TEST, false>(ray, inv, query, robustness, stats),
        }
    }

    /// [`Bvh4::walk`] for a valid ray with reciprocal direction `inv`, parallel to an axis
    /// or not (`PARALLEL`).
    #[inline(always)]
    fn walk_in<const TEST: u8, const PARALLEL: bool>(
        &self,
        ray: &Ray,
        inv: Vec3,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        let widen = robustness.far_widen();
        let leaf = LeafRay::new(ray, robustness);
        let slab4 = SlabRay4::new(ray.origin, inv, ray.tmin, widen);
        let intervals = |node: &Bvh4Node, tmax: f32| -> (u32, [f32; WIDTH]) {
            let used = UVec4::from_array(node.kind).cmpne(UVec4::ZERO).bitmask();
            if PARALLEL {
                let (mut hit, mut enter) = (0u32, [0.0f32; WIDTH]);
                for (k, slot_enter) in enter.iter_mut().enumerate() {
                    if used >> k & 1 != 0 {
                        let b = node.bbox(k);
                        let (e, x) = b.slab_interval(ray.origin, inv, ray.tmin, tmax, widen);
                        *slot_enter = e;
                        hit |= ((e <= x) as u32) << k;
                    }
                }
                (hit, enter)
            } else {
                let lo = [node.lo_x, node.lo_y, node.lo_z].map(Vec4::from_array);
                let hi = [node.hi_x, node.hi_y, node.hi_z].map(Vec4::from_array);
                let (e, x) = slab4.intervals(lo, hi, tmax);
                (e.cmple(x).bitmask() & used, e.to_array())
            }
        };
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        // Not zeroed (768 bytes per ray, a twentieth of a primary ray's time): an entry is
        // read only below `sp`, where it was written.
        let mut stack = [MaybeUninit::<Entry>::uninit(); STACK_SIZE];
        let mut sp = 0usize;
        let (mut child, mut kind) = (0u32, INNER);
        'walk: loop {
            let mut descended = false;
            if kind == INNER {
                let index = child;
                let node: &Bvh4Node = &self.nodes[index as usize];
                stats.nodes += 1;
                // Used slots whose boxes the ray enters before the prune bound.
                let (hit, enter) = intervals(node, prune);
                if hit != 0 {
                    descended = true;
                    // One or two children without counting bits (no popcnt in baseline x86-64).
                    let rest = hit & (hit - 1);
                    if rest == 0 {
                        let k = hit.trailing_zeros() as usize;
                        (child, kind) = (node.child[k], node.kind[k]);
                    } else if rest & (rest - 1) == 0 {
                        // The common case of the rank order below, without the ranks.
                        let a = hit.trailing_zeros() as usize;
                        let b = (31 - hit.leading_zeros()) as usize;
                        let (near, far) = if enter[b] < enter[a] { (b, a) } else { (a, b) };
                        (child, kind) = (node.child[near], node.kind[near]);
                        stack[sp].write(Entry {
                            slot: index << SLOT_BITS | far as u32,
                            enter: enter[far],
                        });
                        sp += 1;
                    } else {
                        // The nearest is visited next; the others pushed farthest first.
                        let n = hit.count_ones();
                        let rank = ranks(hit, enter);
                        for (k, (&r, &e)) in rank.iter().zip(&enter).enumerate() {
                            if hit >> k & 1 == 0 {
                                continue;
                            }
                            if r == 0 {
                                (child, kind) = (node.child[k], node.kind[k]);
                            } else {
                                stack[sp + (n - 1 - r) as usize].write(Entry {
                                    slot: index << SLOT_BITS | k as u32,
                                    enter: e,
                                });
                            }
                        }
                        sp += (n - 1) as usize;
                    }
                }
            } else {
                let first = child as usize;
                let tris = &self.tris[first..first + kind as usize];
                if leaf.test_leaf::<TEST>(tris, query == Query::Any, &mut best, &mut prune, stats) {
                    return best;
                }
            }
            if !descended {
                // The nearest entry whose box is still entered before the prune bound (the
                // slab test again with the new bound: only its tmax changed).
                loop {
                    if sp == 0 {
                        break 'walk;
                    }
                    sp -= 1;
                    // SAFETY: every entry below the stack pointer was written by a push.
                    let e = unsafe { stack[sp].assume_init() };
                    if e.enter <= prune {
                        let node = &self.nodes[(e.slot >> SLOT_BITS) as usize];
                        let k = (e.slot & SLOT_MASK) as usize;
                        (child, kind) = (node.child[k], node.kind[k]);
                        break;
                    }
                }
            }
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_order_by_entry_then_slot() {
        let r = ranks(0b1011, [2.0, 1.0, 0.0, 1.0]);
        assert_eq!((r[0], r[1], r[3]), (2, 0, 1));
        let r = ranks(0b1111, [-0.0, 0.0, 0.0, -1.0]);
        assert_eq!(r, [1, 2, 3, 0]);
    }
}
