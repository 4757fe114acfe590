//! The geometry of one regular grid, in f64: its box, its resolution (the density
//! heuristic), its cell planes and the margin cells are grown by when triangles are binned.
//! Binning and traversal compute a cell face with the same expression, [`Frame::plane`].

use glam::DVec3;

/// Relative margin, in cell sizes, by which cells are grown when triangles are binned.
const MARGIN_REL: f64 = 1.0 / 1024.0;

/// Absolute margin, relative to the whole scene's diagonal: it covers the f32 triangle
/// test's rounding (a few ulps of the distance to the ray origin) for origins up to tens of
/// scene diagonals away.
pub(crate) const MARGIN_SCENE: f64 = 1.0 / 65536.0;

/// One regular grid: `res` cells along each axis from `lo`, each `cs` wide.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    /// Low corner.
    pub lo: DVec3,
    /// High corner: exactly `plane(a, res[a])` on each axis.
    pub hi: DVec3,
    /// Cell size.
    pub cs: DVec3,
    /// 1 / cell size.
    pub inv_cs: DVec3,
    /// Cells along each axis (≥ 1).
    pub res: [u32; 3],
    /// How far cells are grown when triangles are binned into them.
    pub margin: DVec3,
    /// `lo` and `cs` as arrays: indexed by a run-time axis in the walk's hot loop, where a
    /// vector's `match` on the index would be a branch.
    lo_a: [f64; 3],
    cs_a: [f64; 3],
    inv_cs_a: [f64; 3],
}

/// ⌊x⌋ as an integer, saturating, NaN → 0, without a call to libm's `floor` (no SSE4.1
/// `roundsd` in the baseline x86-64 target).
#[inline(always)]
fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - ((i as f64) > x) as i64
}

impl Frame {
    /// The grid of `res` cells over [lo, hi]; `scene_margin` is the absolute part of the
    /// binning margin.
    pub fn new(lo: DVec3, hi: DVec3, res: [u32; 3], scene_margin: f64) -> Frame {
        let r = DVec3::new(res[0] as f64, res[1] as f64, res[2] as f64);
        let cs = (hi - lo) / r;
        Frame::from_parts(lo, cs, DVec3::ONE / cs, res, scene_margin)
    }

    /// The grid of `res` cells of size `cs` (1/cs = `inv_cs`) from `lo`: [`new`](Self::new)
    /// without its divisions, for a cell size computed once and stored.
    #[inline(always)]
    pub fn from_parts(
        lo: DVec3,
        cs: DVec3,
        inv_cs: DVec3,
        res: [u32; 3],
        scene_margin: f64,
    ) -> Frame {
        let mut f = Frame {
            lo,
            hi: lo,
            cs,
            inv_cs,
            res,
            margin: (cs * MARGIN_REL).max(DVec3::splat(scene_margin)),
            lo_a: lo.to_array(),
            cs_a: cs.to_array(),
            inv_cs_a: inv_cs.to_array(),
        };
        f.hi = DVec3::new(f.plane(0, res[0]), f.plane(1, res[1]), f.plane(2, res[2]));
        f
    }

    /// The face plane `k` (0..=res) along axis `a`.
    #[inline(always)]
    pub fn plane(&self, a: usize, k: u32) -> f64 {
        self.lo_a[a] + k as f64 * self.cs_a[a]
    }

    /// Number of cells.
    pub fn cells(&self) -> u64 {
        self.res.iter().map(|&r| r as u64).product()
    }

    /// Linear index of cell `c` (x fastest).
    #[inline(always)]
    pub fn linear(&self, c: [u32; 3]) -> u64 {
        c[0] as u64 + self.res[0] as u64 * (c[1] as u64 + self.res[1] as u64 * c[2] as u64)
    }

    /// The corners of cell `c`.
    pub fn cell_box(&self, c: [u32; 3]) -> (DVec3, DVec3) {
        let lo = DVec3::new(
            self.plane(0, c[0]),
            self.plane(1, c[1]),
            self.plane(2, c[2]),
        );
        let hi = DVec3::new(
            self.plane(0, c[0] + 1),
            self.plane(1, c[1] + 1),
            self.plane(2, c[2] + 1),
        );
        (lo, hi)
    }

    /// The cell along axis `a` that holds coordinate `x`, clamped into the grid (a NaN gives
    /// cell 0).
    #[inline]
    pub fn index(&self, a: usize, x: f64) -> u32 {
        let i = floor_i64((x - self.lo_a[a]) * self.inv_cs_a[a]);
        i.clamp(0, self.res[a] as i64 - 1) as u32
    }

    /// The cell along axis `a` that holds coordinate `x`, the lower one when `x` lies on a
    /// face (for rays heading down the axis); clamped into the grid.
    #[inline]
    pub fn index_below(&self, a: usize, x: f64) -> u32 {
        // ⌈y⌉ − 1 = −⌊−y⌋ − 1.
        let i = -floor_i64(-(x - self.lo_a[a]) * self.inv_cs_a[a]) - 1;
        i.clamp(0, self.res[a] as i64 - 1) as u32
    }
}

/// The density heuristic: cells along each axis proportional to the box's extent, about
/// `density · n` cells in all, at most `max_res` along an axis and `max_cells` in all. Axes
/// too thin for one cell get one, and the others share the cell count among themselves.
pub(crate) fn resolution(
    extent: DVec3,
    n: usize,
    density: f64,
    max_res: u32,
    max_cells: u64,
) -> [u32; 3] {
    let max_res = max_res.max(1);
    let want = (density * n as f64).max(1.0);
    let mut free = [true; 3];
    let mut res = [1u32; 3];
    // Up to three rounds: each may retire an axis that gets less than one cell.
    for _ in 0..3 {
        let dims = free.iter().filter(|&&f| f).count();
        if dims == 0 {
            break;
        }
        let vol: f64 = (0..3).filter(|&a| free[a]).map(|a| extent[a]).product();
        let k = (want / vol).powf(1.0 / dims as f64);
        let mut retired = false;
        for a in 0..3 {
            if free[a] {
                let r = extent[a] * k;
                if r.is_nan() || r < 1.0 {
                    free[a] = false;
                    res[a] = 1;
                    retired = true;
                } else {
                    res[a] = r.round().min(max_res as f64) as u32;
                }
            }
        }
        if !retired {
            break;
        }
    }
    // The cell cap: shrink every axis until the product fits.
    let mut total: u64 = res.iter().map(|&r| r as u64).product();
    while total > max_cells.max(1) {
        let s = (max_cells.max(1) as f64 / total as f64).cbrt() * 0.999;
        for r in &mut res {
            *r = ((*r as f64 * s).floor() as u32).max(1);
        }
        total = res.iter().map(|&r| r as u64).product();
    }
    res
}
