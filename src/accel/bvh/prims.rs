//! The builders' shared kit: the primitives as references, parallel joins, median split.

use glam::Vec3;

use super::prim_ref::Ref;
use crate::geometry::Aabb;

/// Nodes with at least this many primitives build their two subtrees in parallel.
pub(crate) const PARALLEL_MIN: usize = 4096;

/// Per-primitive input of the builders: one reference (box and index) per primitive, in
/// index order (positions in the mesh's included triangles). The streaming builders take the
/// references over; the others read boxes and centroids from them.
pub(crate) struct Prims {
    pub refs: Vec<Ref>,
}

impl Prims {
    /// The references of these triangle boxes, made on all threads.
    pub fn new(boxes: impl rayon::iter::IndexedParallelIterator<Item = Aabb>) -> Prims {
        use rayon::prelude::*;
        let refs = boxes
            .enumerate()
            .map(|(i, b)| Ref::new(&b, i as u32))
            .collect();
        Prims { refs }
    }

    pub fn len(&self) -> usize {
        self.refs.len()
    }

    pub fn bbox(&self, i: u32) -> Aabb {
        self.refs[i as usize].bbox().aabb()
    }

    pub fn centroid(&self, i: u32) -> Vec3 {
        self.refs[i as usize].centroid().into()
    }

    pub fn bounds(&self, idx: &[u32]) -> (Aabb, Aabb) {
        idx.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &i| {
            (b.union(self.bbox(i)), c.grow(self.centroid(i)))
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
        let (ca, cb) = (prims.centroid(a)[axis], prims.centroid(b)[axis]);
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    k
}
