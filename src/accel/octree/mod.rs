//! An octree over a mesh's triangles: a cube around the mesh, split at its centre into eight
//! children, recursively, until a cell holds few triangles, a split is not expected to save
//! work ([`OctreeOptions`]) or the depth cap is reached.
//!
//! An octree is a hierarchy of 2×2×2 grids, and it is built and walked with the grids'
//! pieces: each triangle is referenced in every child cell it overlaps (the grids' binning,
//! an exact triangle–box test on cells grown by the grids' margin, so the f32 triangle test's
//! rounding near a cell face cannot lose a hit), triangles are held in the grids' Morton
//! order, and a ray keeps the grids' walk state (the mailbox, which skips a triangle just
//! tested in an earlier cell, and the tie rule). Empty children are not stored: a parent
//! keeps an 8-bit mask of its non-empty children, which lie next to each other.
//!
//! - `build.rs`: the top-down build, its memory budget and the assembly of the node array.
//! - `traverse.rs`: the [`Accel`](crate::accel::Accel) implementation: a front-to-back
//!   stack traversal of (node, t-interval) entries.

mod build;
mod traverse;

use glam::DVec3;

use super::grid::prims::Prims;
use crate::error::Result;
use crate::geometry::Aabb;
use crate::mesh::Mesh;

/// Deepest level any octree may have. Cells are grown by the grids' scene margin, 2⁻¹⁶ of
/// the mesh's diagonal, when triangles are binned: at depth 16 a cell (2⁻¹⁶ of the cube's
/// side, at least 0.58 margins) is smaller than the margin it is grown by, so a deeper
/// split only copies its references into every child. The traversal's stack holds
/// 3·16 entries.
pub const MAX_OCTREE_DEPTH: usize = 16;

/// How to build an [`Octree`]: when a cell stops being split, and the memory cap.
///
/// A cell is split when it holds more than `leaf_size` triangles, lies above the depth cap,
/// and the split is expected to save work: a ray through the cell crosses each child cube
/// with probability 1/4 (its surface area over the parent's), so the split costs
/// `traversal_cost + Σ n_child / 4` triangle tests against `n` for a leaf. The test stops the
/// splitting where more cells would only copy references — the line where two triangles
/// cross, a vertex where several meet — which leaf size and depth alone cannot tell from a
/// cell that holds many small triangles.
///
/// Defaults: `max_depth = 14`, `leaf_size = 4`, `traversal_cost = 4`, measured on the bunny
/// (69,451 triangles; one thread timed by its own CPU time, best of 3, on a shared machine
/// where speeds vary by about 10 %; `tests/octree.rs`, `bunny_depth_leaf_and_cost`):
///
/// | depth cap : leaf : cost | refs | MiB | build | primary 512² Mrays/s, cells, tris | random 2¹⁸ |
/// |---|---|---|---|---|---|
/// | 14 : 4 : 1 | 1.64 M | 15.4 | 5.0 s | 2.15, 8.6, 2.2 | 0.37, 17.1, 4.5 |
/// | 14 : 4 : 2 | 0.81 M | 8.6 | 2.8 s | 2.15, 8.4, 2.5 | 0.40, 16.6, 5.3 |
/// | **14 : 4 : 4** | 0.35 M | 4.7 | 1.6 s | 2.14, 7.8, 4.1 | 0.39, 15.4, 8.6 |
/// | 14 : 4 : 8 | 0.25 M | 3.9 | 1.2 s | 1.86, 7.3, 7.9 | 0.37, 14.3, 17.0 |
/// | 14 : 8 : 4 | 0.34 M | 4.6 | 0.9 s | 1.96, 7.7, 5.1 | 0.37, 15.2, 10.5 |
/// | 14 : 16 : 4 | 0.24 M | 3.9 | 0.7 s | 1.59, 7.2, 9.4 | 0.36, 14.1, 20.6 |
/// | 8 : 4 : 4 | 0.35 M | 4.7 | 1.5 s | 2.21, 7.8, 4.1 | 0.42, 15.4, 8.6 |
/// | (BVH, kd-tree) | | | 0.5 s, 3.5 s | 5.22, 3.41 | 0.95, 0.54 |
///
/// The traversal is memory-bound (perf: the loads of nodes and references take a third of
/// its time): a cost of 4 traces as fast as 1
/// or 2 with a quarter to half the references and a third to half the build time, while 8
/// tests twice the triangles and is slower. At cost 4 a cell of 4 triangles is never split
/// (`4 + Σ/4 ≥ 4`), so leaf sizes up to 4 build the same tree; 8 and 16 test more triangles
/// and are slower. The split test ends the bunny's tree at depth 12, most of it by depth 8
/// (caps 8 to 14 give the same references and work per ray); 14 leaves two levels for
/// meshes some 16 times larger (four times the triangles on a surface take one level
/// more). Set `traversal_cost` to `f32::NEG_INFINITY` to split every cell above the leaf
/// size and the depth cap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctreeOptions {
    /// Deepest cell (the root cube is at depth 0), at most [`MAX_OCTREE_DEPTH`].
    pub max_depth: usize,
    /// A cell with at most this many triangles is a leaf.
    pub leaf_size: usize,
    /// The cost of visiting a cell, in triangle tests, in the split test.
    pub traversal_cost: f32,
    /// Memory the build may use (the tree and its temporaries), besides the memory available
    /// on the machine. `None`: only the machine's limit.
    pub max_bytes: Option<u64>,
}

impl Default for OctreeOptions {
    fn default() -> Self {
        OctreeOptions {
            max_depth: 14,
            leaf_size: 4,
            traversal_cost: 4.0,
            max_bytes: None,
        }
    }
}

/// Size and shape of a built [`Octree`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OctreeStats {
    /// Triangles in the tree (the mesh's included ones).
    pub triangles: usize,
    /// Stored nodes, inner and leaves (empty cells are not stored).
    pub nodes: usize,
    /// Leaves (non-empty cells that are not split).
    pub leaves: usize,
    /// Depth of the deepest leaf (the root is at depth 0).
    pub max_depth: usize,
    /// The depth cap the tree was built under.
    pub depth_cap: usize,
    /// Triangles in the largest leaf.
    pub largest_leaf: usize,
    /// Triangle references held by the leaves.
    pub references: usize,
    /// References beyond one per triangle: a triangle is referenced by every leaf whose
    /// (grown) cell it overlaps.
    pub duplicated_references: usize,
    /// Memory of the built tree: nodes, references and triangles.
    pub bytes: usize,
}

/// A node: 8 bytes. Inner: (index of its first stored child, mask of its non-empty children
/// << 1); the children lie in ascending child order (bit 0: x, bit 1: y, bit 2: z, set for
/// the upper half). Leaf: (first reference, count << 1 | 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Node {
    a: u32,
    b: u32,
}

impl Node {
    pub(crate) fn leaf(first: u32, count: u32) -> Node {
        Node {
            a: first,
            b: (count << 1) | 1,
        }
    }
    pub(crate) fn inner(first_child: u32, mask: u8) -> Node {
        Node {
            a: first_child,
            b: (mask as u32) << 1,
        }
    }
    #[inline(always)]
    pub(crate) fn is_leaf(self) -> bool {
        self.b & 1 == 1
    }
    #[inline(always)]
    pub(crate) fn first(self) -> usize {
        self.a as usize
    }
    #[inline(always)]
    pub(crate) fn count(self) -> usize {
        (self.b >> 1) as usize
    }
    #[inline(always)]
    pub(crate) fn mask(self) -> u32 {
        self.b >> 1
    }
    /// The node index of child `c` (0..8), or None when that child is empty.
    #[inline(always)]
    pub(crate) fn child(self, c: u32) -> Option<usize> {
        let m = self.mask();
        (m >> c & 1 == 1).then(|| self.a as usize + (m & ((1 << c) - 1)).count_ones() as usize)
    }
    /// This node moved into a larger array: children `nodes` and references `refs` later.
    pub(crate) fn shifted(self, nodes: u32, refs: u32) -> Node {
        let by = if self.is_leaf() { refs } else { nodes };
        Node {
            a: self.a + by,
            b: self.b,
        }
    }
}

/// The root cube: its low corner and the cell size at each depth.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cube {
    pub(crate) lo: DVec3,
    /// `size[d]`: the side of a cell at depth d (the cube's side over 2^d, exact).
    pub(crate) size: [f64; MAX_OCTREE_DEPTH + 2],
    /// The grids' scene margin cells are grown by (the absolute part).
    pub(crate) margin: f64,
}

/// An octree over the included triangles of a mesh, traced on the CPU through
/// [`Accel`](crate::accel::Accel). Hits report original triangle indices.
#[derive(Clone, Debug)]
pub struct Octree {
    pub(crate) prims: Prims,
    /// None when there are no triangles.
    pub(crate) cube: Option<Cube>,
    /// The root is node 0.
    pub(crate) nodes: Vec<Node>,
    /// The leaves' references: local triangle indices, ascending within a leaf.
    pub(crate) refs: Vec<u32>,
    stats: OctreeStats,
}

impl Octree {
    /// Builds the octree over `mesh.included()` triangles. Refuses, with an error naming the
    /// size and the limit, a build whose memory estimate (up front, then as triangles that
    /// overlap several children add references) passes [`OctreeOptions::max_bytes`] or the
    /// memory available.
    pub fn build(mesh: &Mesh, opts: &OctreeOptions) -> Result<Octree> {
        build::build(Prims::new(mesh), opts)
    }

    /// Size and shape of the tree.
    pub fn stats(&self) -> OctreeStats {
        self.stats
    }

    /// The root cube the cells divide (the triangles' bounds grown by a small margin, made a
    /// cube), rounded outwards to f32; empty for an empty mesh.
    pub fn cube(&self) -> Aabb {
        self.cube.map_or(Aabb::EMPTY, |c| {
            let hi = c.lo + DVec3::splat(c.size[0]);
            Aabb {
                lo: c.lo.as_vec3(),
                hi: hi.as_vec3(),
            }
        })
    }

    /// Every inner node's three split planes as (axis 0 = x, 1 = y, 2 = z; position rounded
    /// to f32), depth-first.
    pub fn split_planes(&self) -> Vec<(usize, f32)> {
        let mut out = Vec::new();
        if let Some(cube) = &self.cube {
            self.planes_below(cube, 0, cube.lo, 0, &mut out);
        }
        out
    }

    fn planes_below(
        &self,
        cube: &Cube,
        idx: usize,
        lo: DVec3,
        depth: usize,
        out: &mut Vec<(usize, f32)>,
    ) {
        let node = self.nodes[idx];
        if node.is_leaf() {
            return;
        }
        let mid = lo + DVec3::splat(cube.size[depth + 1]);
        out.extend((0..3).map(|a| (a, mid[a] as f32)));
        for c in 0..8 {
            if let Some(child) = node.child(c) {
                let pick = |a: u32, l: f64, m: f64| if c >> a & 1 == 1 { m } else { l };
                let clo = DVec3::new(
                    pick(0, lo.x, mid.x),
                    pick(1, lo.y, mid.y),
                    pick(2, lo.z, mid.z),
                );
                self.planes_below(cube, child, clo, depth + 1, out);
            }
        }
    }
}
