//! Acceleration structures on the CPU: one trait, [`Accel`], and one entry point,
//! [`build`]. The BVH is built by [`bvh`] and traversed through a flattened
//! [`Layout`](crate::layout::Layout), whose CPU twin is the BVH's `Accel`: the CPU walks
//! the same arrays, in the same order, as the GPU kernel.

pub mod bvh;
pub mod grid;
pub mod kdtree;

mod query;

use rayon::prelude::*;

use crate::geometry::{Aabb, Hit, Ray, Robustness};
use crate::layout::{self, LayoutKind};
use crate::mesh::Mesh;

pub use query::{Query, RayStats};

/// A CPU acceleration structure over a mesh's triangles.
///
/// Hits report original (file-order) triangle indices; ties at equal t go to the smaller
/// index; an invalid ray (NaN, zero direction, empty interval) is a miss.
pub trait Accel: Send + Sync {
    /// Bounds of the triangles in the structure (empty when there are none).
    fn bounds(&self) -> Aabb;

    /// Traces one ray: the closest hit in [tmin, tmax], or any hit for [`Query::Any`].
    /// Adds the work done to `stats`.
    fn intersect(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit;

    /// Traces a batch of rays on all threads; returns hits and per-ray work.
    fn trace_batch(
        &self,
        rays: &[Ray],
        query: Query,
        robustness: &Robustness,
    ) -> (Vec<Hit>, Vec<RayStats>) {
        rays.par_iter()
            .map(|r| {
                let mut s = RayStats::default();
                let h = self.intersect(r, query, robustness, &mut s);
                (h, s)
            })
            .unzip()
    }
}

/// Which acceleration structure to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccelKind {
    /// A BVH, traversed through the given flattened layout's CPU twin.
    Bvh(LayoutKind),
}

impl Default for AccelKind {
    fn default() -> Self {
        AccelKind::Bvh(LayoutKind::default())
    }
}

/// Builds an acceleration structure over the mesh's usable triangles.
pub fn build(kind: AccelKind, mesh: &Mesh, options: &bvh::BuildOptions) -> Box<dyn Accel> {
    match kind {
        AccelKind::Bvh(layout) => {
            let tree = bvh::build(mesh, options);
            layout::flatten(layout, &tree, mesh)
        }
    }
}
