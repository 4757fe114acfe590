//! Binned SAH (Wald 2007): K equal bins over the centroid bounds on each axis, filled in
//! one pass over the node's primitives; the partition is in place.

use super::build::{join, leaf, median_split, BuildOptions, Node, Prims, PARALLEL_MIN};
use crate::geometry::Aabb;

pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> (Node, Vec<u32>) {
    let mut idx: Vec<u32> = (0..prims.boxes.len() as u32).collect();
    let (bbox, _) = prims.bounds(&idx);
    let root = node(prims, opts, &mut idx, bbox, 0, 0);
    (root, idx)
}

/// Maps centroids on one axis to bins.
#[derive(Clone, Copy)]
struct Binner {
    lo: f32,
    scale: f32,
    bins: usize,
}

impl Binner {
    fn bin(&self, c: f32) -> usize {
        (((c - self.lo) * self.scale) as usize).min(self.bins - 1)
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bbox: Aabb,
    count: usize,
}

fn node(
    prims: &Prims,
    opts: &BuildOptions,
    idx: &mut [u32],
    bbox: Aabb,
    offset: usize,
    depth: usize,
) -> Node {
    let n = idx.len();
    if n == 1 {
        return leaf(bbox, offset, 1);
    }
    let cbox = idx
        .iter()
        .fold(Aabb::EMPTY, |c, &p| c.grow(prims.centroids[p as usize]));
    let nbins = opts.bins.max(2);
    let ext = cbox.extent();
    let binners: [Option<Binner>; 3] = std::array::from_fn(|a| {
        (ext[a] > 0.0).then(|| Binner {
            lo: cbox.lo[a],
            scale: nbins as f32 / ext[a],
            bins: nbins,
        })
    });
    // (cost, axis, first bin on the right, left box, right box)
    let mut best: Option<(f32, usize, usize, Aabb, Aabb)> = None;
    if !opts.depth_forces_median(depth, n) && binners.iter().any(Option::is_some) {
        let empty = Bin {
            bbox: Aabb::EMPTY,
            count: 0,
        };
        let mut bins = vec![[empty; 3]; nbins];
        // Every axis is binned (a flat one all into bin 0, never chosen): no branch per axis.
        let scale = binners.map(|b| b.map_or(0.0, |b| b.scale));
        let lo = cbox.lo;
        for &p in idx.iter() {
            let (c, b) = (prims.centroids[p as usize], prims.boxes[p as usize]);
            for a in 0..3 {
                let k = (((c[a] - lo[a]) * scale[a]) as usize).min(nbins - 1);
                let bin = &mut bins[k][a];
                bin.bbox = bin.bbox.union(b);
                bin.count += 1;
            }
        }
        let area = bbox.area();
        let mut right = vec![(Aabb::EMPTY, 0usize); nbins];
        for a in (0..3).filter(|&a| binners[a].is_some()) {
            let mut acc = (Aabb::EMPTY, 0);
            for s in (1..nbins).rev() {
                acc = (acc.0.union(bins[s][a].bbox), acc.1 + bins[s][a].count);
                right[s] = acc;
            }
            let mut l = (Aabb::EMPTY, 0);
            for s in 1..nbins {
                l = (l.0.union(bins[s - 1][a].bbox), l.1 + bins[s - 1][a].count);
                let r = right[s];
                if l.1 == 0 || r.1 == 0 {
                    continue;
                }
                let cost = opts.split_cost(area, l.0.area(), l.1, r.0.area(), r.1);
                if best.is_none_or(|b| cost < b.0) {
                    best = Some((cost, a, s, l.0, r.0));
                }
            }
        }
    }
    let (k, axis, lbox, rbox) = match best {
        Some((cost, axis, s, lbox, rbox)) => {
            if opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let bn = binners[axis].expect("axis with extent");
            let k = partition(idx, |p| bn.bin(prims.centroids[p as usize][axis]) < s);
            (k, axis, lbox, rbox)
        }
        None => {
            // Depth cap or identical centroids: object median.
            let cost = opts.split_cost(1.0, 1.0, n / 2, 1.0, n - n / 2);
            if !opts.depth_forces_median(depth, n) && opts.prefers_leaf(n, cost) {
                return leaf(bbox, offset, n);
            }
            let axis = cbox.longest_axis();
            let k = median_split(prims, idx, axis);
            (
                k,
                axis,
                prims.bounds(&idx[..k]).0,
                prims.bounds(&idx[k..]).0,
            )
        }
    };
    let (l, r) = idx.split_at_mut(k);
    let (a, b) = join(
        opts.parallel && n >= PARALLEL_MIN,
        || node(prims, opts, l, lbox, offset, depth + 1),
        || node(prims, opts, r, rbox, offset + k, depth + 1),
    );
    Node::Inner {
        bbox,
        axis: axis as u8,
        children: Box::new([a, b]),
    }
}

/// In-place two-pointer partition (deterministic); returns the size of the `true` side.
fn partition(idx: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let (mut i, mut j) = (0, idx.len());
    while i < j {
        if left(idx[i]) {
            i += 1;
        } else {
            j -= 1;
            idx.swap(i, j);
        }
    }
    i
}
