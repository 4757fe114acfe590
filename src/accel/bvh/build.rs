//! Shared parts of the three builders: options, the tree they produce, the SAH cost, the
//! leaf rule and the depth cap.

use glam::Vec3;
use rayon::prelude::*;

use crate::geometry::Aabb;
use crate::scene::Mesh;

/// Deepest leaf depth (root = 0). Traversal keeps one stack entry per interior ancestor,
/// so a 64-entry stack (CPU and GPU) can never overflow.
pub const MAX_DEPTH: usize = 64;

/// Nodes with at least this many primitives build their two subtrees in parallel.
pub(crate) const PARALLEL_MIN: usize = 4096;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Builder {
    /// Full sweep SAH over every centroid on all three axes (the seed's algorithm).
    #[default]
    Sweep,
    /// Binned SAH with `bins` bins per axis.
    Binned,
    /// Object median on the longest centroid axis.
    Median,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    pub builder: Builder,
    /// Cost of one box test; a split costs 2·t_cube (both children are tested).
    pub t_cube: f32,
    /// Cost of one triangle test.
    pub t_obj: f32,
    /// A node with more primitives than this is always split.
    pub max_leaf: usize,
    /// Bins per axis for the binned builder.
    pub bins: usize,
    /// Deepest leaf allowed (capped at MAX_DEPTH, the traversal stack size). Honoured by the
    /// SAH builders for any input with ⌈log2 N⌉ ≤ max_depth; the median tree is balanced.
    pub max_depth: usize,
    /// Build subtrees in parallel with rayon (the result is identical to the serial build).
    pub parallel: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            builder: Builder::Sweep,
            t_cube: 1.0,
            t_obj: 1.0,
            max_leaf: 16,
            bins: 16,
            max_depth: MAX_DEPTH,
            parallel: true,
        }
    }
}

impl BuildOptions {
    /// T = 2·T_cube + (A_L·N_L + A_R·N_R)/A·T_obj.
    pub fn split_cost(&self, a: f32, al: f32, nl: usize, ar: f32, nr: usize) -> f32 {
        // A zero-area node (possible only for sub-denormal geometry): weigh sides by count.
        let (al, ar, a) = if a > 0.0 {
            (al, ar, a)
        } else {
            (1.0, 1.0, 1.0)
        };
        2.0 * self.t_cube + (al * nl as f32 + ar * nr as f32) / a * self.t_obj
    }

    /// Leaf when N·T_obj ≤ best split cost, unless N exceeds max_leaf.
    pub fn prefers_leaf(&self, n: usize, best_split: f32) -> bool {
        n <= self.max_leaf.max(1) && n as f32 * self.t_obj <= best_split
    }

    /// A leaf of n primitives costs n·T_obj and any split at least 2·T_cube (both children
    /// are tested; areas are ≥ 0), so when n·T_obj ≤ 2·T_cube the node is a leaf without
    /// evaluating a single split — the tree is the same, the work is not.
    pub(crate) fn leaf_beats_any_split(&self, n: usize) -> bool {
        n <= self.max_leaf.max(1) && n as f32 * self.t_obj <= 2.0 * self.t_cube
    }

    /// Whether a node must take a balanced (median) split to keep every leaf within
    /// max_depth: a median split halves n, so depth + ⌈log2 n⌉ ≤ max_depth holds all the way
    /// down (it holds at the root for any n < 2^64 when max_depth = 64).
    pub(crate) fn depth_forces_median(&self, depth: usize, n: usize) -> bool {
        depth + ceil_log2(n) >= self.max_depth.min(MAX_DEPTH)
    }
}

fn ceil_log2(n: usize) -> usize {
    (usize::BITS - n.saturating_sub(1).leading_zeros()) as usize
}

/// A built tree. Leaves refer to ranges of [`Bvh::order`].
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    Leaf {
        bbox: Aabb,
        start: u32,
        count: u32,
    },
    Inner {
        bbox: Aabb,
        axis: u8,
        /// Nodes in this subtree, itself included: where flattening puts the second child.
        nodes: u32,
        children: Box<[Node; 2]>,
    },
}

impl Node {
    pub(crate) fn inner(bbox: Aabb, axis: usize, children: [Node; 2]) -> Node {
        Node::Inner {
            bbox,
            axis: axis as u8,
            nodes: 1 + children[0].nodes() + children[1].nodes(),
            children: Box::new(children),
        }
    }

    /// Nodes in this subtree, itself included.
    pub fn nodes(&self) -> u32 {
        match self {
            Node::Leaf { .. } => 1,
            Node::Inner { nodes, .. } => *nodes,
        }
    }

    pub fn bbox(&self) -> &Aabb {
        match self {
            Node::Leaf { bbox, .. } | Node::Inner { bbox, .. } => bbox,
        }
    }
}

/// A BVH over the included triangles of a mesh: `order[i]` is the original triangle index
/// at position i of leaf order (leaves appear left to right).
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    pub root: Node,
    pub order: Vec<u32>,
}

impl Drop for Bvh {
    /// A big tree is one small allocation per inner node: the top subtrees are freed on all
    /// threads.
    fn drop(&mut self) {
        fn free(node: Node, depth: u32) {
            if let Node::Inner { children, .. } = node {
                if depth < 4 {
                    let [a, b] = *children;
                    rayon::join(|| free(a, depth + 1), || free(b, depth + 1));
                }
            }
        }
        free(
            std::mem::replace(&mut self.root, leaf(Aabb::EMPTY, 0, 0)),
            0,
        );
    }
}

/// Per-primitive input of the builders, indexed by position in `ids`.
pub(crate) struct Prims {
    pub boxes: Vec<Aabb>,
    pub centroids: Vec<Vec3>,
}

impl Prims {
    pub fn bounds(&self, idx: &[u32]) -> (Aabb, Aabb) {
        idx.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &i| {
            let i = i as usize;
            (b.union(self.boxes[i]), c.grow(self.centroids[i]))
        })
    }
}

pub(crate) fn leaf(bbox: Aabb, start: usize, count: usize) -> Node {
    Node::Leaf {
        bbox,
        start: start as u32,
        count: count as u32,
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

/// Builds a BVH over the mesh's included triangles. Deterministic for a given input.
pub fn build(mesh: &Mesh, opts: &BuildOptions) -> Bvh {
    let ids = mesh.included();
    let boxes: Vec<Aabb> = ids
        .par_iter()
        .map(|&i| mesh.triangles[i as usize].bbox())
        .collect();
    let centroids = boxes.par_iter().map(Aabb::center).collect();
    let prims = Prims { boxes, centroids };
    if ids.is_empty() {
        return Bvh {
            root: leaf(Aabb::EMPTY, 0, 0),
            order: Vec::new(),
        };
    }
    let (root, local) = match opts.builder {
        Builder::Sweep => super::sweep::build(&prims, opts),
        Builder::Binned => super::binned::build(&prims, opts),
        Builder::Median => super::median::build(&prims, opts),
    };
    Bvh {
        root,
        order: local.par_iter().map(|&l| ids[l as usize]).collect(),
    }
}
