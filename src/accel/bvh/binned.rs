//! Binned SAH (Wald 2007): K equal bins over the centroid bounds on each axis.

use super::build::{join, leaf, median_split, BuildOptions, Node, Prims, PARALLEL_MIN};
use crate::geometry::Aabb;

pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let mut idx: Vec<u32> = (0..prims.boxes.len() as u32).collect();
    let root = node(prims, opts, &mut idx, 0, 0);
    (root, idx)
}

fn bin_of(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

fn node(prims: &Prims, opts: &BuildOptions, idx: &mut [u32], offset: usize, depth: usize) -> Node {
    let n = idx.len();
    let (bbox, cbox) = prims.bounds(idx);
    if n == 1 {
        return leaf(bbox, offset, 1);
    }
    let bins = opts.bins.max(2);
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, split bin)
    if !opts.depth_forces_median(depth, n) {
        let ext = cbox.extent();
        for axis in 0..3 {
            if ext[axis] <= 0.0 {
                continue;
            }
            let scale = bins as f32 / ext[axis];
            let mut count = vec![0usize; bins];
            let mut boxes = vec![Aabb::EMPTY; bins];
            for &p in idx.iter() {
                let b = bin_of(
                    prims.centroids[p as usize][axis],
                    cbox.lo[axis],
                    scale,
                    bins,
                );
                count[b] += 1;
                boxes[b] = boxes[b].union(prims.boxes[p as usize]);
            }
            let mut right_area = vec![0.0; bins];
            let mut right_n = vec![0; bins];
            let (mut b, mut m) = (Aabb::EMPTY, 0);
            for s in (1..bins).rev() {
                b = b.union(boxes[s]);
                m += count[s];
                right_area[s] = b.area();
                right_n[s] = m;
            }
            let (mut b, mut m) = (Aabb::EMPTY, 0);
            for s in 1..bins {
                b = b.union(boxes[s - 1]);
                m += count[s - 1];
                if m == 0 || right_n[s] == 0 {
                    continue;
                }
                let cost = opts.split_cost(bbox.area(), b.area(), m, right_area[s], right_n[s]);
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, s));
                }
            }
        }
    }
    let k = match best {
        Some((cost, axis, s)) => {
            if opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let scale = bins as f32 / cbox.extent()[axis];
            let lo = cbox.lo[axis];
            let (l, r): (Vec<u32>, Vec<u32>) = idx
                .iter()
                .partition(|&&p| bin_of(prims.centroids[p as usize][axis], lo, scale, bins) < s);
            idx[..l.len()].copy_from_slice(&l);
            idx[l.len()..].copy_from_slice(&r);
            (l.len(), axis)
        }
        None => {
            // Depth cap or identical centroids: object median.
            let cost = opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
            if !opts.depth_forces_median(depth, n) && opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let axis = cbox.longest_axis();
            (median_split(prims, idx, axis), axis)
        }
    };
    let (k, axis) = k;
    let (l, r) = idx.split_at_mut(k);
    let (a, b) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(prims, opts, l, offset, depth + 1),
        || node(prims, opts, r, offset + k, depth + 1),
    );
    Node::Inner {
        bbox,
        axis: axis as u8,
        children: Box::new([a, b]),
    }
}
