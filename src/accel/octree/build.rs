//! The top-down octree build. A cell with more than `leaf_size` triangles, above the depth
//! cap, has its triangles binned into its eight children as a 2×2×2 grid (the grids'
//! binning: an exact triangle–box test on each child grown by the grids' margin); when the
//! split is expected to save work ([`OctreeOptions`]) every non-empty child is built in
//! turn, big cells' children in parallel, else the cell is a leaf.
//!
//! Each subtree is built into its own arrays, indices relative to them; a parent places its
//! children's roots side by side and appends their arrays, shifted.
//!
//! Memory: the triangles, one reference each and the root's list are reserved up front;
//! then each split reserves, before its children are built, [`BYTES_PER_REF`] for each
//! reference it adds and [`BYTES_PER_NODE`] for each child, so a tree that would not fit
//! ends in an error naming its size and the limit.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::{Cube, Node, Octree, OctreeOptions, OctreeStats, MAX_OCTREE_DEPTH};
use crate::accel::grid::binning::for_each_cell;
use crate::accel::grid::budget::{Budget, MAX_REFS};
use crate::accel::grid::frame::Frame;
use crate::accel::grid::prims::Prims;
use crate::error::Result;

/// Build memory per added reference: its entry in a child's list, in a leaf, and its copy
/// while subtrees are assembled.
const BYTES_PER_REF: u64 = 12;

/// Build memory per node: the node and its copy while subtrees are assembled.
const BYTES_PER_NODE: u64 = 16;

/// Cells with at least this many triangles bin them and build their children in parallel.
const PARALLEL_MIN: usize = 2048;

/// Triangles per parallel binning task.
const CHUNK: usize = 1024;

/// Largest leaf a [`Node`] can hold (its count is shifted left by one).
const LEAF_MAX: u64 = (u32::MAX >> 1) as u64;

/// What to do instead, when the build is refused.
const HINT: &str = "lower OctreeOptions::max_depth or raise OctreeOptions::leaf_size, or use \
                    the BVH (its size is linear in the triangles)";

/// A built subtree: its root, and the nodes below it (the root's children first), indices
/// relative to these arrays.
struct Sub {
    root: Node,
    nodes: Vec<Node>,
    refs: Vec<u32>,
    max_depth: usize,
    largest_leaf: usize,
}

/// What every cell of one build shares.
struct Ctx<'a> {
    tris: &'a [[DVec3; 3]],
    cube: &'a Cube,
    cap: usize,
    leaf_size: usize,
    traversal_cost: f64,
    budget: Budget,
    /// An upper bound on the finished tree's references, and its nodes, so far.
    refs: AtomicU64,
    nodes: AtomicU64,
}

/// The low corner of child `c` of the cell at `lo` whose centre is `mid`.
#[inline]
pub(crate) fn child_lo(lo: DVec3, mid: DVec3, c: u32) -> DVec3 {
    let pick = |a: u32, l: f64, m: f64| if c >> a & 1 == 1 { m } else { l };
    DVec3::new(
        pick(0, lo.x, mid.x),
        pick(1, lo.y, mid.y),
        pick(2, lo.z, mid.z),
    )
}

/// A leaf of `ids` at `depth`.
fn leaf(ids: Vec<u32>, depth: usize) -> Sub {
    let n = ids.len();
    Sub {
        root: Node::leaf(0, n as u32),
        nodes: Vec::new(),
        refs: ids,
        max_depth: depth,
        largest_leaf: n,
    }
}

/// The subtree of a split cell: the children's roots side by side, then their arrays.
fn assemble(mask: u8, subs: Vec<Sub>) -> Sub {
    let below: usize = subs.iter().map(|s| s.nodes.len()).sum();
    let mut nodes = Vec::with_capacity(subs.len() + below);
    let mut refs = Vec::with_capacity(subs.iter().map(|s| s.refs.len()).sum());
    // Sizes were checked against u32 while building (`Ctx::account`).
    let (mut at, mut rat) = (subs.len() as u32, 0u32);
    for s in &subs {
        nodes.push(s.root.shifted(at, rat));
        at += s.nodes.len() as u32;
        rat += s.refs.len() as u32;
    }
    let (mut max_depth, mut largest_leaf) = (0, 0);
    for s in subs {
        let (at, rat) = (nodes.len() as u32, refs.len() as u32);
        nodes.extend(s.nodes.iter().map(|n| n.shifted(at, rat)));
        refs.extend_from_slice(&s.refs);
        max_depth = max_depth.max(s.max_depth);
        largest_leaf = largest_leaf.max(s.largest_leaf);
    }
    Sub {
        root: Node::inner(0, mask),
        nodes,
        refs,
        max_depth,
        largest_leaf,
    }
}

impl Ctx<'_> {
    /// The triangles `ids` that overlap each child of `frame` (a 2×2×2 grid), ascending.
    fn bin(&self, frame: &Frame, ids: &[u32]) -> [Vec<u32>; 8] {
        let one = |ids: &[u32]| {
            let mut lists: [Vec<u32>; 8] = Default::default();
            for &id in ids {
                for_each_cell(frame, &self.tris[id as usize], |c| {
                    lists[(c[0] | c[1] << 1 | c[2] << 2) as usize].push(id)
                });
            }
            lists
        };
        if ids.len() < PARALLEL_MIN {
            return one(ids);
        }
        let parts: Vec<[Vec<u32>; 8]> = ids.par_chunks(CHUNK).map(one).collect();
        std::array::from_fn(|c| parts.iter().flat_map(|p| p[c].iter().copied()).collect())
    }

    /// Counts a split that adds `added` references and `kids` nodes, and reserves their
    /// memory; refuses when the budget or the u32 indices would be passed.
    fn account(&self, added: u64, kids: u64) -> Result<()> {
        let refs = self.refs.fetch_add(added, Ordering::Relaxed) + added;
        let nodes = self.nodes.fetch_add(kids, Ordering::Relaxed) + kids;
        if refs > MAX_REFS || nodes > u32::MAX as u64 {
            return Err(self.budget.too_many_refs(refs));
        }
        self.budget
            .reserve(added as u128 * BYTES_PER_REF as u128 + kids as u128 * BYTES_PER_NODE as u128)
    }

    /// The subtree of the cell at `lo`, at `depth`, holding triangles `ids`.
    fn node(&self, lo: DVec3, depth: usize, ids: Vec<u32>) -> Result<Sub> {
        let n = ids.len();
        if n <= self.leaf_size || depth >= self.cap {
            return Ok(leaf(ids, depth));
        }
        let half = self.cube.size[depth + 1];
        let frame = Frame::from_parts(
            lo,
            DVec3::splat(half),
            DVec3::splat(1.0 / half),
            [2; 3],
            self.cube.margin,
        );
        let lists = self.bin(&frame, &ids);
        let total: usize = lists.iter().map(Vec::len).sum();
        // A child cube has a quarter of its parent's surface area.
        if self.traversal_cost + total as f64 / 4.0 >= n as f64 {
            return Ok(leaf(ids, depth));
        }
        drop(ids);
        let mask = (0..8).fold(0u8, |m, c| m | ((!lists[c].is_empty() as u8) << c));
        self.account(total.saturating_sub(n) as u64, mask.count_ones() as u64)?;
        // The centre as the traversal computes it: the low corner plus half the side.
        let mid = lo + DVec3::splat(half);
        let jobs: Vec<(DVec3, Vec<u32>)> = lists
            .into_iter()
            .enumerate()
            .filter(|(_, l)| !l.is_empty())
            .map(|(c, l)| (child_lo(lo, mid, c as u32), l))
            .collect();
        let build = |(clo, l): (DVec3, Vec<u32>)| self.node(clo, depth + 1, l);
        let subs: Vec<Sub> = if n >= PARALLEL_MIN {
            jobs.into_par_iter().map(build).collect::<Result<_>>()?
        } else {
            jobs.into_iter().map(build).collect::<Result<_>>()?
        };
        Ok(assemble(mask, subs))
    }
}

/// Builds the octree over `prims` (see [`Octree::build`]).
pub(super) fn build(prims: Prims, opts: &OctreeOptions) -> Result<Octree> {
    let n = prims.len();
    let cap = opts.max_depth.min(MAX_OCTREE_DEPTH);
    let empty = |prims: Prims| Octree {
        prims,
        cube: None,
        nodes: vec![Node::leaf(0, 0)],
        refs: Vec::new(),
        stats: OctreeStats {
            depth_cap: cap,
            nodes: 1,
            leaves: 1,
            ..OctreeStats::default()
        },
    };
    let Some((lo, hi, margin)) = prims.grid_box() else {
        return Ok(empty(prims));
    };
    // A cube on the grids' box (the bounds grown by twice the margin), from its low corner.
    let mut size = [(hi - lo).max_element(); MAX_OCTREE_DEPTH + 2];
    for d in 1..size.len() {
        size[d] = size[d - 1] * 0.5;
    }
    let cube = Cube { lo, size, margin };
    let budget = Budget::with_knobs(
        format!(
            "an octree over {n} triangles (depth cap {cap}, leaf size {})",
            opts.leaf_size
        ),
        opts.max_bytes,
        "OctreeOptions::max_bytes",
        HINT,
    );
    // Up front: the triangles (f32 and the f64 copy binning reads), the root's list, one
    // reference per triangle and the root.
    budget.reserve(prims.bytes() as u128 + n as u128 * (72 + 4 + BYTES_PER_REF as u128) + 8)?;
    if n as u64 > LEAF_MAX {
        return Err(budget.too_many_refs(n as u64));
    }
    let tris = prims.to_f64();
    let ctx = Ctx {
        tris: &tris,
        cube: &cube,
        cap,
        leaf_size: opts.leaf_size.max(1),
        traversal_cost: opts.traversal_cost as f64,
        budget,
        refs: AtomicU64::new(n as u64),
        nodes: AtomicU64::new(1),
    };
    let sub = ctx.node(lo, 0, (0..n as u32).collect())?;
    drop(tris);
    let mut nodes = Vec::with_capacity(1 + sub.nodes.len());
    nodes.push(sub.root.shifted(1, 0));
    nodes.extend(sub.nodes.iter().map(|x| x.shifted(1, 0)));
    let refs = sub.refs;
    let leaves = nodes.iter().filter(|x| x.is_leaf()).count();
    let stats = OctreeStats {
        triangles: n,
        nodes: nodes.len(),
        leaves,
        max_depth: sub.max_depth,
        depth_cap: cap,
        largest_leaf: sub.largest_leaf,
        references: refs.len(),
        duplicated_references: refs.len().saturating_sub(n),
        bytes: prims.bytes() as usize + nodes.len() * 8 + refs.len() * 4,
    };
    Ok(Octree {
        prims,
        cube: Some(cube),
        nodes,
        refs,
        stats,
    })
}
