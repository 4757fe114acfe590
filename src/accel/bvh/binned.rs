//! Binned SAH (Wald 2007): K equal bins over the centroid bounds on each axis, filled in
//! one pass over the node's primitives; the partition is in place. The builder moves
//! 32-byte primitive references (box in SIMD lanes, index in a spare lane) rather than
//! indices, so every pass streams through memory; a node costs two linear passes (bin,
//! partition), the partition also yielding the children's centroid bounds. The split
//! candidates of the three axes are evaluated together in SIMD lanes; a small node sweeps
//! only its occupied bins.

use std::cell::RefCell;
use std::mem::MaybeUninit;

use glam::{Mat3A, Vec3A, Vec4};

use super::prim_ref::{bounds, box_area, BoxA, Ref};

use super::prims::{join, Prims, PARALLEL_MIN};
use super::tree::{leaf, Kids, Node};
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
    use rayon::prelude::*;
    (root, refs.par_iter().map(Ref::id).collect())
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
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
fn bin_index(c: f32, lo: f32, scale: f32, last: usize) -> usize {
    let x = (c - lo) * scale;
    debug_assert!((0.0..=(last + 1) as f32 * 1.001).contains(&x));
    // SAFETY: x is finite and in [0, K + ε] as argued above, so it fits an i32.
    (unsafe { x.to_int_unchecked::<i32>() } as usize).min(last)
}

/// Whether a centroid coordinate's bin lies left of bin `s`: `bin_index(c) < s` without
/// the conversion. x = (c − lo)·scale ≥ 0 and s is a whole number no greater than the last
/// bin, so min(⌊x⌋, last) < s exactly when x < s (checked by
/// `the_partition_test_is_the_bins`).
#[inline(always)]
fn left_of(c: f32, lo: f32, scale: f32, s: usize) -> bool {
    (c - lo) * scale < s as f32
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

/// The bins of a node's centroid bounds `cbox`: K/extent per axis (0 where the axis is not
/// binned), and which axes are binned: not a flat one, nor one so thin that K/extent
/// overflows.
fn bin_scale(cbox: BoxA, nbins: usize) -> (Vec3A, glam::BVec3A) {
    let ext = cbox.hi - cbox.lo;
    let scale = nbins as f32 / ext;
    let splittable = ext.cmpgt(Vec3A::ZERO) & scale.is_finite_mask();
    (Vec3A::select(splittable, scale, Vec3A::ZERO), splittable)
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
    let (scale, splittable) = bin_scale(cbox, nbins);
    // (cost, axis, first bin on the right, left box, right box)
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    if !opts.depth_forces_median(depth, n) && splittable.any() {
        best = if n <= SPARSE_NODE {
            let area = bbox.area();
            match best_split_sparse(opts, idx, nbins, cbox.lo, scale, splittable, area) {
                Small::Leaf => return leaf(bbox, offset, n),
                Small::Split(best) => best,
            }
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
            let (k, lc, rc) = partition(idx, |c| left_of(c[axis], lo, scale, s));
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
    let kids = Kids::reserve();
    let (l, r) = idx.split_at_mut(k);
    let (a, b) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(opts, top, l, lbox, lc, offset, depth + 1),
        || node(opts, top, r, rbox, rc, offset + k, depth + 1),
    );
    kids.inner(bbox, axis, [a, b])
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
    // Right to left: area and count of everything right of each boundary s = 1..nbins
    // (only those are written and read; clearing them all would cost more).
    let mut right = [const { MaybeUninit::<(Vec3A, Vec3A)>::uninit() }; MAX_BINS];
    let mut acc = Lanes::EMPTY;
    for s in (1..nbins).rev() {
        acc.add(&Lanes::of(&bins[s]));
        right[s].write((acc.area(), acc.count));
    }
    // SAFETY: right[s] was written above for every s in 1..nbins.
    let right = |s: usize| unsafe { right[s].assume_init() };
    // Left to right: the candidates. A boundary after an empty bin repeats the one before
    // it and cannot win (strictly smaller keys only).
    let mut l = Lanes::EMPTY;
    let (mut key_best, mut s_best, mut al_best) = (Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO);
    let mut found = glam::BVec3A::FALSE;
    for s in 1..nbins {
        l.add(&Lanes::of(&bins[s - 1]));
        let (r_area, r_count) = right(s);
        let valid = l.count.cmpgt(Vec3A::ZERO) & r_count.cmpgt(Vec3A::ZERO) & splittable;
        let al = l.area();
        let key = al * l.count + r_area * r_count;
        let better = valid & (key.cmplt(key_best) | !found);
        key_best = Vec3A::select(better, key, key_best);
        s_best = Vec3A::select(better, Vec3A::splat(s as f32), s_best);
        al_best = Vec3A::select(better, al, al_best);
        found |= valid;
    }
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    for a in (0..3).filter(|&a| found.test(a)) {
        let s = s_best[a] as usize;
        // The count right of s in whole numbers: the lanes' f32 sums round above 2^24.
        let nr: usize = bins[s..nbins].iter().map(|bin| bin[a].count).sum();
        let cost = opts.split_cost(area, al_best[a], n - nr, right(s).0[a], nr);
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

/// Nodes of at most this many references find their split in sparse bins
/// ([`best_split_sparse`]): the same split, without sweeping empty bins.
const SPARSE_NODE: usize = 64;

thread_local! {
    /// Each thread's bins for small nodes, all empty between nodes: a node adds its
    /// references without a branch on whether a bin is in use yet (its outcome is as good as
    /// random), and empties again only the bins it used.
    static SPARSE_BINS: RefCell<[[Tally; MAX_BINS]; 3]> =
        const { RefCell::new([[Tally::EMPTY; MAX_BINS]; 3]) };
}

/// One occupied bin of a small node's axis: its box and count.
#[derive(Clone, Copy)]
struct Occupied {
    bbox: BoxA,
    count: u32,
    /// The bin's index.
    k: u32,
}

/// What [`best_split_sparse`] found.
enum Small {
    /// A leaf beats every split ([`BuildOptions::leaf_beats_splits_over`]): none was swept.
    Leaf,
    /// The split [`best_split`] would find.
    Split(Option<(f32, usize, usize, BoxA, BoxA)>),
}

/// [`best_split`] for a node of at most [`SPARSE_NODE`] references: the bins of each axis
/// are filled as there, but only the occupied ones are swept; none at all where the
/// references' own boxes show that a leaf beats every split. A boundary after an empty bin
/// repeats the key before it and cannot win (strictly smaller keys only), so the candidates
/// are the boundaries right after each occupied bin but the last. Keys, costs and tie order
/// are computed as there, so the split is the same (checked by
/// `small_nodes_split_as_the_bins_do`). Not inlined: its arrays (some 12 KB) would otherwise
/// sit in every level of the recursion's stack.
#[inline(never)]
fn best_split_sparse(
    opts: &BuildOptions,
    refs: &[Ref],
    nbins: usize,
    lo: Vec3A,
    scale: Vec3A,
    splittable: glam::BVec3A,
    area: f32,
) -> Small {
    let n = refs.len();
    debug_assert!(n <= SPARSE_NODE);
    // Whether a leaf is allowed at all.
    let leaf_test = n <= opts.max_leaf;
    // Each axis's occupied bins in bin order, taken out of the thread's bins (emptying them).
    let mut occupied = [[const { MaybeUninit::<Occupied>::uninit() }; SPARSE_NODE]; 3];
    let mut m = [0usize; 3];
    let leaf = SPARSE_BINS.with_borrow_mut(|tallies| {
        let mut used = [0u64; 3];
        // The areas of the references' boxes, where a leaf is allowed.
        let mut boxes_area = 0.0;
        for r in refs {
            let k = bin_of(r.centroid(), lo, scale, nbins - 1);
            let operands = Tally::operands(r);
            for a in 0..3 {
                tallies[a][k[a]].add(operands);
                used[a] |= 1 << k[a];
            }
            if leaf_test {
                boxes_area += box_area(r.bbox());
            }
        }
        let leaf = leaf_test && opts.leaf_beats_splits_over(n, boxes_area, area);
        for a in 0..3 {
            let mut rest = used[a];
            while rest != 0 {
                let k = rest.trailing_zeros();
                rest &= rest - 1;
                let tally = std::mem::replace(&mut tallies[a][k as usize], Tally::EMPTY);
                if !leaf {
                    let (bbox, count) = tally.bin();
                    occupied[a][m[a]].write(Occupied { bbox, count, k });
                    m[a] += 1;
                }
            }
        }
        leaf
    });
    if leaf {
        return Small::Leaf;
    }
    let mut best: Option<(f32, usize, usize, BoxA, BoxA)> = None;
    for a in (0..3).filter(|&a| splittable.test(a)) {
        let m = m[a];
        // SAFETY: the first m entries of axis a were written above.
        let bin = |j: usize| unsafe { occupied[a][j].assume_init() };
        // Right to left: the union, its area and count of the occupied bins of rank j.. (in
        // bin order), for j = m − 1 down to 1 (only those are written and read). References
        // hold no −0, so the union's bits do not depend on the order `best_split` takes.
        let mut right = [const { MaybeUninit::<(BoxA, f32, u32)>::uninit() }; SPARSE_NODE];
        let (mut acc, mut count) = (BoxA::EMPTY, 0);
        for j in (1..m).rev() {
            let b = bin(j);
            acc = acc.union(b.bbox);
            count += b.count;
            right[j].write((acc, box_area(acc), count));
        }
        // SAFETY: right[j] was written above for every j in 1..m.
        let right = |j: usize| unsafe { right[j].assume_init() };
        // Left to right: the candidates; the first smallest key wins.
        // (key, boundary, left area, left box, right rank)
        let mut axis_best: Option<(f32, usize, f32, BoxA, usize)> = None;
        let (mut left, mut l_count) = (BoxA::EMPTY, 0);
        for j in 1..m {
            let b = bin(j - 1);
            left = left.union(b.bbox);
            l_count += b.count;
            let (_, ar, nr) = right(j);
            let al = box_area(left);
            let key = al * l_count as f32 + ar * nr as f32;
            if axis_best.is_none_or(|b| key < b.0) {
                axis_best = Some((key, b.k as usize + 1, al, left, j));
            }
        }
        if let Some((_, s, al, l, j)) = axis_best {
            let (r, ar, nr) = right(j);
            let cost = opts.split_cost(area, al, n - nr as usize, ar, nr as usize);
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, a, s, l, r));
            }
        }
    }
    Small::Split(best)
}

/// A bin while it is filled: the box's low corner with the count in lane w, and its high
/// corner negated, so that a reference is added by two lane-wise minimums and one addition
/// (max(h, x) = −min(−h, −x) exactly) — two stores instead of three.
#[derive(Clone, Copy)]
struct Tally {
    lo: Vec4,
    neg_hi: Vec4,
}

impl Tally {
    const EMPTY: Tally = Tally {
        lo: Vec4::new(f32::MAX, f32::MAX, f32::MAX, 0.0),
        neg_hi: Vec4::splat(f32::MAX),
    };

    /// Adds a reference given as [`Tally::operands`].
    #[inline(always)]
    fn add(&mut self, (lo, neg_hi): (Vec4, Vec4)) {
        // Adding −0 leaves every value as it is (−0 included); lane w counts.
        self.lo = self.lo.min(lo) + Vec4::new(-0.0, -0.0, -0.0, 1.0);
        self.neg_hi = self.neg_hi.min(neg_hi);
    }

    /// A reference's box as `add` takes it: lane w of the low corner +∞ (the count's
    /// minimum leaves it), lane w of the negated high corner never read.
    #[inline(always)]
    fn operands(r: &Ref) -> (Vec4, Vec4) {
        let b = r.bbox();
        (b.lo.extend(f32::INFINITY), -b.hi.extend(0.0))
    }

    /// The box and count tallied.
    #[inline(always)]
    fn bin(self) -> (BoxA, u32) {
        let bbox = BoxA {
            lo: Vec3A::from_vec4(self.lo),
            hi: -Vec3A::from_vec4(self.neg_hi),
        };
        (bbox, self.lo.w as u32)
    }

    /// The bin, its count added to `bin`'s.
    #[inline(always)]
    fn into_bin(self, bin: &mut Bin) {
        let (bbox, count) = self.bin();
        bin.bbox = bin.bbox.union(bbox);
        bin.count += count as usize;
    }
}

/// Most references tallied before the counts are moved out of their lanes (f32 counts
/// every integer up to 2^24 exactly).
const TALLY_MAX: usize = 1 << 24;

/// Bins every reference on all three axes (a flat axis all into bin 0, never chosen), so
/// there is no branch per axis.
fn fill_bins(refs: &[Ref], nbins: usize, lo: Vec3A, scale: Vec3A) -> Vec<[Bin; 3]> {
    fill_bins_in_runs(refs, nbins, lo, scale, TALLY_MAX)
}

/// [`fill_bins`], the counts moved out of the tallies every `run` references (a test
/// makes runs short).
fn fill_bins_in_runs(
    refs: &[Ref],
    nbins: usize,
    lo: Vec3A,
    scale: Vec3A,
    run: usize,
) -> Vec<[Bin; 3]> {
    let mut bins = vec![[EMPTY_BIN; 3]; nbins];
    let mut tallies = vec![[Tally::EMPTY; 3]; nbins];
    let add = |tallies: &mut [[Tally; 3]], r: &Ref| {
        let k = bin_of(r.centroid(), lo, scale, nbins - 1);
        let operands = Tally::operands(r);
        for a in 0..3 {
            tallies[k[a]][a].add(operands);
        }
    };
    let empty = |tallies: &mut [[Tally; 3]], bins: &mut [[Bin; 3]]| {
        for (bin, tally) in bins.iter_mut().zip(tallies) {
            for a in 0..3 {
                tally[a].into_bin(&mut bin[a]);
                tally[a] = Tally::EMPTY;
            }
        }
    };
    if refs.len() < TWO_BIN_SETS {
        refs.iter().for_each(|r| add(&mut tallies, r));
        empty(&mut tallies, &mut bins);
        return bins;
    }
    // Neighbouring references mostly fall in the same bins: alternate between two sets so
    // that one update need not wait for the store of the one before. And find a block's
    // bins before adding any: an add's address is then known long before its load, which
    // the processor would otherwise start early, guessing that it does not depend on the
    // add before it, and replay when it does (~5% of a 4M-triangle build).
    let mut other = vec![[Tally::EMPTY; 3]; nbins];
    let put = |tallies: &mut [[Tally; 3]], k: &[u32; 3], r: &Ref| {
        let operands = Tally::operands(r);
        for a in 0..3 {
            tallies[k[a] as usize][a].add(operands);
        }
    };
    for chunk in refs.chunks(run) {
        for block in chunk.chunks(BLOCK) {
            let mut ks = [[0u32; 3]; BLOCK];
            for (k, r) in ks.iter_mut().zip(block) {
                *k = bin_of(r.centroid(), lo, scale, nbins - 1).map(|b| b as u32);
            }
            let (pairs, rest) = block.as_chunks::<2>();
            let (k_pairs, k_rest) = ks[..block.len()].as_chunks::<2>();
            for ([a, b], [ka, kb]) in pairs.iter().zip(k_pairs) {
                put(&mut tallies, ka, a);
                put(&mut other, kb, b);
            }
            for (r, k) in rest.iter().zip(k_rest) {
                put(&mut tallies, k, r);
            }
        }
        empty(&mut tallies, &mut bins);
        empty(&mut other, &mut bins);
    }
    bins
}

/// References whose bins [`fill_bins`] finds before it adds any of them (an even number:
/// the two sets alternate as without blocks).
const BLOCK: usize = 64;

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
                    // Low bounds of −0 and +0 (x = 0 and x = 8): references make −0 +0, so
                    // two bin sets keep the bits of one.
                    let x = if x == 0 { -0.0 } else { x as f32 - 8.0 };
                    let lo = Vec3::new(x, if left { 0.0 } else { 10.0 }, i as f32);
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
                let want = one(&refs);
                for run in [TALLY_MAX, 7, 2] {
                    let got = fill_bins_in_runs(&refs, 16, cbox.lo, scale, run);
                    for (w, g) in want.iter().flatten().zip(got.iter().flatten()) {
                        prop_assert!(w.count == g.count && same_box(w.bbox, g.bbox));
                    }
                }
            }
        }

        /// Small nodes skip the bins; the split must be the binned one: same cost to the
        /// bit, same axis, same references on each side, same boxes.
        #[test]
        fn small_nodes_split_as_the_bins_do(
            boxes in prop::collection::vec(
                (prop::array::uniform3(-512i16..512), prop::array::uniform3(0i8..3)),
                2..=SPARSE_NODE,
            ),
            nbins in 2usize..=MAX_BINS,
            fine in any::<bool>(),
        ) {
            // Coarse coordinates (16 values), so that centroids often share a bin or a
            // value; or fine ones (1,024), so that up to 64 bins are occupied. Zeros of both
            // signs: references make −0 +0, so the order of unions never shows.
            let x = |x: i16| match (fine, x) {
                (_, -512) => -0.0,
                (false, x) => (x >> 6) as f32 * 0.25,
                (true, x) => x as f32 / 64.0,
            };
            let refs: Vec<Ref> = boxes
                .iter()
                .enumerate()
                .map(|(i, (lo, size))| {
                    let lo = Vec3::from(lo.map(x));
                    let size = Vec3::from(size.map(|s| s as f32 * 0.5));
                    // hi = lo where the size is 0, so that −0 is a high bound too.
                    let hi = Vec3::select(size.cmpeq(Vec3::ZERO), lo, lo + size);
                    Ref::new(&Aabb { lo, hi }, i as u32)
                })
                .collect();
            let (bbox, cbox) = bounds(&refs);
            let (scale, splittable) = bin_scale(cbox, nbins);
            let opts = BuildOptions::default();
            let area = bbox.aabb().area();
            let bins = fill_bins(&refs, nbins, cbox.lo, scale);
            let binned = best_split(&opts, &bins, nbins, splittable, area, refs.len());
            // Without leaves (max_leaf 0) the sweep always runs.
            let no_leaf = BuildOptions { max_leaf: 0, ..opts };
            let Small::Split(small) =
                best_split_sparse(&no_leaf, &refs, nbins, cbox.lo, scale, splittable, area)
            else {
                unreachable!("no leaf is allowed");
            };
            // Where the leaf test skips the sweep, the split found would make a leaf too.
            let leaf_test = best_split_sparse(&opts, &refs, nbins, cbox.lo, scale, splittable, area);
            if matches!(leaf_test, Small::Leaf) {
                prop_assert!(binned.is_none_or(|b| opts.prefers_leaf(refs.len(), b.0)), "leaf test");
            }
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

        /// Small nodes of boxes that overlap much: where the leaf test skips the sweep, the
        /// best binned split would have made the node a leaf as well.
        #[test]
        fn the_leaf_test_makes_only_leaves_the_bins_make(
            boxes in prop::collection::vec(
                (prop::array::uniform3(0u8..32), prop::array::uniform3(0u8..64)),
                3..=16,
            ),
            nbins in 2usize..=MAX_BINS,
        ) {
            let refs: Vec<Ref> = boxes
                .iter()
                .enumerate()
                .map(|(i, (lo, size))| {
                    let lo = Vec3::from(lo.map(|x| x as f32 / 16.0));
                    let size = Vec3::from(size.map(|x| 2.0 + x as f32 / 16.0));
                    Ref::new(&Aabb { lo, hi: lo + size }, i as u32)
                })
                .collect();
            let (bbox, cbox) = bounds(&refs);
            let (scale, splittable) = bin_scale(cbox, nbins);
            let opts = BuildOptions::default();
            let area = bbox.aabb().area();
            let small = best_split_sparse(&opts, &refs, nbins, cbox.lo, scale, splittable, area);
            if matches!(small, Small::Leaf) {
                let bins = fill_bins(&refs, nbins, cbox.lo, scale);
                let binned = best_split(&opts, &bins, nbins, splittable, area, refs.len());
                prop_assert!(binned.is_none_or(|b| opts.prefers_leaf(refs.len(), b.0)));
            }
        }

        /// The partition's side test, (c − lo)·scale < s, is the bins' bin_index(c) < s for
        /// every first bin on the right s, at a random centroid and at the bins' boundaries
        /// (and one float either side).
        #[test]
        fn the_partition_test_is_the_bins(
            lo in -100.0f32..100.0,
            width in 1e-3f32..100.0,
            t in 0.0f32..=1.0,
            nbins in 2usize..=MAX_BINS,
        ) {
            let hi = lo + width;
            let scale = nbins as f32 / (hi - lo);
            let mut cs = vec![lo, hi, lo + t * (hi - lo)];
            for s in 1..nbins {
                let c = lo + s as f32 / scale;
                cs.extend([c.next_down(), c, c.next_up()]);
            }
            for c in cs.into_iter().map(|c| c.clamp(lo, hi)) {
                for s in 1..nbins {
                    prop_assert_eq!(
                        left_of(c, lo, scale, s),
                        bin_index(c, lo, scale, nbins - 1) < s,
                        "c {} s {}", c, s
                    );
                }
            }
        }
    }

    /// The leaf test fires for boxes that nearly fill their node, and not for small boxes
    /// far apart (which a split separates).
    #[test]
    fn the_leaf_test_fires_where_the_boxes_fill_the_node() {
        let small = |boxes: &[(f32, f32)]| {
            let refs: Vec<Ref> = (boxes.iter().enumerate())
                .map(|(i, &(lo, hi))| {
                    let b = Aabb {
                        lo: Vec3::new(lo, 0.0, 0.0),
                        hi: Vec3::new(hi, 1.0, 1.0),
                    };
                    Ref::new(&b, i as u32)
                })
                .collect();
            let (bbox, cbox) = bounds(&refs);
            let scale = Vec3A::new(16.0 / (cbox.hi.x - cbox.lo.x), 0.0, 0.0);
            let splittable = glam::BVec3A::new(true, false, false);
            let area = bbox.aabb().area();
            let opts = BuildOptions::default();
            best_split_sparse(&opts, &refs, 16, cbox.lo, scale, splittable, area)
        };
        assert!(matches!(
            small(&[(0.0, 10.0), (0.1, 10.1), (0.2, 10.2)]),
            Small::Leaf
        ));
        assert!(matches!(
            small(&[(0.0, 1.0), (5.0, 6.0), (10.0, 11.0)]),
            Small::Split(Some(_))
        ));
    }
}
