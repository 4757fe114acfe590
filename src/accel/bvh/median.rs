//! Object-median build: split at the median centroid on the longest centroid axis; a node
//! becomes a leaf under the same SAH rule as the other builders.

use super::prims::{join, median_split, Prims, PARALLEL_MIN};
use super::tree::{leaf, Kids, Node};
use super::BuildOptions;

pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let mut idx: Vec<u32> = (0..prims.len() as u32).collect();
    let root = node(prims, opts, &mut idx, 0);
    (root, idx)
}

fn node(prims: &Prims, opts: &BuildOptions, idx: &mut [u32], offset: usize) -> Node {
    let n = idx.len();
    let (bbox, cbox) = prims.bounds(idx);
    if n == 1 {
        return leaf(bbox, offset, 1);
    }
    let axis = cbox.longest_axis();
    let k = median_split(prims, idx, axis);
    let (lb, _) = prims.bounds(&idx[..k]);
    let (rb, _) = prims.bounds(&idx[k..]);
    let cost = opts.split_cost(bbox.area(), lb.area(), k, rb.area(), n - k);
    if opts.prefers_leaf(n, cost) {
        return leaf(bbox, offset, n);
    }
    let kids = Kids::reserve();
    let (l, r) = idx.split_at_mut(k);
    let (a, b) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(prims, opts, l, offset),
        || node(prims, opts, r, offset + k),
    );
    kids.inner(bbox, axis, [a, b])
}
