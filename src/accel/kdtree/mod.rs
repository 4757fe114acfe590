//! A kd-tree over a mesh's triangles: SAH splits found by the O(N log N) event sweep of
//! Wald & Havran 2006 ("On building fast kd-trees for ray tracing, and on doing that in
//! O(N log N)"), triangles clipped to their cells, and a front-to-back stack traversal that
//! keeps the tie rule (equal t → smaller original index).
//!
//! - `build.rs`: events, the SAH sweep, classification and the split of sorted event lists.
//! - `clip.rs`: Sutherland–Hodgman clipping of a triangle to a cell, conservatively.
//! - `traverse.rs`: the [`Accel`](crate::accel::Accel) implementation, which is also the CPU
//!   twin of the GPU traversal;
//! - `gpu.rs` and `kdtree.wgsl`: the tree as a [`GpuForm`](crate::accel::GpuForm): its own
//!   node and triangle arrays uploaded as they are, walked by the WGSL step for step as
//!   `traverse.rs` walks them.

mod build;
mod gpu;
mod traverse;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::LeafTri;
use crate::error::Result;
use crate::geometry::{Aabb, Triangle};
use crate::mesh::Mesh;

/// Deepest leaf any kd-tree may have: the traversal's stack holds one entry per level.
pub const MAX_KD_DEPTH: usize = 64;

/// How to build a [`KdTree`]: the SAH constants, the depth cap and the memory cap.
///
/// Defaults: `traversal_cost = 1`, `intersection_cost = 1.5`, `empty_bonus = 0.8`, the
/// depth cap ⌊8 + 1.3·log2 N⌋. The costs keep Wald & Havran's ratio (K_T = 15, K_I = 20: a
/// triangle test costs about 1.3 inner-node steps), a little higher because the watertight
/// test with its per-vertex shear is dearer than their Möller–Trumbore while a kd step is
/// one multiply and two compares; their empty-space bonus makes a split that leaves one
/// side empty cost 80 %. Measured on the bunny (1024² default view and 2²⁰ random rays, 2
/// threads), K_I = 1, 1.2, 1.5 and 2 trace within 2 % of each other; 1.5 keeps their
/// ratio and tests 20 % fewer triangles per ray than 1 (which matters more where a test is
/// dearer than here), for a 20 % larger tree (360 k references against 300 k)
/// (`tests/kdtree.rs`, `bunny_speed_against_the_bvh`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KdOptions {
    /// K_T: the cost of one inner-node step.
    pub traversal_cost: f32,
    /// K_I: the cost of one ray–triangle test.
    pub intersection_cost: f32,
    /// λ: factor on a split's cost when one side holds no triangle (1 = no bonus).
    pub empty_bonus: f32,
    /// Deepest leaf: `None` = ⌊8 + 1.3·log2 N⌋ (pbrt's rule); always capped at
    /// [`MAX_KD_DEPTH`].
    pub max_depth: Option<usize>,
    /// Memory the build may use, in bytes: the build is refused (an error naming both sizes)
    /// when its estimate passes this. `None` = the memory available on the machine.
    pub max_memory: Option<u64>,
    /// Build big subtrees in parallel with rayon (the tree is identical to the serial one).
    pub parallel: bool,
}

impl Default for KdOptions {
    fn default() -> Self {
        KdOptions {
            traversal_cost: 1.0,
            intersection_cost: 1.5,
            empty_bonus: 0.8,
            max_depth: None,
            max_memory: None,
            parallel: true,
        }
    }
}

impl KdOptions {
    /// The depth cap for `n` triangles: `max_depth` or ⌊8 + 1.3·log2 n⌋, at most
    /// [`MAX_KD_DEPTH`].
    pub fn depth_cap(&self, n: usize) -> usize {
        let auto = || (8.0 + 1.3 * (n.max(1) as f64).log2()) as usize;
        self.max_depth.unwrap_or_else(auto).min(MAX_KD_DEPTH)
    }
}

/// Size and shape of a built [`KdTree`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KdStats {
    /// Triangles in the tree (the mesh's included ones).
    pub triangles: usize,
    /// All nodes, inner and leaves.
    pub nodes: usize,
    /// Leaves (empty ones included).
    pub leaves: usize,
    /// Leaves with no triangle.
    pub empty_leaves: usize,
    /// Depth of the deepest leaf (the root is at depth 0).
    pub max_depth: usize,
    /// The depth cap the tree was built under.
    pub depth_cap: usize,
    /// Triangle references held by the leaves.
    pub references: usize,
    /// References beyond one per triangle: triangles that straddle split planes are
    /// referenced by every leaf they reach.
    pub duplicated_references: usize,
    /// Memory of the built tree: nodes and leaf triangles (a 48-byte copy per reference).
    pub bytes: usize,
}

/// A node: 8 bytes, two to a 16-byte GPU word (WGSL `kd_load_node` in kdtree.wgsl).
/// Inner: `a` = the split position's bits, `b` = index of the child above the split <<
/// [`ABOVE_SHIFT`] | [`ABOVE_EMPTY`] | [`BELOW_EMPTY`] | axis; the child below is the next
/// node. Leaf: `a` = first triangle, `b` = count << [`COUNT_SHIFT`] | [`LEAF_TAG`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Node {
    a: u32,
    b: u32,
}

/// The low two bits of `b`: a leaf when equal to this, else the split axis.
pub(crate) const LEAF_TAG: u32 = 3;
/// Inner-node flag: the child below the split is an empty leaf.
pub(crate) const BELOW_EMPTY: u32 = 1 << 2;
/// Inner-node flag: the child above the split is an empty leaf.
pub(crate) const ABOVE_EMPTY: u32 = 1 << 3;
/// Where an inner node's `b` holds the above child's index.
pub(crate) const ABOVE_SHIFT: u32 = 4;
/// Where a leaf's `b` holds its triangle count.
pub(crate) const COUNT_SHIFT: u32 = 2;

/// Largest node index or leaf size a [`Node`] can hold.
pub(crate) const NODE_FIELD_MAX: usize = (1 << 28) - 1;

impl Node {
    pub(crate) fn leaf(first: u32, count: u32) -> Node {
        Node {
            a: first,
            b: (count << COUNT_SHIFT) | LEAF_TAG,
        }
    }
    /// An inner node; `below` and `above` are its children (for their emptiness).
    pub(crate) fn inner(axis: usize, split: f32, above_idx: u32, below: Node, above: Node) -> Node {
        let flag = |child: Node, bit: u32| if child.is_empty_leaf() { bit } else { 0 };
        Node {
            a: split.to_bits(),
            b: (above_idx << ABOVE_SHIFT)
                | flag(above, ABOVE_EMPTY)
                | flag(below, BELOW_EMPTY)
                | axis as u32,
        }
    }
    #[inline(always)]
    pub(crate) fn is_leaf(self) -> bool {
        self.b & 3 == LEAF_TAG
    }
    pub(crate) fn is_empty_leaf(self) -> bool {
        self.is_leaf() && self.count() == 0
    }
    #[inline(always)]
    pub(crate) fn axis(self) -> usize {
        (self.b & 3) as usize
    }
    #[inline(always)]
    pub(crate) fn split(self) -> f32 {
        f32::from_bits(self.a)
    }
    #[inline(always)]
    pub(crate) fn above(self) -> usize {
        (self.b >> ABOVE_SHIFT) as usize
    }
    /// Whether the child below / above the split is an empty leaf (not worth a visit).
    #[inline(always)]
    pub(crate) fn empty_children(self) -> (bool, bool) {
        (self.b & BELOW_EMPTY != 0, self.b & ABOVE_EMPTY != 0)
    }
    #[inline(always)]
    pub(crate) fn first(self) -> usize {
        self.a as usize
    }
    #[inline(always)]
    pub(crate) fn count(self) -> usize {
        (self.b >> COUNT_SHIFT) as usize
    }
    /// This node moved into a larger array: children `nodes` and references `refs` later.
    pub(crate) fn shifted(self, nodes: u32, refs: u32) -> Node {
        if self.is_leaf() {
            Node {
                a: self.a + refs,
                b: self.b,
            }
        } else {
            Node {
                a: self.a,
                b: self.b + (nodes << ABOVE_SHIFT),
            }
        }
    }
}

/// A triangle with its original (file-order) index: 40 bytes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct KdTri {
    pub(crate) v: [Vec3; 3],
    pub(crate) prim: u32,
}

/// A kd-tree over the included triangles of a mesh, traced on the CPU through
/// [`Accel`](crate::accel::Accel) and on the GPU as a [`GpuForm`](crate::accel::GpuForm)
/// (the same arrays). Hits report original triangle indices.
///
/// A leaf's triangles are copies ([`LeafTri`], 48 bytes, ascending original index within a
/// leaf), one per reference, rather than 4-byte indices into one triangle array: a triangle
/// test then loads 3 words instead of 4, the fourth dependent on a load before it, at 44
/// more bytes per reference (the bunny: 360 k references, 17 MiB instead of 4 MiB).
#[derive(Clone, Debug)]
pub struct KdTree {
    /// Depth-first nodes; the root is node 0 (a single empty leaf for an empty mesh). An
    /// unreachable empty leaf pads an odd count to whole 16-byte words.
    pub(crate) nodes: Vec<Node>,
    /// The leaves' triangles: leaf (first, count) is `tris[first..first + count]`.
    pub(crate) tris: Vec<LeafTri>,
    /// Bounds of the included triangles: the root cell.
    pub(crate) bounds: Aabb,
    stats: KdStats,
}

impl KdTree {
    /// Builds the kd-tree over `mesh.included()` triangles. Refuses, with an error naming the
    /// size and the limit, a build whose memory estimate (up front, then as straddling
    /// triangles add references) passes [`KdOptions::max_memory`] or the memory available.
    pub fn build(mesh: &Mesh, opts: &KdOptions) -> Result<KdTree> {
        let tris: Vec<KdTri> = mesh
            .included()
            .into_iter()
            .map(|i| KdTri {
                v: mesh.triangles[i as usize].v,
                prim: i,
            })
            .collect();
        let bounds = tris
            .iter()
            .fold(Aabb::EMPTY, |b, t| b.union(Triangle { v: t.v }.bbox()));
        let cap = opts.depth_cap(tris.len());
        let mut built = build::build(&tris, &bounds, opts, cap)?;
        let leaves = built.nodes.iter().filter(|n| n.is_leaf()).count();
        let empty_leaves = built.nodes.iter().filter(|n| n.is_empty_leaf()).count();
        let leaf_tris: Vec<LeafTri> = (built.refs.par_iter())
            .map(|&r| {
                let t = &tris[r as usize];
                LeafTri::new(t.v, t.prim)
            })
            .collect();
        let stats = KdStats {
            triangles: tris.len(),
            nodes: built.nodes.len(),
            leaves,
            empty_leaves,
            max_depth: built.max_depth,
            depth_cap: cap,
            references: built.refs.len(),
            duplicated_references: built.refs.len().saturating_sub(tris.len()),
            bytes: built.nodes.len() * std::mem::size_of::<Node>()
                + leaf_tris.len() * std::mem::size_of::<LeafTri>(),
        };
        if built.nodes.len() % 2 == 1 {
            built.nodes.push(Node::leaf(0, 0));
        }
        Ok(KdTree {
            nodes: built.nodes,
            tris: leaf_tris,
            bounds,
            stats,
        })
    }

    /// Size and shape of the tree.
    pub fn stats(&self) -> KdStats {
        self.stats
    }

    /// Every inner node's split as (axis 0 = x, 1 = y, 2 = z; position), depth-first.
    pub fn split_planes(&self) -> Vec<(usize, f32)> {
        self.nodes[..self.stats.nodes]
            .iter()
            .filter(|n| !n.is_leaf())
            .map(|n| (n.axis(), n.split()))
            .collect()
    }
}
