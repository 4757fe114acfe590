//! Acceleration structures: one trait, [`Accel`], and two entry points, [`build`] (the CPU
//! form of every structure) and [`build_gpu`] (the GPU form of those that have one). The BVH
//! is built by [`bvh`] and traversed through a flattened [`GpuForm`], whose CPU twin is the
//! BVH's `Accel`: the CPU walks the same arrays, in the same order, as the GPU kernel. The
//! kd-tree and the BIH are their own [`GpuForm`]s (their CPU traversals are the twins of their
//! WGSL).

pub mod bih;
pub mod bvh;
pub mod grid;
pub mod instances;
pub mod kdtree;
pub mod octree;

mod gpu_form;
pub(crate) mod leaf_tri;
mod plane_ray;
mod query;
mod traversal_mode;

use std::sync::Arc;

use rayon::prelude::*;

use crate::accel::bvh::layouts::{self, LayoutKind};
use crate::geometry::{Aabb, Hit, Ray, Robustness};
use crate::mesh::Mesh;

pub(crate) use gpu_form::capacity_for;
pub use gpu_form::{GpuArrays, GpuForm, ROOM_BYTES, ROOM_MIN_BYTES};
pub use leaf_tri::LeafTri;
pub use query::{HitMask, Mask, Query, RayStats};
pub use traversal_mode::TraversalMode;

/// Rays a CPU thread takes at a time in a batch ([`Accel::trace_hits`]): enough to make
/// the hand-over cost nothing, few enough to balance two threads on a small batch.
pub const RAY_CHUNK: usize = 1024;

/// How CPU tracers drive a batch (the twins' default [`Accel::trace_hits`] and the Embree
/// row alike; cwbvh's twin answers whole chunks, [`trace_chunks`]): rayon's threads take
/// [`RAY_CHUNK`] rays at a time, each chunk with its own
/// `scratch()` (work counters, an Embree context), and `trace` answers one ray, written in
/// place into an output filled with `empty`; the answers are in ray order.
pub(crate) fn trace_in_chunks<T, S>(
    rays: &[Ray],
    empty: T,
    scratch: impl Fn() -> S + Sync,
    trace: impl Fn(&mut S, &Ray) -> T + Sync,
) -> Vec<T>
where
    T: Clone + Send + Sync,
{
    trace_chunks(rays, empty, |rays, out| {
        let mut s = scratch();
        for (o, r) in out.iter_mut().zip(rays) {
            *o = trace(&mut s, r);
        }
    })
}

/// [`trace_in_chunks`] for a tracer that answers a whole chunk at once: `trace(rays, out)`
/// writes the answers to `rays` into `out` (as long, filled with `empty`).
pub(crate) fn trace_chunks<T>(
    rays: &[Ray],
    empty: T,
    trace: impl Fn(&[Ray], &mut [T]) + Sync,
) -> Vec<T>
where
    T: Clone + Send + Sync,
{
    let mut out = vec![empty; rays.len()];
    out.par_chunks_mut(RAY_CHUNK)
        .zip(rays.par_chunks(RAY_CHUNK))
        .for_each(|(out, rays)| trace(rays, out));
    out
}

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
    ) -> Hit {
        self.intersect_masked(ray, query, robustness, None, stats)
    }

    /// [`Accel::intersect`] where a hit counts only if `mask` keeps it ([`HitMask`]):
    /// masked-out hits are skipped in the traversal, by closest-hit and any-hit alike.
    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit;

    /// [`Accel::intersect_masked`], and where the structure keeps it the prune bound of the
    /// hit returned: the bound its traversal cut boxes against after taking that hit
    /// ([`TriHit::prune`](crate::geometry::TriHit::prune), the WGSL `taken_prune`), which a
    /// two-level walk carries on to the next instance instead of testing the triangle
    /// again. None where the structure does not keep it (and for a miss, whatever it is).
    fn intersect_pruned(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, Option<f32>) {
        (
            self.intersect_masked(ray, query, robustness, mask, stats),
            None,
        )
    }

    /// This structure as cwbvh's CPU twin, if it is one: the two-level twin
    /// ([`TwoLevel`](instances::TwoLevel)) walks a batch through cwbvh bottom levels two rays
    /// at a time, as cwbvh's own batches are walked.
    fn as_cwbvh(&self) -> Option<&layouts::Cwbvh> {
        None
    }

    /// Traces a batch of rays on all threads; returns the hits alone, without recording
    /// per-ray work (what [`Tracer`](crate::Tracer) runs when no statistics are asked for;
    /// rays go to the threads in chunks of [`RAY_CHUNK`], as the Embree row's do).
    fn trace_hits(&self, rays: &[Ray], query: Query, robustness: &Robustness) -> Vec<Hit> {
        trace_in_chunks(rays, Hit::miss(0.0), RayStats::default, |stats, r| {
            self.intersect(r, query, robustness, stats)
        })
    }

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

/// Which acceleration structure to build: the registry, one variant per folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccelKind {
    /// A BVH, traversed through the given flattened layout's CPU twin.
    Bvh(LayoutKind),
    /// An SAH kd-tree ([`kdtree::KdTree`]).
    KdTree,
    /// A uniform grid ([`grid::UniformGrid`]).
    UniformGrid,
    /// A two-level grid ([`grid::TwoLevelGrid`]).
    TwoLevelGrid,
    /// A hashed grid, only non-empty cells stored ([`grid::HashedGrid`]).
    HashedGrid,
    /// A bounding interval hierarchy ([`bih::Bih`]).
    Bih,
    /// An octree ([`octree::Octree`]).
    Octree,
}

impl AccelKind {
    /// Every structure, the BVH (in dfs-sign, the simplest layout) first (benches and tests
    /// run them all).
    pub const ALL: &'static [AccelKind] = &[
        AccelKind::Bvh(LayoutKind::DfsSign),
        AccelKind::KdTree,
        AccelKind::UniformGrid,
        AccelKind::TwoLevelGrid,
        AccelKind::HashedGrid,
        AccelKind::Bih,
        AccelKind::Octree,
    ];

    /// The name the command line and benches use.
    pub fn name(self) -> &'static str {
        match self {
            AccelKind::Bvh(_) => "bvh",
            AccelKind::KdTree => "kdtree",
            AccelKind::UniformGrid => "grid",
            AccelKind::TwoLevelGrid => "grid2",
            AccelKind::HashedGrid => "hashgrid",
            AccelKind::Bih => "bih",
            AccelKind::Octree => "octree",
        }
    }

    /// The structure of this [name](AccelKind::name), the BVH in dfs-sign (see
    /// [`with_layout`](AccelKind::with_layout)), if any.
    pub fn from_name(name: &str) -> Option<AccelKind> {
        AccelKind::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// This structure, the BVH in `layout` (the others have no layout).
    pub fn with_layout(self, layout: LayoutKind) -> AccelKind {
        match self {
            AccelKind::Bvh(_) => AccelKind::Bvh(layout),
            other => other,
        }
    }

    /// Whether it has a GPU kernel ([`build_gpu`] builds its GPU form).
    pub fn has_gpu_form(self) -> bool {
        matches!(self, AccelKind::Bvh(_) | AccelKind::KdTree | AccelKind::Bih)
    }

    /// What it is, in a few words (the command line's help).
    pub fn describe(self) -> &'static str {
        match self {
            AccelKind::Bvh(_) => "Bounding volume hierarchy (CPU and GPU)",
            AccelKind::KdTree => "SAH kd-tree (CPU and GPU)",
            AccelKind::UniformGrid => "Uniform grid (CPU)",
            AccelKind::TwoLevelGrid => "Two-level grid (CPU)",
            AccelKind::HashedGrid => "Hashed grid (CPU)",
            AccelKind::Bih => "Bounding interval hierarchy (CPU and GPU)",
            AccelKind::Octree => "Octree (CPU)",
        }
    }
}

impl std::fmt::Display for AccelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Builds an acceleration structure over the mesh's usable triangles (each structure with its
/// default options; the BVH with `options`). Structures that would not fit in memory are
/// refused with the size and the limit named.
pub fn build(
    kind: AccelKind,
    mesh: &Mesh,
    options: &bvh::BuildOptions,
) -> crate::Result<Box<dyn Accel>> {
    mesh.check_arrays()?;
    Ok(match kind {
        AccelKind::Bvh(layout) => {
            let tree = bvh::build(mesh, options);
            layouts::try_flatten_owned(layout, tree, mesh)?
        }
        AccelKind::KdTree => Box::new(kdtree::KdTree::build(mesh, &Default::default())?),
        AccelKind::UniformGrid => Box::new(grid::UniformGrid::build(mesh, &Default::default())?),
        AccelKind::TwoLevelGrid => Box::new(grid::TwoLevelGrid::build(mesh, &Default::default())?),
        AccelKind::HashedGrid => Box::new(grid::HashedGrid::build(mesh, &Default::default())?),
        AccelKind::Bih => Box::new(bih::Bih::build(mesh, &Default::default())?),
        AccelKind::Octree => Box::new(octree::Octree::build(mesh, &Default::default())?),
    })
}

/// Builds the GPU form of structure `kind` (arrays, WGSL traversal and CPU twin), or None
/// when it has no GPU kernel (nothing is built then). Options as for [`build`].
pub fn build_gpu(
    kind: AccelKind,
    mesh: &Mesh,
    options: &bvh::BuildOptions,
) -> crate::Result<Option<Arc<dyn GpuForm>>> {
    Ok(match kind {
        AccelKind::Bvh(layout) => {
            let tree = bvh::build(mesh, options);
            Some(layouts::try_flatten_owned(layout, tree, mesh)?.into())
        }
        AccelKind::KdTree => Some(Arc::new(kdtree::KdTree::build(mesh, &Default::default())?)),
        AccelKind::Bih => Some(Arc::new(bih::Bih::build(mesh, &Default::default())?)),
        AccelKind::UniformGrid
        | AccelKind::TwoLevelGrid
        | AccelKind::HashedGrid
        | AccelKind::Octree => None,
    })
}
