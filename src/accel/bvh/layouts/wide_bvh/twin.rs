//! The CPU twin of `wide_bvh.wgsl`, step for step: the used slots' boxes through the shared
//! slab test (`Aabb::slab_interval`; for a ray with no parallel axis four at a time in SIMD
//! lanes, `SlabRay4`, which equals it, or for bvh8 on a CPU with AVX2 all eight in one
//! vector, `SlabRay4::intervals8`, which equals that), the same child order (entry
//! distance, then slot), the same stack of (node and slot, entry) entries popped only while
//! their entry is within the prune bound, and the shared leaf step (`LeafRay::test_leaf`:
//! triangle test, tie rule).

use std::mem::MaybeUninit;

use glam::{Vec3, Vec4};

use super::{stack_size, WideBvh, WideNode, INNER, MAX_STACK_SIZE};
use crate::accel::leaf_tri::{walk_accel_methods, with_leaf_test, LeafRay};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, SlabRay4, MISS, PARALLEL_INV};

/// A pushed child: its node and slot (`node << SLOT_BITS | slot`), and the entry distance its box
/// was entered at (WGSL `WideEntry`). 8 bytes, not the child and kind themselves (12): a
/// popped entry reads them again from the node, and the kernels' stack stays small.
#[derive(Clone, Copy, Debug)]
struct Entry {
    slot: u32,
    enter: f32,
}

impl<const W: usize> Accel for WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    fn bounds(&self) -> Aabb {
        let root = &self.nodes[0];
        (0..W)
            .filter(|&k| root.kind[k] != 0)
            .fold(Aabb::EMPTY, |b, k| b.union(root.bbox(k)))
    }

    // The walk compiled for AVX2 where the CPU has it: bvh8's eight slots tested in one
    // vector (0.72× → 0.82× of Embree on the bunny's primary rays); bvh4's, the same
    // source as for baseline x86-64, 0.74× → 0.77× (what the walk generic over the width
    // had cost it against its own 4-wide code).
    walk_accel_methods!(avx2);
}

impl<const W: usize> WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    /// [`Accel::intersect_pruned`] compiled with AVX2 (and the bit instructions every AVX2 CPU
    /// has); the CPU must have them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt,bmi1,lzcnt")]
    unsafe fn intersect_avx2(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        self.intersect_with::<true>(ray, query, robustness, mask, stats)
    }

    /// [`Accel::intersect_pruned`] with the slab test in SSE or (`AVX2`, for `intersect_avx2`
    /// alone) AVX2 lanes.
    #[inline(always)]
    fn intersect_with<const AVX2: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        // One specialised loop per triangle test (the choice is not re-made per triangle).
        with_leaf_test!(
            robustness,
            self.walk::<_, AVX2>(ray, query, robustness, mask, stats)
        )
    }
}

/// bvh8's slab test of all eight slots in one AVX2 vector, for the walk compiled with it
/// (`AVX2`); None for bvh4 or the walk without AVX2.
#[inline(always)]
fn intervals8<const W: usize, const AVX2: bool>(
    slab4: &SlabRay4,
    node: &WideNode<W>,
    tmax: f32,
) -> Option<(u32, [f32; W])> {
    #[cfg(target_arch = "x86_64")]
    if AVX2 && W == 8 {
        let lo = [&node.lo_x[..], &node.lo_y[..], &node.lo_z[..]];
        let hi = [&node.hi_x[..], &node.hi_y[..], &node.hi_z[..]];
        // SAFETY: `AVX2` is true only below `intersect_avx2`, which runs only where
        // `has_avx2()` said the CPU has it.
        let (e, hit) = unsafe { slab4.intervals8(lo, hi, tmax) };
        let mut enter = [0.0; W];
        enter.copy_from_slice(&e);
        return Some((hit, enter));
    }
    let _ = (slab4, node, tmax);
    None
}

/// The order hit children are visited in: `rank[k]` = how many children of the bit set
/// `hit` come before slot k by (entry distance, slot). Slots not hit get no rank.
#[inline(always)]
fn ranks<const W: usize>(hit: u32, enter: [f32; W]) -> [u32; W] {
    let mut rank = [0u32; W];
    let mut js = hit;
    while js != 0 {
        let j = js.trailing_zeros() as usize;
        js &= js - 1;
        let mut ks = hit;
        while ks != 0 {
            let k = ks.trailing_zeros() as usize;
            ks &= ks - 1;
            rank[k] += (enter[j] < enter[k] || (enter[j] == enter[k] && j < k)) as u32;
        }
    }
    rank
}

impl<const W: usize> WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8, const AVX2: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        if !ray.is_valid() {
            return (Hit::miss(ray.tmax), f32::NAN);
        }
        // The shared slab test: the scalar one (parallel-axis rule) for a ray parallel to
        // an axis, one slot at a time; else four slots at a time in SIMD lanes, which equal
        // it.
        // Two loops, so that the common one has no choice to make per node.
        let inv = ray.inv_dir();
        let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
        match parallel {
            true => self.walk_in::<TEST, true, AVX2>(ray, inv, query, robustness, mask, stats),
            false => self.walk_in::<TEST, false, AVX2>(ray, inv, query, robustness, mask, stats),
        }
    }

    /// [`WideBvh::walk`] for a valid ray with reciprocal direction `inv`, parallel to an axis
    /// or not (`PARALLEL`).
    #[inline(always)]
    fn walk_in<const TEST: u8, const PARALLEL: bool, const AVX2: bool>(
        &self,
        ray: &Ray,
        inv: Vec3,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        let mut best = Hit::miss(ray.tmax);
        let widen = robustness.far_widen();
        let leaf = LeafRay::new(ray, robustness, mask);
        let slab4 = SlabRay4::new(ray.origin, inv, ray.tmin, widen);
        let intervals = |node: &WideNode<W>, tmax: f32| -> (u32, [f32; W]) {
            if PARALLEL {
                let (mut hit, mut enter) = (0u32, [0.0f32; W]);
                for (k, slot_enter) in enter.iter_mut().enumerate() {
                    if node.kind[k] != 0 {
                        let b = node.bbox(k);
                        let (e, x) = b.slab_interval(ray.origin, inv, ray.tmin, tmax, widen);
                        *slot_enter = e;
                        hit |= ((e <= x) as u32) << k;
                    }
                }
                (hit, enter)
            } else if let Some((hit, enter)) = intervals8::<W, AVX2>(&slab4, node, tmax) {
                (hit & node.used(), enter)
            } else {
                // Four slots at a time.
                let (mut hit, mut enter) = (0u32, [0.0f32; W]);
                for g in (0..W / 4).map(|i| 4 * i) {
                    let four = |a: &[f32; W]| Vec4::from_slice(&a[g..g + 4]);
                    let lo = [&node.lo_x, &node.lo_y, &node.lo_z].map(four);
                    let hi = [&node.hi_x, &node.hi_y, &node.hi_z].map(four);
                    let (e, x) = slab4.intervals(lo, hi, tmax);
                    hit |= e.cmple(x).bitmask() << g;
                    e.write_to_slice(&mut enter[g..g + 4]);
                }
                (hit & node.used(), enter)
            }
        };
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        // Not zeroed (768 bytes per ray for bvh4, a twentieth of a primary ray's time): an
        // entry is read only below `sp`, where it was written. Sized for the widest layout
        // (a generic const cannot size an array); `validate` bounds the entries used by
        // `stack_size(W)` (the kernel's array holds those of the tree's own depth).
        let mut stack = [MaybeUninit::<Entry>::uninit(); MAX_STACK_SIZE];
        let mut sp = 0usize;
        let (mut child, mut kind) = (0u32, INNER);
        'walk: loop {
            let mut descended = false;
            if kind == INNER {
                let index = child;
                let node = &self.nodes[index as usize];
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
                            slot: index << Self::SLOT_BITS | far as u32,
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
                                    slot: index << Self::SLOT_BITS | k as u32,
                                    enter: e,
                                });
                            }
                        }
                        sp += (n - 1) as usize;
                    }
                    debug_assert!(sp <= stack_size(W));
                }
            } else {
                let first = child as usize;
                let tris = &self.tris[first..first + kind as usize];
                if leaf.test_leaf::<TEST>(tris, query == Query::Any, &mut best, &mut prune, stats) {
                    return (best, prune);
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
                        let node = &self.nodes[(e.slot >> Self::SLOT_BITS) as usize];
                        let k = (e.slot & ((1 << Self::SLOT_BITS) - 1)) as usize;
                        (child, kind) = (node.child[k], node.kind[k]);
                        break;
                    }
                }
            }
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        (best, prune)
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
