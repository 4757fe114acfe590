//! The builders' shared kit: per-primitive boxes and centroids, parallel joins, median split.

use glam::Vec3;

use super::prim_ref::Ref;
use crate::geometry::Aabb;

/// Nodes with at least this many primitives build their two subtrees in parallel.
pub(crate) const PARALLEL_MIN: usize = 4096;

/// Per-primitive input of the builders, indexed by position in `ids`.
pub(crate) struct Prims {
    pub boxes: Vec<Aabb>,
    pub centroids: Vec<Vec3>,
}

impl Prims {
    /// One reference per primitive, in index order, made on all threads.
    pub fn refs(&self) -> Vec<Ref> {
        use rayon::prelude::*;
        (self.boxes.par_iter().enumerate())
            .map(|(i, b)| Ref::new(b, i as u32))
            .collect()
    }

    pub fn bounds(&self, idx: &[u32]) -> (Aabb, Aabb) {
        idx.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &i| {
            let i = i as usize;
            (b.union(self.boxes[i]), c.grow(self.centroids[i]))
        })
    }
}

/// Runs both closures, in parallel when asked and the node is big enough.
pub(crate) fn join<A: Send, B: Send>(
    parallel: bool,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    if parallel {
        rayon::join(a, b)
    } else {
        (a(), b())
    }
}

/// Sorts `idx` by centroid on `axis` (ties by index) and returns the middle position.
pub(crate) fn median_split(prims: &Prims, idx: &mut [u32], axis: usize) -> usize {
    let k = idx.len() / 2;
    idx.select_nth_unstable_by(k, |&a, &b| {
        let (ca, cb) = (
            prims.centroids[a as usize][axis],
            prims.centroids[b as usize][axis],
        );
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    k
}
