//! The seed's full-sweep SAH build. Primitives are sorted by centroid once per axis at the
//! root; every node sweeps each sorted list right→left (areas of the right parts) and
//! left→right (areas of the left parts, and the cost of every candidate). After the split
//! the other two lists are partitioned stably, so they stay sorted without re-sorting:
//! O(N log N) in all.
//!
//! Above [`BuildOptions::exact_below`] primitives (1024 by default) a node picks its split
//! by binning instead (64 bins per axis, the binned builder's code) and hands its children
//! over to the exact sweep once they are small enough: each handed-over subtree is sorted
//! once per axis and swept as above. The top levels are where the sweep is slowest (its
//! lists outgrow the caches) and where 64 bins lose least: the tree's SAH stays within
//! 0.5 % of the full sweep's on every model measured (docs/src/results). With
//! `exact_below = usize::MAX` every node is swept, the seed's build exactly.
//!
//! How it goes fast: the lists hold 32-byte references (box and index, [`Ref`]) instead of
//! indices, so sweeps and partitions stream through memory rather than gather boxes; the
//! three axes are swept in one loop (three independent chains of box unions); a list is
//! sorted by (centroid, index), so a reference's side is decided by its own centroid against
//! the first reference right of the split, with no side flags looked up; a partition copies
//! into a spare array of the same length and the two swap roles, so every node works in its
//! own slices of arrays split alongside the lists and nothing is allocated below the root.

use glam::Vec3A;

use super::binned::{self, Handover, Top, MAX_BINS};
use super::prim_ref::{bounds, box_area, BoxA, Ref};
use super::prims::{join, Prims, PARALLEL_MIN};
use super::tree::{leaf, Kids, Node};
use super::BuildOptions;
use crate::geometry::Aabb;

pub(crate) fn build(prims: Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let exact = |refs: &mut [Ref], bbox: BoxA, offset: usize, depth: usize| {
        subtree(opts, refs, bbox, offset, depth)
    };
    let top = Top {
        bins: MAX_BINS,
        handover: Some(Handover {
            below: opts.exact_below.max(1),
            build: &exact,
        }),
    };
    binned::build_with(prims, opts, &top)
}

/// The exact sweep over a subtree's references, left in leaf order.
fn subtree(opts: &BuildOptions, refs: &mut [Ref], bbox: BoxA, offset: usize, depth: usize) -> Node {
    let n = refs.len();
    let par = opts.parallel && n >= PARALLEL_MIN;
    let (mut x, (mut y, mut z)) = {
        let refs: &[Ref] = refs;
        let in_index_order = refs.windows(2).all(|w| w[0].id() < w[1].id());
        let sorted = |axis: usize| sorted_by_centroid(refs, axis, in_index_order);
        join(par, || sorted(0), || join(par, || sorted(1), || sorted(2)))
    };
    let mut spare = x.clone();
    let mut right_areas = vec![Vec3A::ZERO; n];
    let work = Work {
        lists: [&mut x, &mut y, &mut z],
        spare: &mut spare,
        right_areas: &mut right_areas,
        order: refs,
    };
    node(opts, work, bbox, offset, depth)
}

/// A node's working memory: the three lists sorted on x, y, z, a spare array, the right
/// parts' areas and the leaf order it writes, all the same length (the node's primitives).
struct Work<'a> {
    lists: [&'a mut [Ref]; 3],
    spare: &'a mut [Ref],
    right_areas: &'a mut [Vec3A],
    order: &'a mut [Ref],
}

impl Work<'_> {
    /// A leaf of the node's primitives, in x order.
    fn leaf(self, bbox: Aabb, offset: usize) -> Node {
        self.order.copy_from_slice(self.lists[0]);
        leaf(bbox, offset, self.order.len())
    }
}

/// A centroid coordinate as an unsigned key ordered like `f32::total_cmp`.
#[inline(always)]
fn sortable(c: f32) -> u32 {
    let b = c.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 1 << 31
    }
}

/// The order of the list on `axis`: centroid, then index (deterministic, unique).
#[inline(always)]
pub(crate) fn order_key(r: &Ref, axis: usize) -> u64 {
    (sortable(r.centroid()[axis]) as u64) << 32 | r.id() as u64
}

/// The references in list order on `axis`. References in index order (the whole mesh's)
/// take a radix sort of their centroid keys, which is stable, so equal centroids stay in
/// index order; others a radix sort of their unique (centroid, index) keys.
pub(crate) fn sorted_by_centroid(refs: &[Ref], axis: usize, in_index_order: bool) -> Vec<Ref> {
    if in_index_order {
        let mut keys: Vec<(u32, u32)> = (refs.iter().enumerate())
            .map(|(i, r)| (sortable(r.centroid()[axis]), i as u32))
            .collect();
        radsort::sort_by_key(&mut keys, |k| k.0);
        keys.iter().map(|&(_, i)| refs[i as usize]).collect()
    } else {
        let mut keys: Vec<(u64, u32)> = (refs.iter().enumerate())
            .map(|(i, r)| (order_key(r, axis), i as u32))
            .collect();
        radsort::sort_by_key(&mut keys, |k| k.0);
        keys.iter().map(|&(_, i)| refs[i as usize]).collect()
    }
}

fn node(opts: &BuildOptions, w: Work, bbox: BoxA, offset: usize, depth: usize) -> Node {
    let n = w.lists[0].len();
    let aabb = bbox.aabb();
    let forced = opts.depth_forces_median(depth, n);
    if n == 1 || (opts.leaf_beats_any_split(n) && !forced) {
        return w.leaf(aabb, offset);
    }
    // Each list is sorted on its axis: the centroid bounds are its ends.
    let cbox = Aabb {
        lo: glam::Vec3::from_array(std::array::from_fn(|a| w.lists[a][0].centroid()[a])),
        hi: glam::Vec3::from_array(std::array::from_fn(|a| w.lists[a][n - 1].centroid()[a])),
    };
    let (axis, k, lbox) = if forced || cbox.extent() == glam::Vec3::ZERO {
        // Depth cap, or identical centroids (no SAH candidate separates them): the object
        // median keeps the tree balanced. A leaf is still taken when the SAH prefers it.
        let cost = opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
        if !forced && opts.prefers_leaf(n, cost) {
            return w.leaf(aabb, offset);
        }
        let axis = cbox.longest_axis();
        (axis, n / 2, bounds(&w.lists[axis][..n / 2]).0)
    } else {
        match sweep(opts, &w.lists, w.right_areas, aabb.area()) {
            Some(s) if !opts.prefers_leaf(n, s.cost) => (s.axis, s.k, s.left),
            Some(_) => return w.leaf(aabb, offset),
            // Every candidate's cost overflowed (boxes near f32::MAX): halve the node.
            None if n > opts.max_leaf => (0, n / 2, bounds(&w.lists[0][..n / 2]).0),
            None => return w.leaf(aabb, offset),
        }
    };

    let Work {
        lists,
        mut spare,
        right_areas,
        order,
    } = w;
    let pivot = order_key(&lists[axis][k], axis);
    let rbox = bounds(&lists[axis][k..]).0;
    let [mut a, mut b, mut c] = lists;
    for (i, list) in [&mut a, &mut b, &mut c].into_iter().enumerate() {
        if i != axis {
            partition_into(list, spare, k, |r| order_key(r, axis) < pivot);
            std::mem::swap(list, &mut spare);
        }
    }
    let (a0, a1) = a.split_at_mut(k);
    let (b0, b1) = b.split_at_mut(k);
    let (c0, c1) = c.split_at_mut(k);
    let (s0, s1) = spare.split_at_mut(k);
    let (r0, r1) = right_areas.split_at_mut(k);
    let (o0, o1) = order.split_at_mut(k);
    let left = Work {
        lists: [a0, b0, c0],
        spare: s0,
        right_areas: r0,
        order: o0,
    };
    let right = Work {
        lists: [a1, b1, c1],
        spare: s1,
        right_areas: r1,
        order: o1,
    };
    let kids = Kids::reserve();
    let (l, r) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(opts, left, lbox, offset, depth + 1),
        || node(opts, right, rbox, offset + k, depth + 1),
    );
    kids.inner(aabb, axis, [l, r])
}

/// The best split of a node.
pub(crate) struct Split {
    pub cost: f32,
    pub axis: usize,
    /// Primitives on the left.
    pub k: usize,
    /// Their bounds.
    pub left: BoxA,
}

/// Best split found by the sweep (None when no position separates two centroids). Per axis
/// the first position with the smallest A_L·N_L + A_R·N_R wins (it orders the candidates as
/// the cost does, without a division each); then the axes by cost, in order.
pub(crate) fn sweep(
    opts: &BuildOptions,
    lists: &[&mut [Ref]; 3],
    right_areas: &mut [Vec3A],
    area: f32,
) -> Option<Split> {
    let n = lists[0].len();
    let [x, y, z] = [&lists[0][..n], &lists[1][..n], &lists[2][..n]];
    let right_areas = &mut right_areas[..n];
    let mut b = [BoxA::EMPTY; 3];
    for k in (1..n).rev() {
        b = [
            b[0].union(x[k].bbox()),
            b[1].union(y[k].bbox()),
            b[2].union(z[k].bbox()),
        ];
        right_areas[k] = Vec3A::new(box_area(b[0]), box_area(b[1]), box_area(b[2]));
    }
    let mut best_key = [f32::INFINITY; 3];
    let mut best_k = [0usize; 3];
    let mut best_left = [BoxA::EMPTY; 3];
    let mut b = [BoxA::EMPTY; 3];
    for k in 1..n {
        b = [
            b[0].union(x[k - 1].bbox()),
            b[1].union(y[k - 1].bbox()),
            b[2].union(z[k - 1].bbox()),
        ];
        let left_area = Vec3A::new(box_area(b[0]), box_area(b[1]), box_area(b[2]));
        let key = left_area * k as f32 + right_areas[k] * (n - k) as f32;
        for a in 0..3 {
            if key[a] < best_key[a] {
                best_key[a] = key[a];
                best_k[a] = k;
                best_left[a] = b[a];
            }
        }
    }
    let mut best: Option<Split> = None;
    for a in 0..3 {
        let k = best_k[a];
        if k == 0 {
            continue;
        }
        let cost = opts.split_cost(area, box_area(best_left[a]), k, right_areas[k][a], n - k);
        if best.as_ref().is_none_or(|b| cost < b.cost) {
            best = Some(Split {
                cost,
                axis: a,
                k,
                left: best_left[a],
            });
        }
    }
    best
}

/// Copies `list` into `out`, the references `is_left` picks first (exactly `k` of them),
/// both groups in their original order. Branch-free: the side picks the cursor (a
/// conditional move), not the path.
fn partition_into(list: &[Ref], out: &mut [Ref], k: usize, is_left: impl Fn(&Ref) -> bool) {
    let (mut l, mut r) = (0, k);
    for &x in list {
        let left = is_left(&x);
        out[if left { l } else { r }] = x;
        l += left as usize;
        r += !left as usize;
    }
    debug_assert_eq!((l, r), (k, list.len()));
}
