//! The two-level grid of Kalojanov, Billeter & Slusallek ("Two-Level Grids for Ray
//! Tracing on GPUs", Eurographics 2011): a coarse top grid (density
//! [`GridOptions::top_density`]) whose every non-empty cell holds its own regular sub-grid,
//! sized by the density heuristic on the triangles overlapping that cell
//! ([`GridOptions::sub_density`]). Dense geometry gets fine cells and empty space coarse ones.
//! Traversal walks the top grid and, in each non-empty top cell, the cell's sub-grid over the
//! same stretch of the ray.

use glam::DVec3;
use rayon::prelude::*;

use super::binning::{Counter, Filled};
use super::budget::{Budget, MAX_REFS};
use super::dda::DdaRay;
use super::frame::{resolution, Frame};
use super::prims::Prims;
use super::ray_walk::RayWalk;
use super::{GridOptions, GridStats};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::error::{Error, Result};
use crate::geometry::{Aabb, Hit, Ray, Robustness, TriangleTest};
use crate::mesh::Mesh;

/// Most sub-grid cells along one axis.
const MAX_SUB_RES: u32 = 1024;

/// A top cell: where its sub-grid's cell offsets start in `sub_start`, its sub-grid's cell
/// size in `sizes`, and its resolution (zero for an empty top cell).
#[derive(Clone, Copy, Debug, Default)]
struct TopCell {
    first: u32,
    size: u32,
    res: [u16; 3],
}

/// A sub-grid's cell size and its reciprocal, as the build computed them (so the walk needs
/// no division and sees exactly the build's cells).
#[derive(Clone, Copy, Debug)]
struct CellSize {
    cs: DVec3,
    inv_cs: DVec3,
}

/// A two-level grid over a mesh's included triangles.
#[derive(Clone, Debug)]
pub struct TwoLevelGrid {
    prims: Prims,
    /// The top grid; None when there are no triangles.
    top: Option<Frame>,
    cells: Vec<TopCell>,
    sizes: Vec<CellSize>,
    /// Sub-grid cell j of top cell c holds `refs[sub_start[first + j]..sub_start[first + j + 1]]`.
    sub_start: Vec<u32>,
    refs: Vec<u32>,
}

impl TwoLevelGrid {
    /// Builds the grid, refusing one whose cells and references would not fit in memory (or
    /// in `max_bytes`).
    pub fn build(mesh: &Mesh, opts: &GridOptions) -> Result<TwoLevelGrid> {
        let prims = Prims::new(mesh);
        let Some((lo, hi, margin)) = prims.grid_box() else {
            return Ok(TwoLevelGrid {
                prims,
                top: None,
                cells: Vec::new(),
                sizes: Vec::new(),
                sub_start: Vec::new(),
                refs: Vec::new(),
            });
        };
        let max_res = opts.max_resolution.min(1 << 21);
        let res = resolution(
            hi - lo,
            prims.len(),
            opts.top_density as f64,
            max_res,
            opts.max_cells,
        );
        let top = Frame::new(lo, hi, res, margin);
        let what = format!(
            "a two-level grid of {}×{}×{} top cells over {} triangles",
            res[0],
            res[1],
            res[2],
            prims.len()
        );
        let budget = Budget::new(what.clone(), opts.max_bytes);
        let refuse = |counter: &Counter, fixed: u128, per: u64| {
            if budget.left() / per < MAX_REFS {
                budget.too_big(fixed + counter.total() as u128 * per as u128)
            } else {
                budget.too_many_refs(counter.total())
            }
        };
        let tris = prims.to_f64();
        let ids: Vec<u32> = (0..prims.len() as u32).collect();
        let ncells = top.cells();
        let fixed = prims.bytes() as u128 * 3 + Filled::dense_bytes(ncells, 0) + ncells as u128 * 8;
        budget.reserve(fixed)?;

        // The top level.
        let counter = Counter::new((budget.left() / 12).min(MAX_REFS));
        let counts = if counter.quick(&top, &tris, &ids) {
            counter.count(&top, &tris, &ids)
        } else {
            Vec::new()
        };
        if counter.over() {
            return Err(refuse(&counter, fixed, 12));
        }
        budget.reserve(Filled::bytes(ids.len(), counter.total()) + counter.total() as u128 * 4)?;
        let (top_start, top_refs) =
            Filled::new(&top, &tris, &ids, &counts).dense(&ids, ncells as usize);

        // Each non-empty top cell's sub-grid: sized, counted against one cap, then filled.
        let occupied: Vec<(usize, Frame)> = (0..ncells as usize)
            .filter(|&c| top_start[c + 1] > top_start[c])
            .map(|c| {
                let n = (top_start[c + 1] - top_start[c]) as usize;
                let cell = [
                    (c % res[0] as usize) as u32,
                    ((c / res[0] as usize) % res[1] as usize) as u32,
                    (c / (res[0] as usize * res[1] as usize)) as u32,
                ];
                let (clo, chi) = top.cell_box(cell);
                let sub_res = resolution(
                    chi - clo,
                    n,
                    opts.sub_density as f64,
                    max_res.min(MAX_SUB_RES),
                    opts.max_cells,
                );
                (c, Frame::new(clo, chi, sub_res, margin))
            })
            .collect();
        let sub_cells: u64 = occupied.iter().map(|(_, f)| f.cells()).sum();
        if sub_cells + occupied.len() as u64 > u32::MAX as u64 {
            return Err(Error::Usage(format!(
                "{what} needs {sub_cells} sub-grid cells, over the limit of {} (u32 offsets): \
                 lower GridOptions::sub_density or max_cells",
                u32::MAX
            )));
        }
        budget.reserve(Filled::dense_bytes(sub_cells, 0) * 2)?;
        let list = |c: usize| &top_refs[top_start[c] as usize..top_start[c + 1] as usize];
        let fixed = fixed + Filled::dense_bytes(sub_cells, 0) * 2;
        let counter = Counter::new((budget.left() / 16).min(MAX_REFS));
        let counts: Vec<Vec<u32>> = occupied
            .par_iter()
            .map(|(c, f)| counter.count(f, &tris, list(*c)))
            .collect();
        if counter.over() {
            return Err(refuse(&counter, fixed, 16));
        }
        budget.reserve(Filled::bytes(ids.len(), counter.total()) + counter.total() as u128 * 8)?;
        let subs: Vec<(Vec<u32>, Vec<u32>)> = occupied
            .par_iter()
            .zip(&counts)
            .map(|((c, f), counts)| {
                Filled::new(f, &tris, list(*c), counts).dense(list(*c), f.cells() as usize)
            })
            .collect();
        drop(tris);

        // Concatenated: one offset array and one reference array.
        let mut cells = vec![TopCell::default(); ncells as usize];
        let mut sizes = Vec::with_capacity(occupied.len());
        let mut sub_start = Vec::with_capacity(sub_cells as usize + occupied.len());
        let mut refs = Vec::with_capacity(subs.iter().map(|s| s.1.len()).sum());
        for ((c, f), (start, r)) in occupied.iter().zip(subs) {
            cells[*c] = TopCell {
                first: sub_start.len() as u32,
                size: sizes.len() as u32,
                res: f.res.map(|x| x as u16),
            };
            sizes.push(CellSize {
                cs: f.cs,
                inv_cs: f.inv_cs,
            });
            let base = refs.len() as u32;
            sub_start.extend(start.iter().map(|&s| s + base));
            refs.extend_from_slice(&r);
        }
        Ok(TwoLevelGrid {
            prims,
            top: Some(top),
            cells,
            sizes,
            sub_start,
            refs,
        })
    }

    /// Top-grid cells along each axis ([1, 1, 1] for an empty mesh).
    pub fn resolution(&self) -> [u32; 3] {
        self.top.map_or([1; 3], |f| f.res)
    }

    /// The box the top cells divide (the triangles' bounds grown by a small margin), in f32.
    pub fn grid_box(&self) -> Aabb {
        self.top.map_or(Aabb::EMPTY, |f| Aabb {
            lo: f.lo.as_vec3(),
            hi: f.hi.as_vec3(),
        })
    }

    /// The top grid's cell face `k` (0..=resolution) along axis `a`, rounded to f32.
    pub fn boundary(&self, a: usize, k: u32) -> f32 {
        self.top.map_or(0.0, |f| f.plane(a, k) as f32)
    }

    /// Cells (top and sub-grid), references (in sub-grid cells) and memory.
    pub fn stats(&self) -> GridStats {
        let top_cells = self.top.map_or(0, |f| f.cells());
        let sub_cells: u64 = self
            .cells
            .iter()
            .map(|c| c.res.iter().map(|&r| r as u64).product::<u64>())
            .sum();
        let mut non_empty = 0u64;
        for c in self.cells.iter().filter(|c| c.res[0] > 0) {
            let n = c.res.iter().map(|&r| r as usize).product::<usize>();
            let s = &self.sub_start[c.first as usize..c.first as usize + n + 1];
            non_empty += s.windows(2).filter(|w| w[1] > w[0]).count() as u64;
        }
        let references = self.refs.len() as u64;
        let triangles = self.prims.len() as u64;
        GridStats {
            resolution: self.resolution(),
            cells: top_cells + sub_cells,
            non_empty_cells: non_empty,
            triangles,
            references,
            duplicated: references.saturating_sub(triangles),
            bytes: self.prims.bytes()
                + (self.cells.len() * std::mem::size_of::<TopCell>()) as u64
                + (self.sizes.len() * std::mem::size_of::<CellSize>()) as u64
                + (self.sub_start.len() + self.refs.len()) as u64 * 4,
        }
    }

    #[inline(always)]
    fn walk<const MT: bool>(
        &self,
        ray: &Ray,
        query: Query,
        reject_near: bool,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let (Some(top), true) = (&self.top, ray.is_valid()) else {
            return Hit::miss(ray.tmax);
        };
        let dray = DdaRay::new(ray);
        let Some((t0, t1)) = dray.clip(top, ray.tmin, ray.tmax) else {
            return Hit::miss(ray.tmax);
        };
        let mut st = RayWalk::<MT>::new(ray, query, reject_near, mask, stats);
        dray.walk(top, t0, t1, |cell, enter, exit| {
            st.stats.nodes += 1;
            let tc = self.cells[top.linear(cell) as usize];
            if tc.res[0] == 0 {
                return st.done(exit);
            }
            let lo = DVec3::new(
                top.plane(0, cell[0]),
                top.plane(1, cell[1]),
                top.plane(2, cell[2]),
            );
            let size = &self.sizes[tc.size as usize];
            let sub = Frame::from_parts(lo, size.cs, size.inv_cs, tc.res.map(|r| r as u32), 0.0);
            let first = tc.first as usize;
            let stopped = dray.walk(&sub, enter, exit, |sc, _, sub_exit| {
                st.stats.nodes += 1;
                let j = first + sub.linear(sc) as usize;
                let refs = &self.refs[self.sub_start[j] as usize..self.sub_start[j + 1] as usize];
                st.test(&self.prims, refs) || st.done(sub_exit)
            });
            stopped || st.done(exit)
        });
        st.best
    }
}

impl Accel for TwoLevelGrid {
    fn bounds(&self) -> Aabb {
        self.prims.bounds
    }

    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let near = robustness.rejects_near_hits_of(ray);
        match robustness.triangle_test {
            TriangleTest::Watertight => self.walk::<false>(ray, query, near, mask, stats),
            TriangleTest::MollerTrumbore => self.walk::<true>(ray, query, near, mask, stats),
        }
    }
}
