//! A bounding interval hierarchy (Wächter & Keller 2006, "Instant Ray Tracing: The
//! Bounding Interval Hierarchy"): a binary tree that partitions the triangles (each is
//! referenced once) and stores per inner node two clip planes on one axis — the left
//! child's maximum and the right child's minimum — so the children may overlap or leave a
//! gap. Built with the paper's global heuristic, traversed like a kd-tree with two plane
//! distances per node; one-sided nodes cut off empty space the global heuristic passes by.
//!
//! - `node.rs`: the 16-byte node, [`BihNode`], and its constants.
//! - `build.rs`: the global-heuristic split, empty-space cuts, the depth cap and the
//!   parallel build.
//! - `traverse.rs`: the [`Accel`](crate::accel::Accel) implementation, the CPU twin of
//!   `bih.wgsl`, which walks the same arrays step for step.
//! - `gpu.rs`: the [`GpuForm`](crate::accel::GpuForm) (arrays, WGSL, validation) that runs
//!   the tree on a GPU (`accel::build_gpu`).
//!
//! The arrays are GPU-ready: [`Bih::nodes`] (16-byte nodes in depth-first order) and
//! [`Bih::triangles`] (the shared 48-byte [`LeafTri`]s in leaf order).

mod build;
mod gpu;
mod node;
mod traverse;

pub use node::{BihNode, BIH_INDEX_MAX, BIH_LEAF_TAG, BIH_LINK_SHIFT, BIH_NODE_BYTES};

use crate::accel::LeafTri;
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use crate::limits::check_memory;
use crate::mesh::Mesh;
use crate::util::human_bytes;

/// Deepest leaf any BIH may have: the traversal's stack holds one entry per level.
pub const MAX_BIH_DEPTH: usize = 64;

/// What to do instead, when a build is refused.
const HINT: &str = "raise BihOptions::max_memory or use a smaller mesh";

/// How to build a [`Bih`]: leaf size, depth cap, memory cap.
///
/// Defaults: leaves of at most 4 triangles, the depth cap [`MAX_BIH_DEPTH`]. On the bunny
/// (2 threads, `tests/bih.rs`, `bunny_speed_and_million_builds`) leaves of 1, 2 and 4 trace
/// the 1024² default view within 5 % of each other and 8 is 25 % slower; on 2²⁰ random
/// rays 4 is the fastest (2 is 8 % slower, 1 is 25 % slower), and it builds the smallest
/// tree of the three.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BihOptions {
    /// A node of at most this many triangles is a leaf (0 counts as 1).
    pub max_leaf: usize,
    /// Deepest leaf: `None` = [`MAX_BIH_DEPTH`]; always capped at it. Where the global
    /// heuristic's split would leave a child too deep to reach leaves of `max_leaf`
    /// triangles under the cap, the node is split at the object median instead.
    pub max_depth: Option<usize>,
    /// Memory the build may use, in bytes: the build is refused (an error naming both sizes)
    /// when its estimate passes this. `None` = the memory available on the machine.
    pub max_memory: Option<u64>,
    /// Build big subtrees in parallel with rayon (the tree is identical to the serial one).
    pub parallel: bool,
}

impl Default for BihOptions {
    fn default() -> Self {
        BihOptions {
            max_leaf: 4,
            max_depth: None,
            max_memory: None,
            parallel: true,
        }
    }
}

impl BihOptions {
    /// The depth cap: `max_depth` or [`MAX_BIH_DEPTH`], at most [`MAX_BIH_DEPTH`].
    pub fn depth_cap(&self) -> usize {
        self.max_depth.unwrap_or(MAX_BIH_DEPTH).min(MAX_BIH_DEPTH)
    }

    /// Bytes a build over `n` triangles may need at its peak: per triangle its build
    /// reference, its index in the mesh's included list and its 48-byte [`LeafTri`]; nodes
    /// fewer than 3n (n − 1 splits and n leaves at most, every leaf holding a triangle, and
    /// a one-sided node above each split at most), twice while the parallel build joins subtrees.
    pub fn peak_bytes(n: usize) -> u128 {
        let per_tri = std::mem::size_of::<build::Prim>() + 4 + std::mem::size_of::<LeafTri>();
        let n = n as u128;
        n * per_tri as u128 + 2 * (3 * n).max(1) * BIH_NODE_BYTES as u128
    }
}

/// Size and shape of a built [`Bih`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BihStats {
    /// Triangles in the tree (the mesh's included ones), each referenced once.
    pub triangles: usize,
    /// All nodes, inner and leaves.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Triangles in the largest leaf.
    pub largest_leaf: usize,
    /// Depth of the deepest leaf (the root is at depth 0).
    pub max_depth: usize,
    /// The depth cap the tree was built under.
    pub depth_cap: usize,
    /// Inner nodes split at the object median rather than by the global heuristic (too
    /// deep for it, or centroids too close to separate by halving).
    pub median_splits: usize,
    /// One-sided nodes cutting off empty space (nodes = 2·leaves − 1 + cuts).
    pub cuts: usize,
    /// Memory of the built tree: nodes and triangles.
    pub bytes: usize,
}

/// A bounding interval hierarchy over the included triangles of a mesh, traced on the CPU
/// through [`Accel`](crate::accel::Accel). Hits report original triangle indices.
#[derive(Clone, Debug)]
pub struct Bih {
    /// Depth-first nodes; the root is node 0 (one empty leaf for an empty mesh).
    nodes: Vec<BihNode>,
    /// The triangles in leaf order, each with its original index.
    tris: Vec<LeafTri>,
    /// Bounds of the included triangles: the root's box.
    bounds: Aabb,
    stats: BihStats,
}

impl Bih {
    /// Builds the BIH over `mesh.included()` triangles. Refuses, with an error naming the
    /// size and the limit, a mesh whose peak build memory ([`BihOptions::peak_bytes`], known
    /// up front: nothing is duplicated) passes [`BihOptions::max_memory`] or the memory
    /// available, or whose nodes would not fit the 30-bit indices.
    pub fn build(mesh: &Mesh, opts: &BihOptions) -> Result<Bih> {
        let included = mesh.included();
        let n = included.len();
        let what = format!("a BIH over {n} triangles");
        let bytes = BihOptions::peak_bytes(n);
        if let Some(limit) = opts.max_memory {
            if bytes > limit as u128 {
                let need = u64::try_from(bytes).map_or("more than 16 EiB".into(), human_bytes);
                return Err(Error::Usage(format!(
                    "{what} needs {need} of memory, more than the limit of {} \
                     (BihOptions::max_memory): {HINT}",
                    human_bytes(limit)
                )));
            }
        }
        check_memory(&what, bytes, HINT)?;
        if 3 * n as u64 > BIH_INDEX_MAX as u64 + 2 {
            return Err(Error::Usage(format!(
                "{what} may need {} nodes, more than the {BIH_INDEX_MAX} its 30-bit indices \
                 address: use the BVH",
                3 * n as u64 - 2
            )));
        }
        let cap = opts.depth_cap();
        let built = build::build(mesh, &included, opts.max_leaf.max(1), cap, opts.parallel);
        let leaves = built.nodes.iter().filter(|n| n.is_leaf()).count();
        let stats = BihStats {
            triangles: n,
            nodes: built.nodes.len(),
            leaves,
            largest_leaf: built.largest_leaf,
            max_depth: built.max_depth,
            depth_cap: cap,
            median_splits: built.median_splits,
            cuts: built.cuts,
            bytes: built.nodes.len() * BIH_NODE_BYTES + n * std::mem::size_of::<LeafTri>(),
        };
        Ok(Bih {
            nodes: built.nodes,
            tris: built.tris,
            bounds: built.bounds,
            stats,
        })
    }

    /// Size and shape of the tree.
    pub fn stats(&self) -> BihStats {
        self.stats
    }

    /// The nodes, depth-first from the root (the array a GPU traversal walks).
    pub fn nodes(&self) -> &[BihNode] {
        &self.nodes
    }

    /// The triangles in leaf order, each with its original index (a leaf's `first`,
    /// `count` are a range of this array).
    pub fn triangles(&self) -> &[LeafTri] {
        &self.tris
    }

    /// Every inner node's clip planes as (axis 0 = x, 1 = y, 2 = z; left child's maximum,
    /// right child's minimum), depth-first.
    pub fn clip_planes(&self) -> Vec<(usize, f32, f32)> {
        self.nodes
            .iter()
            .filter(|n| !n.is_leaf())
            .map(|n| (n.axis(), n.clip[0], n.clip[1]))
            .collect()
    }
}
