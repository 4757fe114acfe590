//! The seed's full-sweep SAH build. Primitives are sorted by centroid once per axis at the
//! root; every node sweeps each sorted list right→left (areas of the right parts) and
//! left→right (areas of the left parts, and the cost of every candidate). After the split
//! the other two lists are partitioned stably by a side flag, so they stay sorted without
//! re-sorting: O(N log N) in all.

use std::sync::atomic::{AtomicBool, Ordering};

use super::prims::{join, Prims, PARALLEL_MIN};
use super::tree::{leaf, Node};
use super::BuildOptions;
use crate::geometry::Aabb;

struct Ctx<'a> {
    prims: &'a Prims,
    opts: &'a BuildOptions,
    /// Side flag per primitive, true = left. Disjoint subtrees touch disjoint entries.
    left: Vec<AtomicBool>,
}

pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let n = prims.boxes.len();
    let sorted = |axis: usize| {
        let mut keyed: Vec<(f32, u32)> = (0..n as u32)
            .map(|i| (prims.centroids[i as usize][axis], i))
            .collect();
        // Equal centroids ordered by index: deterministic, same as a stable sort.
        keyed.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        keyed.into_iter().map(|(_, i)| i).collect::<Vec<u32>>()
    };
    let par = opts.parallel && n >= PARALLEL_MIN;
    let (mut x, (mut y, mut z)) = join(par, || sorted(0), || join(par, || sorted(1), || sorted(2)));
    let ctx = Ctx {
        prims,
        opts,
        left: (0..n).map(|_| AtomicBool::new(false)).collect(),
    };
    let root = node(&ctx, [&mut x, &mut y, &mut z], 0, 0);
    (root, x)
}

/// Best split found by the sweep: (cost, axis, number of primitives on the left).
fn sweep(ctx: &Ctx, lists: &[&mut [u32]; 3], area: f32) -> (f32, usize, usize) {
    let n = lists[0].len();
    let mut best = (f32::INFINITY, 0, n / 2);
    let mut right_area = vec![0.0f32; n];
    for (axis, list) in lists.iter().enumerate() {
        // right_area[k] = area of the box of list[k..].
        let mut b = Aabb::EMPTY;
        for k in (1..n).rev() {
            b = b.union(ctx.prims.boxes[list[k] as usize]);
            right_area[k] = b.area();
        }
        let mut b = Aabb::EMPTY;
        for k in 1..n {
            b = b.union(ctx.prims.boxes[list[k - 1] as usize]);
            let cost = ctx.opts.split_cost(area, b.area(), k, right_area[k], n - k);
            if cost < best.0 {
                best = (cost, axis, k);
            }
        }
    }
    best
}

fn node(ctx: &Ctx, lists: [&mut [u32]; 3], offset: usize, depth: usize) -> Node {
    let n = lists[0].len();
    let (bbox, cbox) = ctx.prims.bounds(lists[0]);
    if n == 1 || (ctx.opts.leaf_beats_any_split(n) && !ctx.opts.depth_forces_median(depth, n)) {
        return leaf(bbox, offset, n);
    }
    let (axis, k) = if ctx.opts.depth_forces_median(depth, n) || cbox.extent() == glam::Vec3::ZERO {
        // Depth cap, or identical centroids (no SAH candidate separates them): the object
        // median keeps the tree balanced. A leaf is still taken when the SAH prefers it.
        let cost = ctx.opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
        if !ctx.opts.depth_forces_median(depth, n) && ctx.opts.prefers_leaf(n, cost) {
            return leaf(bbox, offset, n);
        }
        (cbox.longest_axis(), n / 2)
    } else {
        let (cost, axis, k) = sweep(ctx, &lists, bbox.area());
        if ctx.opts.prefers_leaf(n, cost) {
            return leaf(bbox, offset, n);
        }
        (axis, k)
    };

    for (i, &p) in lists[axis].iter().enumerate() {
        ctx.left[p as usize].store(i < k, Ordering::Relaxed);
    }
    let mut scratch = Vec::with_capacity(n);
    let [a, b, c] = lists;
    for (i, list) in [&mut *a, &mut *b, &mut *c].into_iter().enumerate() {
        if i != axis {
            stable_partition(list, &ctx.left, &mut scratch);
        }
    }
    let (a0, a1) = a.split_at_mut(k);
    let (b0, b1) = b.split_at_mut(k);
    let (c0, c1) = c.split_at_mut(k);
    let par = ctx.opts.parallel && n >= PARALLEL_MIN;
    let (l, r) = join(
        par,
        || node(ctx, [a0, b0, c0], offset, depth + 1),
        || node(ctx, [a1, b1, c1], offset + k, depth + 1),
    );
    Node::inner(bbox, axis, [l, r])
}

/// Left-flagged entries first, both groups in their original order.
fn stable_partition(list: &mut [u32], left: &[AtomicBool], scratch: &mut Vec<u32>) {
    scratch.clear();
    let mut w = 0;
    for i in 0..list.len() {
        let p = list[i];
        if left[p as usize].load(Ordering::Relaxed) {
            list[w] = p;
            w += 1;
        } else {
            scratch.push(p);
        }
    }
    list[w..].copy_from_slice(scratch);
}
