//! Spatial-split BVH (Stich, Friedrich & Dietrich 2009, "Spatial splits in bounding volume
//! hierarchies"). A node's references are split either by object (the seed's full sweep
//! over centroids sorted on each axis) or in space: a plane cuts the references that
//! straddle it, each side keeping the bounds of its part of the triangle (clipped with
//! [`clip_bounds`]), so long thin triangles stop inflating every box they cross.
//!
//! - Spatial candidates are binned (√N bins per axis over the node's box, at least 8 and at
//!   most [`SPATIAL_BINS`]), each reference clipped into the bins it spans, and tried only
//!   where the best object split's children overlap by more than [`OVERLAP`] of the root's
//!   area.
//! - Reference unsplitting: a straddling reference goes whole to one side when that costs
//!   less than duplicating it (the paper's C₁/C₂ against C_split), taken in the node's
//!   centroid order on x.
//! - A duplication budget of [`DUPLICATION`] times the triangles, spent level by level from
//!   the root (see [`build`]), so the tree is the same whether it is built on one thread
//!   or many.
//!
//! A triangle may thus be referenced by several leaves; each leaf's box holds its part of
//! the triangle, and together they hold all of it (the bounds are conservative), which is
//! what the traversal needs: a ray that meets the triangle enters one of those leaves.
//! Leaves that reference it test the whole triangle, so hits, the tie rule and any-hit are
//! those of any other tree; the per-ray statistics count each test made.

use glam::Vec3A;

use super::prim_ref::{bounds, box_area, BoxA, Ref};
use super::prims::{join, Prims, PARALLEL_MIN};
use super::sweep::{order_key, sorted_by_centroid, sweep};
use super::tree::{leaf, Kids, Node};
use super::BuildOptions;
use crate::geometry::{chopped_bounds, clip_bounds, Aabb, Triangle};

/// Most bins per axis for the spatial candidates (Stich et al. use as many as the object
/// binning; 32 is the common choice).
pub const SPATIAL_BINS: usize = 32;

/// Spatial splits are tried only where the best object split's children overlap by more
/// than this share of the root's surface area (the paper's α).
pub const OVERLAP: f32 = 1e-5;

/// At most this many extra references per triangle, over the whole tree.
pub const DUPLICATION: f32 = 0.3;

/// What every node's planning shares: the options, the triangles by reference index, the
/// root's area.
struct Ctx<'a> {
    opts: &'a BuildOptions,
    tri: &'a (dyn Fn(u32) -> Triangle + Sync),
    root_area: f32,
}

/// A node's references sorted on x, y and z by (centroid, index).
type Lists = [Vec<Ref>; 3];

/// A node's references: sorted on each axis when an object split made them (the parent's
/// lists partitioned, which keeps the order), in any order when a spatial split did (the
/// clipped references' centroids moved: they are sorted again).
enum Refs {
    Sorted(Lists),
    Unsorted(Vec<Ref>),
}

impl Refs {
    /// The references, in some order.
    fn any(&self) -> &[Ref] {
        match self {
            Refs::Sorted(l) => &l[0],
            Refs::Unsorted(r) => r,
        }
    }
}

/// A node waiting to be planned: its references, depth, and where its parent points.
struct Pending {
    refs: Refs,
    depth: usize,
    at: usize,
}

/// A node of the tree being built, in an arena (children by index).
enum Built {
    Leaf(Aabb, Vec<u32>),
    Inner(Aabb, usize, [usize; 2]),
}

/// Builds over `prims` (triangle `tri(i)` for reference `i`); returns the tree and its leaf
/// order, where a triangle split in space appears once per leaf that holds a part of it.
///
/// Level by level: every node of a level is planned on all threads (its best object split
/// and, where it beats that, its spatial split, made), then the duplication budget goes to
/// the level's spatial splits in order, left to right, and a node refused one takes its
/// object split. The budget is spent top-down, where spatial splits matter most, and the
/// tree is the same on any number of threads.
pub(crate) fn build(
    prims: Prims,
    tri: &(dyn Fn(u32) -> Triangle + Sync),
    opts: &BuildOptions,
) -> (Node, Vec<u32>) {
    use rayon::prelude::*;
    let refs = prims.refs;
    let mut budget = (refs.len() as f64 * DUPLICATION as f64) as usize;
    let root_area = box_area(bounds(&refs).0);
    let ctx = Ctx {
        opts,
        tri,
        root_area,
    };
    let mut arena: Vec<Built> = vec![Built::Leaf(Aabb::EMPTY, Vec::new())];
    let mut level = vec![Pending {
        refs: Refs::Unsorted(refs),
        depth: 0,
        at: 0,
    }];
    while !level.is_empty() {
        let plans: Vec<(Plan, usize, usize)> = if opts.parallel {
            (level.into_par_iter())
                .with_max_len(1)
                .map(|p| (plan(&ctx, p.refs, p.depth), p.depth, p.at))
                .collect()
        } else {
            (level.into_iter())
                .map(|p| (plan(&ctx, p.refs, p.depth), p.depth, p.at))
                .collect()
        };
        level = Vec::new();
        for (plan, depth, at) in plans {
            let (bbox, split) = match plan {
                Plan::Leaf(bbox, ids) => {
                    arena[at] = Built::Leaf(bbox, ids);
                    continue;
                }
                Plan::Split {
                    bbox,
                    spatial: Some(s),
                    ..
                } if s.duplicated <= budget => {
                    budget -= s.duplicated;
                    let (l, r) = (Refs::Unsorted(s.left), Refs::Unsorted(s.right));
                    (bbox, (s.axis, l, r))
                }
                Plan::Split { bbox, object, .. } => match object {
                    Object::Leaf(ids) => {
                        arena[at] = Built::Leaf(bbox, ids);
                        continue;
                    }
                    Object::Split(axis, l, r) => (bbox, (axis, Refs::Sorted(l), Refs::Sorted(r))),
                },
            };
            let (axis, left, right) = split;
            let kids = [arena.len(), arena.len() + 1];
            arena.push(Built::Leaf(Aabb::EMPTY, Vec::new()));
            arena.push(Built::Leaf(Aabb::EMPTY, Vec::new()));
            arena[at] = Built::Inner(bbox, axis, kids);
            for (refs, at) in [(left, kids[0]), (right, kids[1])] {
                level.push(Pending {
                    refs,
                    depth: depth + 1,
                    at,
                });
            }
        }
    }
    let mut order = Vec::new();
    let root = assemble(&mut arena, 0, &mut order);
    (root, order)
}

/// The arena's subtree at `i` as a [`Node`], its leaves' references appended to `order`.
fn assemble(arena: &mut [Built], i: usize, order: &mut Vec<u32>) -> Node {
    match std::mem::replace(&mut arena[i], Built::Leaf(Aabb::EMPTY, Vec::new())) {
        Built::Leaf(bbox, ids) => {
            let start = order.len();
            order.extend(ids);
            leaf(bbox, start, order.len() - start)
        }
        Built::Inner(bbox, axis, [l, r]) => {
            let kids = Kids::reserve();
            let l = assemble(arena, l, order);
            let r = assemble(arena, r, order);
            kids.inner(bbox, axis, [l, r])
        }
    }
}

/// What a node becomes without a spatial split.
enum Object {
    Leaf(Vec<u32>),
    Split(usize, Lists, Lists),
}

/// A node's plan: a leaf, or a split — in space if the budget allows it, else by object.
enum Plan {
    Leaf(Aabb, Vec<u32>),
    Split {
        bbox: Aabb,
        spatial: Option<Spatial>,
        object: Object,
    },
}

/// A leaf's references (triangle indices), in index order.
fn leaf_ids(refs: &[Ref]) -> Vec<u32> {
    let mut ids: Vec<u32> = refs.iter().map(Ref::id).collect();
    ids.sort_unstable();
    ids
}

/// The lists of the two sides of an object split at position `k` of the list on `axis`:
/// that list cut, the other two partitioned by it, each keeping its order.
fn divide(lists: &Lists, axis: usize, k: usize) -> (Lists, Lists) {
    let pivot = order_key(&lists[axis][k], axis);
    let n = lists[axis].len();
    let side = |a: usize, left: bool| -> Vec<Ref> {
        if a == axis {
            let (l, r) = lists[a].split_at(k);
            return if left { l.to_vec() } else { r.to_vec() };
        }
        let mut out = Vec::with_capacity(if left { k } else { n - k });
        out.extend(
            lists[a]
                .iter()
                .filter(|r| (order_key(r, axis) < pivot) == left),
        );
        out
    };
    (
        std::array::from_fn(|a| side(a, true)),
        std::array::from_fn(|a| side(a, false)),
    )
}

fn plan(ctx: &Ctx, refs: Refs, depth: usize) -> Plan {
    let opts = ctx.opts;
    let n = refs.any().len();
    let (bbox, cbox) = bounds(refs.any());
    let aabb = bbox.aabb();
    let forced = opts.depth_forces_median(depth, n);
    if n == 1 || (opts.leaf_beats_any_split(n) && !forced) {
        return Plan::Leaf(aabb, leaf_ids(refs.any()));
    }
    let par = opts.parallel && n >= PARALLEL_MIN;
    let mut lists: Lists = match refs {
        Refs::Sorted(lists) => lists,
        Refs::Unsorted(refs) => {
            let sorted = |axis: usize| sorted_by_centroid(&refs, axis, false);
            let (x, (y, z)) = join(par, || sorted(0), || join(par, || sorted(1), || sorted(2)));
            [x, y, z]
        }
    };

    if forced || cbox.aabb().extent() == glam::Vec3::ZERO {
        // Depth cap, or identical centroids: the object median keeps the tree balanced.
        let cost = opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
        if !forced && opts.prefers_leaf(n, cost) {
            return Plan::Leaf(aabb, leaf_ids(&lists[0]));
        }
        let axis = cbox.aabb().longest_axis();
        let (l, r) = divide(&lists, axis, n / 2);
        return Plan::Split {
            bbox: aabb,
            spatial: None,
            object: Object::Split(axis, l, r),
        };
    }
    let mut right_areas = vec![Vec3A::ZERO; n];
    let best = {
        let [x, y, z] = &mut lists;
        sweep(opts, &[x, y, z], &mut right_areas, aabb.area())
    };
    drop(right_areas);
    let overlap = best.as_ref().map_or(f32::INFINITY, |s| {
        let right = bounds(&lists[s.axis][s.k..]).0;
        box_area(intersection(s.left, right))
    });
    // The binned estimate must beat the object split, then the split as made.
    let beats_object = |cost: f32| best.as_ref().is_none_or(|o| cost < o.cost);
    let spatial = (overlap > OVERLAP * ctx.root_area)
        .then(|| best_spatial(ctx, &lists[0], bbox))
        .flatten()
        .filter(|s| beats_object(s.cost))
        .and_then(|s| split_in_space(ctx, &lists[0], s))
        .filter(|s| beats_object(s.cost))
        .filter(|s| !opts.prefers_leaf(n, s.cost));
    let object = match best {
        Some(o) if opts.prefers_leaf(n, o.cost) => Object::Leaf(leaf_ids(&lists[0])),
        Some(o) => {
            let (l, r) = divide(&lists, o.axis, o.k);
            Object::Split(o.axis, l, r)
        }
        None if n <= opts.max_leaf => Object::Leaf(leaf_ids(&lists[0])),
        // Every candidate's cost overflowed (boxes near f32::MAX): halve the node.
        None => {
            let (l, r) = divide(&lists, 0, n / 2);
            Object::Split(0, l, r)
        }
    };
    if spatial.is_none() {
        if let Object::Leaf(ids) = object {
            return Plan::Leaf(aabb, ids);
        }
    }
    Plan::Split {
        bbox: aabb,
        spatial,
        object,
    }
}

fn intersection(a: BoxA, b: BoxA) -> BoxA {
    let lo = a.lo.max(b.lo);
    let hi = a.hi.min(b.hi);
    if lo.cmple(hi).all() {
        BoxA { lo, hi }
    } else {
        BoxA { lo, hi: lo }
    }
}

/// A spatial candidate: a plane on an axis, and the binned estimate of its cost.
#[derive(Clone, Copy)]
struct Plane {
    axis: usize,
    at: f32,
    cost: f32,
}

/// Planes `lo + (hi − lo)·b/bins` for b = 0..=bins, the last exactly `hi`.
struct Planes {
    at: [f32; SPATIAL_BINS + 1],
    bins: usize,
}

impl Planes {
    fn new(lo: f32, hi: f32, bins: usize) -> Planes {
        let mut at = [hi; SPATIAL_BINS + 1];
        for (b, q) in at.iter_mut().enumerate().take(bins) {
            *q = lo + (hi - lo) * (b as f32 / bins as f32);
        }
        Planes { at, bins }
    }

    /// The bin `b` with `at[b] ≤ x < at[b + 1]` (the last bin also takes `x = hi`).
    fn bin_of(&self, x: f32) -> usize {
        let (lo, hi, bins) = (self.at[0], self.at[self.bins], self.bins);
        let guess = ((x - lo) / (hi - lo) * bins as f32) as usize;
        let mut b = guess.min(bins - 1);
        while b > 0 && x < self.at[b] {
            b -= 1;
        }
        while b + 1 < bins && x >= self.at[b + 1] {
            b += 1;
        }
        b
    }
}

/// A reference's box with its extent on `axis` cut to [lo, hi].
fn cut(b: BoxA, axis: usize, lo: f32, hi: f32) -> Aabb {
    let mut a = b.aabb();
    a.lo[axis] = a.lo[axis].max(lo);
    a.hi[axis] = a.hi[axis].min(hi);
    a
}

/// One axis's bins: the bounds of the parts of references in each, and how many
/// references start and end in each.
struct Bins {
    boxes: [BoxA; SPATIAL_BINS],
    enter: [usize; SPATIAL_BINS],
    exit: [usize; SPATIAL_BINS],
}

/// The best binned spatial split over the node's box `bbox`, if any plane separates. Small
/// nodes take fewer planes, √N for N references (at least 8): a surface of N triangles is
/// about √N triangles across, so a triangle spans about one bin and is clipped about once
/// per axis rather than once per bin it crosses.
fn best_spatial(ctx: &Ctx, refs: &[Ref], bbox: BoxA) -> Option<Plane> {
    let area = box_area(bbox);
    let bins = ((refs.len() as f64).sqrt() as usize).clamp(8, SPATIAL_BINS);
    let planes: [Planes; 3] = std::array::from_fn(|a| Planes::new(bbox.lo[a], bbox.hi[a], bins));
    let mut binned: [Bins; 3] = std::array::from_fn(|_| Bins {
        boxes: [BoxA::EMPTY; SPATIAL_BINS],
        enter: [0; SPATIAL_BINS],
        exit: [0; SPATIAL_BINS],
    });
    let flat = |a: usize| bbox.hi[a] <= bbox.lo[a];
    for r in refs {
        let b = r.bbox();
        let mut span = [(0, 0); 3];
        for a in (0..3).filter(|&a| !flat(a)) {
            let (b0, b1) = (planes[a].bin_of(b.lo[a]), planes[a].bin_of(b.hi[a]));
            binned[a].enter[b0] += 1;
            binned[a].exit[b1] += 1;
            span[a] = (b0, b1);
            if b0 == b1 {
                binned[a].boxes[b0] = binned[a].boxes[b0].union(b);
            }
        }
        if span.iter().all(|&(b0, b1)| b0 == b1) {
            continue;
        }
        // The reference clipped once, then chopped at the planes it spans on each axis.
        let cuts: [&[f32]; 3] =
            std::array::from_fn(|a| &planes[a].at[span[a].0 + 1..=span[a].1.max(span[a].0)]);
        chopped_bounds(&(ctx.tri)(r.id()), &b.aabb(), cuts, |a, i, part| {
            let bin = &mut binned[a].boxes[span[a].0 + i];
            *bin = bin.union(part.into());
        });
    }
    let mut best: Option<Plane> = None;
    for a in (0..3).filter(|&a| !flat(a)) {
        let Bins { boxes, enter, exit } = &binned[a];
        // Right to left: the boxes and reference counts right of each plane.
        let mut right = [(BoxA::EMPTY, 0usize); SPATIAL_BINS];
        let mut acc = (BoxA::EMPTY, 0);
        for k in (1..bins).rev() {
            acc = (acc.0.union(boxes[k]), acc.1 + exit[k]);
            right[k] = acc;
        }
        let mut left = (BoxA::EMPTY, 0);
        for k in 1..bins {
            left = (left.0.union(boxes[k - 1]), left.1 + enter[k - 1]);
            let (rbox, nr) = right[k];
            let at = planes[a].at[k];
            if left.1 == 0 || nr == 0 || at <= bbox.lo[a] || at >= bbox.hi[a] {
                continue;
            }
            let cost = (ctx.opts).split_cost(area, box_area(left.0), left.1, box_area(rbox), nr);
            if best.is_none_or(|b| cost < b.cost) {
                best = Some(Plane { axis: a, at, cost });
            }
        }
    }
    best
}

/// A spatial split made: both sides' references, how many were duplicated, its cost.
struct Spatial {
    axis: usize,
    left: Vec<Ref>,
    right: Vec<Ref>,
    duplicated: usize,
    cost: f32,
}

/// Splits the references at `plane`, unsplitting where that is cheaper. None when it
/// leaves a side with every reference (no progress).
fn split_in_space(ctx: &Ctx, refs: &[Ref], plane: Plane) -> Option<Spatial> {
    let Plane { axis, at, .. } = plane;
    let (mut left, mut right, mut straddling) = (Vec::new(), Vec::new(), Vec::new());
    for r in refs {
        let b = r.bbox();
        if b.hi[axis] <= at {
            left.push(*r);
        } else if b.lo[axis] >= at {
            right.push(*r);
        } else {
            let t = (ctx.tri)(r.id());
            let l = clip_bounds(&t, &cut(b, axis, f32::NEG_INFINITY, at));
            let h = clip_bounds(&t, &cut(b, axis, at, f32::INFINITY));
            match (l, h) {
                (Some(l), Some(h)) => straddling.push((*r, l, h)),
                (Some(l), None) => left.push(Ref::new(&l, r.id())),
                (None, Some(h)) => right.push(Ref::new(&h, r.id())),
                // The triangle misses its own box (cannot happen for a box from clipping): keep
                // the reference whole.
                (None, None) => left.push(*r),
            }
        }
    }
    let (mut lbox, mut rbox) = (bounds(&left).0, bounds(&right).0);
    for (_, l, h) in &straddling {
        lbox = lbox.union((*l).into());
        rbox = rbox.union((*h).into());
    }
    let (mut nl, mut nr) = (
        left.len() + straddling.len(),
        right.len() + straddling.len(),
    );
    let mut duplicated = 0;
    for (r, l, h) in straddling {
        let whole: BoxA = l.union(h).into();
        let (al, ar) = (box_area(lbox), box_area(rbox));
        let split = al * nl as f32 + ar * nr as f32;
        let to_left = box_area(lbox.union(whole)) * nl as f32 + ar * (nr - 1) as f32;
        let to_right = al * (nl - 1) as f32 + box_area(rbox.union(whole)) * nr as f32;
        if to_left < split && to_left <= to_right {
            left.push(Ref::new(&whole.aabb(), r.id()));
            lbox = lbox.union(whole);
            nr -= 1;
        } else if to_right < split {
            right.push(Ref::new(&whole.aabb(), r.id()));
            rbox = rbox.union(whole);
            nl -= 1;
        } else {
            left.push(Ref::new(&l, r.id()));
            right.push(Ref::new(&h, r.id()));
            duplicated += 1;
        }
    }
    let n = refs.len();
    if left.len() >= n || right.len() >= n || left.is_empty() || right.is_empty() {
        return None;
    }
    let area = box_area(bounds(refs).0);
    let (lb, rb) = (bounds(&left).0, bounds(&right).0);
    let cost = ctx
        .opts
        .split_cost(area, box_area(lb), left.len(), box_area(rb), right.len());
    Some(Spatial {
        axis,
        left,
        right,
        duplicated,
        cost,
    })
}
