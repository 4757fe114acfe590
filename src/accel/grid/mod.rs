//! Grids on the CPU: a [`UniformGrid`], a [`TwoLevelGrid`] (Kalojanov, Billeter & Slusallek
//! 2011) and a [`HashedGrid`] (a fine grid that stores only its non-empty cells).
//!
//! All three reference each triangle in every cell it overlaps (an exact triangle–box test,
//! Akenine-Möller 2001, on cells grown by a small margin so that the f32 triangle test's
//! rounding near a cell face cannot lose a hit) and walk the cells a ray crosses with a 3D-DDA
//! (Amanatides & Woo 1987) in f64, the cell faces' t computed from the face planes, never
//! accumulated. A per-ray mailbox skips triangles just tested in an earlier cell. The tie rule
//! is the BVH's: the walk ends after a cell only once the best hit's t, plus its error bound
//! and [`prune_bound`](crate::geometry::prune_bound)'s slack, lies before the cell's exit, so a
//! triangle at exactly the best t in a later cell is still tested and equal t goes to the
//! smaller original index.
//!
//! Builds refuse, with an error naming the size and the limit, a structure whose references
//! would not fit in [`GridOptions::max_bytes`] or the memory available: references are counted
//! (a conservative count, stopped as soon as it passes the limit) before anything is allocated.

// Shared with the octree (a hierarchy of 2×2×2 grids): binning, budget, margins, the
// triangles' local order and the per-ray walk state.
pub(crate) mod binning;
pub(crate) mod budget;
mod dda;
pub(crate) mod frame;
mod hashed;
mod overlap;
pub(crate) mod prims;
pub(crate) mod ray_walk;
mod two_level;
mod uniform;

pub use hashed::HashedGrid;
pub use two_level::TwoLevelGrid;
pub use uniform::UniformGrid;

/// Build settings of the three grids. Each grid reads its own fields; the caps apply to all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridOptions {
    /// [`UniformGrid`]: cells per triangle (λ of the density heuristic: about λ·N cells, as
    /// near to cubes as the box allows). Default 3.
    pub density: f32,
    /// [`TwoLevelGrid`]: top-level cells per triangle. Default 1/16.
    pub top_density: f32,
    /// [`TwoLevelGrid`]: cells per triangle of each top cell's sub-grid (counting the
    /// triangles that overlap that cell). Default 4.
    pub sub_density: f32,
    /// [`HashedGrid`]: cells per triangle of its (virtual) fine grid. Default 8.
    pub hashed_density: f32,
    /// Most cells of one dense cell array: the uniform grid, the two-level grid's top grid
    /// and each of its sub-grids. Default 2²⁴.
    pub max_cells: u64,
    /// Most cells along one axis of any grid (the hashed grid's virtual grid included; at
    /// most 2²¹). Default 4096.
    pub max_resolution: u32,
    /// Memory the build may use (the structure and its temporaries), besides the memory
    /// available on the machine. Default `None`: only the machine's limit.
    pub max_bytes: Option<u64>,
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            density: 3.0,
            top_density: 1.0 / 16.0,
            sub_density: 4.0,
            hashed_density: 8.0,
            max_cells: 1 << 24,
            max_resolution: 4096,
            max_bytes: None,
        }
    }
}

/// What a grid holds, for reports and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GridStats {
    /// Cells along each axis: the grid's, the top grid's for a [`TwoLevelGrid`], the virtual
    /// grid's for a [`HashedGrid`].
    pub resolution: [u32; 3],
    /// All cells: for a [`TwoLevelGrid`] top cells plus sub-grid cells; for a [`HashedGrid`]
    /// the cells of its virtual grid (only the non-empty ones are stored).
    pub cells: u64,
    /// Cells holding at least one triangle reference (for a [`TwoLevelGrid`], sub-grid cells).
    pub non_empty_cells: u64,
    /// Triangles in the grid (the mesh's included triangles).
    pub triangles: u64,
    /// Triangle references in the leaf cells.
    pub references: u64,
    /// References beyond the first of each triangle: `references − triangles`.
    pub duplicated: u64,
    /// Memory held by the structure (cells, references, triangles), in bytes.
    pub bytes: u64,
}
