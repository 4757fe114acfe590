//! Binned SAH (Wald 2007): K equal bins over the centroid bounds on each axis, filled in
//! one pass over the node's primitives; the partition is in place. The builder moves
//! 32-byte primitive references (box in SIMD lanes, index in a spare lane) rather than
//! indices, so every pass streams through memory; a node costs two linear passes (bin,
//! partition), the partition also yielding the children's centroid bounds. The split
//! candidates of the three axes are evaluated together in SIMD lanes.

use glam::{Mat3A, Vec3A};

use super::prim_ref::{bounds, box_area, BoxA, Ref};

use super::prims::{join, Prims, PARALLEL_MIN};
use super::tree::{leaf, Node};
use super::BuildOptions;

/// Most bins per axis the builder supports (the CLI refuses more).
pub const MAX_BINS: usize = 64;

pub(crate) fn build(prims: Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let top = Top {
        bins: opts.bins.clamp(2, MAX_BINS),
        handover: None,
    };
    build_with(prims, opts, &top)
}

/// Builds the subtree over a node's references (leaving them in leaf order), given their
/// bounds, the subtree's first leaf-order position and its depth.
pub(crate) type SubtreeBuilder<'a> = &'a (dyn Fn(&mut [Ref], BoxA, usize, usize) -> Node + Sync);

/// A builder that takes over the nodes of at most `below` primitives.
pub(crate) struct Handover<'a> {
    pub below: usize,
    pub build: SubtreeBuilder<'a>,
}

/// How the binned recursion runs: its bins per axis, and where it hands over.
pub(crate) struct Top<'a> {
    pub bins: usize,
    pub handover: Option<Handover<'a>>,
}

/// The binned build with `top`'s bins, handing small nodes over where it says.
pub(crate) fn build_with(prims: Prims, opts: &BuildOptions, top: &Top) -> (Node, Vec<u32>) {
    let mut refs = prims.refs;
    let (bbox, cbox) = bounds(&refs);
    let root = node(opts, top, &mut refs, bbox, cbox, 0, 0);
    (root, refs.iter().map(Ref::id).collect())
}

#[derive(Clone, Copy)]
struct Bin {
    bbox: BoxA,
    count: usize,
}

const EMPTY_BIN: Bin = Bin {
    bbox: BoxA::EMPTY,
    count: 0,
};

/// Bin of a centroid coordinate. `(c − lo)·scale` lies in [0, K] (c within the centroid
/// bounds, scale finite), so the truncating conversion needs no saturation checks.
#[inline(always)]
fn bin_index(c: f32, lo: f32, scale: f32, last: usize) -> usize {
    let x = (c - lo) * scale;
    debug_assert!((0.0..=(last + 1) as f32 * 1.001).contains(&x));
    // SAFETY: x is finite and in [0, K + ε] as argued above, so it fits an i32.
    (unsafe { x.to_int_unchecked::<i32>() } as usize).min(last)
}

/// Bin index of a centroid on every axis at once; a flat axis (scale 0) maps all to bin 0.
/// The same values as [`bin_index`] per axis (clamping before truncating is equivalent),
/// converted in one SIMD instruction.
#[inline(always)]
fn bin_of(c: Vec3A, lo: Vec3A, scale: Vec3A, last: usize) -> [usize; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128i, _mm_cvttps_epi32};
        let x = ((c - lo) * scale).min(Vec3A::splat(last as f32));
        // SAFETY: SSE2 is part of x86_64. Lanes x, y, z lie in [0, last] (see bin_index),
        // so truncation is exact; lane w is never read.
        let k: [i32; 4] = unsafe { std::mem::transmute::<__m128i, _>(_mm_cvttps_epi32(x.into())) };
        [k[0] as usize, k[1] as usize, k[2] as usize]
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::array::from_fn(|a| bin_index(c[a], lo[a], scale[a], last))
}

fn node(
    opts: &BuildOptions,
    top: &Top,
    idx: &mut [Ref],
    bbox_simd: BoxA,
    cbox: BoxA,
    offset: usize,
    depth: usize,
) -> Node {
    let n = idx.len();
    if let Some(h) = top.handover.as_ref().filter(|h| n <= h.below) {
        return (h.build)(idx, bbox_simd, offset, depth);
    }
    let bbox = bbox_simd.aabb();
    if n == 1 || (opts.leaf_beats_any_split(n) && !opts.depth_forces_median(depth, n)) {
        return leaf(bbox, offset, n);
    }
    let nbins = top.bins;
    let ext = cbox.hi - cbox.lo;
    let scale = nbins as f32 / ext;
    // A flat axis, or one so thin that K/extent overflows, is not binned.
    let splittable = ext.cmpgt(Vec3A::ZERO) & scale.is_finite_mask();
    let scale = Vec3A::select(splittable, scale, Vec3A::ZERO);
    // (cost, axis, first bin on the right, left box, right box)
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    if !opts.depth_forces_median(depth, n) && splittable.any() {
        best = if n <= SMALL_NODE {
            best_split_small(opts, idx, nbins, cbox.lo, scale, splittable, bbox.area())
        } else {
            let fill = |refs: &[Ref]| fill_bins(refs, nbins, cbox.lo, scale);
            // The top nodes, where the subtree parallelism has not started yet, bin in chunks
            // on all threads (the union of boxes and sum of counts are order-independent).
            let bins = if opts.parallel && n >= 4 * PARALLEL_MIN {
                use rayon::prelude::*;
                idx.par_chunks(PARALLEL_MIN)
                    .map(fill)
                    .reduce_with(merge_bins)
                    .unwrap_or_else(|| fill(idx))
            } else {
                fill(idx)
            };
            best_split(opts, &bins, nbins, splittable, bbox.area(), n)
        };
    }
    let (k, axis, lbox, rbox, lc, rc) = match best {
        Some((cost, axis, s, lbox, rbox)) => {
            if opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let (lo, scale) = (cbox.lo[axis], scale[axis]);
            let (k, lc, rc) = partition(idx, |c| bin_index(c[axis], lo, scale, nbins - 1) < s);
            (k, axis, lbox, rbox, lc, rc)
        }
        None => {
            // Depth cap or identical centroids: object median.
            let cost = opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
            if !opts.depth_forces_median(depth, n) && opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let axis = cbox.aabb().longest_axis();
            let k = n / 2;
            idx.select_nth_unstable_by(k, |a, b| {
                let (ca, cb) = (a.centroid()[axis], b.centroid()[axis]);
                ca.total_cmp(&cb).then(a.id().cmp(&b.id()))
            });
            let (lbox, lc) = bounds(&idx[..k]);
            let (rbox, rc) = bounds(&idx[k..]);
            (k, axis, lbox, rbox, lc, rc)
        }
    };
    let (l, r) = idx.split_at_mut(k);
    let (a, b) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(opts, top, l, lbox, lc, offset, depth + 1),
        || node(opts, top, r, rbox, rc, offset + k, depth + 1),
    );
    Node::inner(bbox, axis, [a, b])
}

/// A bin on all three axes at once, transposed so that each vector holds one coordinate
/// of the three axes' bins: lane a of `lo[0]` is bins[s][a].lo.x.
struct Lanes {
    lo: [Vec3A; 3],
    hi: [Vec3A; 3],
    count: Vec3A,
}

impl Lanes {
    const EMPTY: Lanes = Lanes {
        lo: [Vec3A::splat(f32::MAX); 3],
        hi: [Vec3A::splat(-f32::MAX); 3],
        count: Vec3A::ZERO,
    };

    fn of(bin: &[Bin; 3]) -> Lanes {
        let lo = Mat3A::from_cols(bin[0].bbox.lo, bin[1].bbox.lo, bin[2].bbox.lo).transpose();
        let hi = Mat3A::from_cols(bin[0].bbox.hi, bin[1].bbox.hi, bin[2].bbox.hi).transpose();
        Lanes {
            lo: [lo.x_axis, lo.y_axis, lo.z_axis],
            hi: [hi.x_axis, hi.y_axis, hi.z_axis],
            count: Vec3A::new(
                bin[0].count as f32,
                bin[1].count as f32,
                bin[2].count as f32,
            ),
        }
    }

    #[inline(always)]
    fn add(&mut self, o: &Lanes) {
        for c in 0..3 {
            self.lo[c] = self.lo[c].min(o.lo[c]);
            self.hi[c] = self.hi[c].max(o.hi[c]);
        }
        self.count += o.count;
    }

    /// The three boxes' surface areas.
    #[inline(always)]
    fn area(&self) -> Vec3A {
        let (ex, ey, ez) = (
            self.hi[0] - self.lo[0],
            self.hi[1] - self.lo[1],
            self.hi[2] - self.lo[2],
        );
        2.0 * (ex * ey + ey * ez + ez * ex)
    }
}

/// The cheapest split over all bin boundaries of the splittable axes: (cost, axis, first
/// bin on the right, left box, right box). The three axes are swept together in SIMD lanes;
/// per axis the first boundary with the smallest A_L·N_L + A_R·N_R wins (it orders the
/// candidates as the cost does, without a division each), then the axes by cost in order.
fn best_split(
    opts: &BuildOptions,
    bins: &[[Bin; 3]],
    nbins: usize,
    splittable: glam::BVec3A,
    area: f32,
    n: usize,
) -> Option<(f32, usize, usize, BoxA, BoxA)> {
    // Right to left: area and count of everything right of each boundary.
    let mut r_area = [Vec3A::ZERO; MAX_BINS];
    let mut r_count = [Vec3A::ZERO; MAX_BINS];
    let mut acc = Lanes::EMPTY;
    for s in (1..nbins).rev() {
        acc.add(&Lanes::of(&bins[s]));
        r_area[s] = acc.area();
        r_count[s] = acc.count;
    }
    // Left to right: the candidates. A boundary after an empty bin repeats the one before
    // it and cannot win (strictly smaller keys only).
    let mut l = Lanes::EMPTY;
    let (mut key_best, mut s_best, mut al_best) = (Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO);
    let mut found = glam::BVec3A::FALSE;
    for s in 1..nbins {
        l.add(&Lanes::of(&bins[s - 1]));
        let valid = l.count.cmpgt(Vec3A::ZERO) & r_count[s].cmpgt(Vec3A::ZERO) & splittable;
        let al = l.area();
        let key = al * l.count + r_area[s] * r_count[s];
        let better = valid & (key.cmplt(key_best) | !found);
        key_best = Vec3A::select(better, key, key_best);
        s_best = Vec3A::select(better, Vec3A::splat(s as f32), s_best);
        al_best = Vec3A::select(better, al, al_best);
        found |= valid;
    }
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    for a in (0..3).filter(|&a| found.test(a)) {
        let s = s_best[a] as usize;
        let (ar, nr) = (r_area[s][a], r_count[s][a] as usize);
        let cost = opts.split_cost(area, al_best[a], n - nr, ar, nr);
        if best.is_none_or(|b| cost < b.0) {
            let side = |r: std::ops::Range<usize>| {
                bins[r]
                    .iter()
                    .fold(BoxA::EMPTY, |b, bin| b.union(bin[a].bbox))
            };
            best = Some((cost, a, s, side(0..s), side(s..nbins)));
        }
    }
    best
}

/// Nodes this small skip the bins: [`best_split_small`] finds the same split directly.
const SMALL_NODE: usize = 8;

/// [`best_split`] for a node of at most [`SMALL_NODE`] references, without bins: the
/// references are sorted by bin and swept from both sides. Only boundaries right after an
/// occupied bin can win (a boundary after an empty bin repeats the key before it), and each
/// side's box is the union of its references' boxes, exactly what the bins would hold. Keys,
/// costs and tie order are computed as there, so the split is the same (checked by
/// `small_nodes_split_as_the_bins_do`).
fn best_split_small(
    opts: &BuildOptions,
    refs: &[Ref],
    nbins: usize,
    lo: Vec3A,
    scale: Vec3A,
    splittable: glam::BVec3A,
    area: f32,
) -> Option<(f32, usize, usize, BoxA, BoxA)> {
    let n = refs.len();
    let mut bin = [[0usize; 3]; SMALL_NODE];
    for (b, r) in bin.iter_mut().zip(refs) {
        *b = bin_of(r.centroid(), lo, scale, nbins - 1);
    }
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    for a in (0..3).filter(|&a| splittable.test(a)) {
        let mut ord: [usize; SMALL_NODE] = std::array::from_fn(|i| i);
        ord[..n].sort_unstable_by_key(|&i| bin[i][a]);
        // right[j]: the union of the references from sorted position j on.
        let mut right = [BoxA::EMPTY; SMALL_NODE];
        let mut acc = BoxA::EMPTY;
        for j in (1..n).rev() {
            acc = acc.union(refs[ord[j]].bbox());
            right[j] = acc;
        }
        // (key, boundary, left area, left box, split position) of the first smallest key.
        let mut axis_best: Option<(f32, usize, f32, BoxA, usize)> = None;
        let mut left = BoxA::EMPTY;
        for j in 1..n {
            left = left.union(refs[ord[j - 1]].bbox());
            let (prev, next) = (bin[ord[j - 1]][a], bin[ord[j]][a]);
            if prev == next {
                continue;
            }
            let al = box_area(left);
            let key = al * j as f32 + box_area(right[j]) * (n - j) as f32;
            if axis_best.is_none_or(|b| key < b.0) {
                axis_best = Some((key, prev + 1, al, left, j));
            }
        }
        if let Some((_, s, al, l, j)) = axis_best {
            let cost = opts.split_cost(area, al, j, box_area(right[j]), n - j);
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, a, s, l, right[j]));
            }
        }
    }
    best
}

/// Bins every reference on all three axes (a flat axis all into bin 0, never chosen), so
/// there is no branch per axis.
fn fill_bins(refs: &[Ref], nbins: usize, lo: Vec3A, scale: Vec3A) -> Vec<[Bin; 3]> {
    let mut bins = vec![[EMPTY_BIN; 3]; nbins];
    let add = |bins: &mut [[Bin; 3]], r: &Ref| {
        let b = r.bbox();
        let k = bin_of(r.centroid(), lo, scale, nbins - 1);
        for a in 0..3 {
            let bin = &mut bins[k[a]][a];
            bin.bbox = bin.bbox.union(b);
            bin.count += 1;
        }
    };
    if refs.len() < TWO_BIN_SETS {
        refs.iter().for_each(|r| add(&mut bins, r));
        return bins;
    }
    // Neighbouring references mostly fall in the same bins: alternate between two sets so
    // that one update need not wait for the store of the one before (the union of boxes and
    // sum of counts do not depend on the order).
    let mut other = vec![[EMPTY_BIN; 3]; nbins];
    let (pairs, rest) = refs.as_chunks::<2>();
    for [a, b] in pairs {
        add(&mut bins, a);
        add(&mut other, b);
    }
    rest.iter().for_each(|r| add(&mut bins, r));
    merge_bins(bins, other)
}

/// Nodes of at least this many references bin into two sets ([`fill_bins`]).
const TWO_BIN_SETS: usize = 256;

fn merge_bins(mut a: Vec<[Bin; 3]>, b: Vec<[Bin; 3]>) -> Vec<[Bin; 3]> {
    for (x, y) in a.iter_mut().flatten().zip(b.iter().flatten()) {
        x.bbox = x.bbox.union(y.bbox);
        x.count += y.count;
    }
    a
}

/// Moves the references whose centroid is `left` before the others (Hoare's scheme: each
/// reference is looked at once, and each swap puts two in place); returns how many go
/// left and the centroid bounds of each side.
fn partition(idx: &mut [Ref], left: impl Fn(Vec3A) -> bool) -> (usize, BoxA, BoxA) {
    let (mut i, mut j) = (0, idx.len());
    let (mut lc, mut rc) = (BoxA::EMPTY, BoxA::EMPTY);
    loop {
        // The first from the left that goes right, and its centroid.
        let mut goes_right = None;
        while i < j {
            let c = idx[i].centroid();
            if !left(c) {
                goes_right = Some(c);
                break;
            }
            lc = lc.grow(c);
            i += 1;
        }
        let Some(cr) = goes_right else { break };
        // The first from the right that goes left.
        let mut goes_left = None;
        while i < j - 1 {
            let c = idx[j - 1].centroid();
            if left(c) {
                goes_left = Some(c);
                break;
            }
            rc = rc.grow(c);
            j -= 1;
        }
        rc = rc.grow(cr);
        let Some(cl) = goes_left else {
            // Everything from i on goes right.
            break;
        };
        lc = lc.grow(cl);
        idx.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
    (i, lc, rc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;
    use glam::Vec3;
    use proptest::prelude::*;

    fn same_box(a: BoxA, b: BoxA) -> bool {
        a.lo.to_array().map(f32::to_bits) == b.lo.to_array().map(f32::to_bits)
            && a.hi.to_array().map(f32::to_bits) == b.hi.to_array().map(f32::to_bits)
    }

    proptest! {
        /// The partition keeps every reference, puts those that go left first, and returns
        /// each side's centroid bounds exactly (any pattern of sides, empty sides included);
        /// two bin sets fill the bins a single pass fills.
        #[test]
        fn partition_sorts_by_side_and_bounds_each(
            sides in prop::collection::vec((any::<bool>(), 0i8..16), 0..600),
        ) {
            let mut refs: Vec<Ref> = sides
                .iter()
                .enumerate()
                .map(|(i, &(left, x))| {
                    let lo = Vec3::new(x as f32, if left { 0.0 } else { 10.0 }, i as f32);
                    Ref::new(&Aabb { lo, hi: lo + Vec3::ONE }, i as u32)
                })
                .collect();
            let before: Vec<u32> = refs.iter().map(Ref::id).collect();
            let (k, lc, rc) = partition(&mut refs, |c| c.y < 5.0);
            prop_assert_eq!(k, sides.iter().filter(|s| s.0).count());
            prop_assert!(refs[..k].iter().all(|r| r.centroid().y < 5.0));
            prop_assert!(refs[k..].iter().all(|r| r.centroid().y >= 5.0));
            let mut after: Vec<u32> = refs.iter().map(Ref::id).collect();
            after.sort_unstable();
            prop_assert_eq!(after, before);
            prop_assert!(same_box(lc, bounds(&refs[..k]).1) && same_box(rc, bounds(&refs[k..]).1));
            if !refs.is_empty() {
                let (_, cbox) = bounds(&refs);
                let ext = cbox.hi - cbox.lo;
                let scale = Vec3A::select(ext.cmpgt(Vec3A::ZERO), 16.0 / ext, Vec3A::ZERO);
                let one = |rs: &[Ref]| {
                    let mut bins = vec![[EMPTY_BIN; 3]; 16];
                    for r in rs {
                        let k = bin_of(r.centroid(), cbox.lo, scale, 15);
                        for a in 0..3 {
                            bins[k[a]][a].bbox = bins[k[a]][a].bbox.union(r.bbox());
                            bins[k[a]][a].count += 1;
                        }
                    }
                    bins
                };
                let (want, got) = (one(&refs), fill_bins(&refs, 16, cbox.lo, scale));
                for (w, g) in want.iter().flatten().zip(got.iter().flatten()) {
                    prop_assert!(w.count == g.count && same_box(w.bbox, g.bbox));
                }
            }
        }

        /// Small nodes skip the bins; the split must be the binned one: same cost to the
        /// bit, same axis, same references on each side, same boxes.
        #[test]
        fn small_nodes_split_as_the_bins_do(
            boxes in prop::collection::vec(
                // Coarse coordinates, so centroids often share a bin or a value.
                (prop::array::uniform3(0i8..8), prop::array::uniform3(0i8..3)),
                2..=SMALL_NODE,
            ),
            nbins in 2usize..=MAX_BINS,
        ) {
            let refs: Vec<Ref> = boxes
                .iter()
                .enumerate()
                .map(|(i, (lo, size))| {
                    let lo = Vec3::from(lo.map(|x| x as f32 * 0.25));
                    let hi = lo + Vec3::from(size.map(|x| x as f32 * 0.5));
                    Ref::new(&Aabb { lo, hi }, i as u32)
                })
                .collect();
            let (bbox, cbox) = bounds(&refs);
            let ext = cbox.hi - cbox.lo;
            let scale = nbins as f32 / ext;
            let splittable = ext.cmpgt(Vec3A::ZERO) & scale.is_finite_mask();
            let scale = Vec3A::select(splittable, scale, Vec3A::ZERO);
            let opts = BuildOptions::default();
            let area = bbox.aabb().area();
            let bins = fill_bins(&refs, nbins, cbox.lo, scale);
            let binned = best_split(&opts, &bins, nbins, splittable, area, refs.len());
            let small = best_split_small(&opts, &refs, nbins, cbox.lo, scale, splittable, area);
            match (binned, small) {
                (None, None) => {}
                (Some(b), Some(s)) => {
                    prop_assert_eq!(b.0.to_bits(), s.0.to_bits(), "cost");
                    prop_assert_eq!(b.1, s.1, "axis");
                    let side = |k: usize| -> Vec<bool> {
                        refs.iter()
                            .map(|r| bin_index(r.centroid()[b.1], cbox.lo[b.1], scale[b.1], nbins - 1) < k)
                            .collect()
                    };
                    prop_assert_eq!(side(b.2), side(s.2), "sides");
                    prop_assert!(same_box(b.3, s.3) && same_box(b.4, s.4), "boxes");
                }
                (b, s) => prop_assert!(false, "binned {:?} vs small {:?}", b.map(|x| x.0), s.map(|x| x.0)),
            }
        }
    }
}
