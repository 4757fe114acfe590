//! Build options: which builder, the SAH constants, leaf and depth limits.

use super::tree::MAX_DEPTH;

/// Which algorithm builds the BVH.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Builder {
    /// Full sweep SAH over every centroid on all three axes (centroids sorted once per axis).
    #[default]
    Sweep,
    /// Binned SAH with `bins` bins per axis.
    Binned,
    /// Object median on the longest centroid axis.
    Median,
    /// Spatial splits (SBVH, Stich et al. 2009): the sweep's object splits, or planes that
    /// cut the triangles straddling them, each side bounding its part; a triangle may be in
    /// several leaves.
    Sbvh,
    /// PLOC: parallel locally-ordered clustering along a Morton curve (Meister & Bittner
    /// 2018), leaves where the SAH prefers them.
    Ploc,
    /// LBVH: a radix tree over a 30-bit Morton curve (Karras 2012), leaves where the SAH
    /// prefers them. The same algorithm builds on the GPU (`gpu::build_lbvh`), equal to this.
    Lbvh,
}

impl Builder {
    /// Every builder, in the order reports list them.
    pub const ALL: [Builder; 6] = [
        Builder::Sweep,
        Builder::Binned,
        Builder::Median,
        Builder::Sbvh,
        Builder::Ploc,
        Builder::Lbvh,
    ];

    /// The name the command line, the JSON and the benches use.
    pub fn name(self) -> &'static str {
        match self {
            Builder::Sweep => "sweep",
            Builder::Binned => "binned",
            Builder::Median => "median",
            Builder::Sbvh => "sbvh",
            Builder::Ploc => "ploc",
            Builder::Lbvh => "lbvh",
        }
    }
}

/// The sweep builder's default [`BuildOptions::exact_below`]: the SAH within 0.5 % of the
/// full sweep's on the models measured, at about twice its speed on a million triangles.
pub const EXACT_BELOW: usize = 1024;

/// How to build a BVH: the builder, the SAH cost constants, leaf and depth limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// The build algorithm.
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
    /// Sweep builder: nodes of more primitives than this pick their split with 64 bins per
    /// axis; smaller ones are swept exactly. `usize::MAX`: every node swept (the seed's build).
    pub exact_below: usize,
    /// After any builder, optimise the tree by reinsertion (Bittner et al. 2013): subtrees
    /// moved to where they cost least; the SAH never rises.
    pub optimize: bool,
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
            exact_below: EXACT_BELOW,
            optimize: false,
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

    /// Whether a leaf beats every split of a node of n primitives and surface area `area`
    /// whose primitives' boxes have areas summing to `boxes_area`: each side's box holds
    /// each of its primitives' boxes, so A_L·N_L + A_R·N_R is at least that sum and any
    /// split costs at least 2·T_cube + sum/A·T_obj. The margin covers the rounding of the
    /// sum and of the splits' costs (a few ulps; a computed area never shrinks as a box
    /// grows, rounding being monotone), so where this holds the splits evaluated would make
    /// the node the same leaf.
    pub(crate) fn leaf_beats_splits_over(&self, n: usize, boxes_area: f32, area: f32) -> bool {
        const MARGIN: f32 = 1.0 - 1e-4;
        let bound = 2.0 * self.t_cube + boxes_area / area * self.t_obj;
        n <= self.max_leaf.max(1)
            && area > 0.0
            && self.t_obj > 0.0
            && self.t_cube >= 0.0
            && n as f32 * self.t_obj <= bound * MARGIN
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
