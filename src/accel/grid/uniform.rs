//! The uniform grid: one regular grid over the mesh, about λ·N cells (the density
//! heuristic), each listing the triangles that overlap it.

use super::binning::{Counter, Filled};
use super::budget::{Budget, MAX_REFS};
use super::dda::DdaRay;
use super::frame::{resolution, Frame};
use super::prims::Prims;
use super::ray_walk::RayWalk;
use super::{GridOptions, GridStats};
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::error::Result;
use crate::geometry::{Aabb, Hit, Ray, Robustness, TriangleTest};
use crate::mesh::Mesh;

/// A uniform grid over a mesh's included triangles.
#[derive(Clone, Debug)]
pub struct UniformGrid {
    prims: Prims,
    /// None when there are no triangles.
    frame: Option<super::frame::Frame>,
    /// Cell c holds `refs[start[c]..start[c + 1]]` (local triangle indices).
    start: Vec<u32>,
    refs: Vec<u32>,
}

impl UniformGrid {
    /// Builds the grid with [`GridOptions::density`] cells per triangle, refusing one whose
    /// cells and references would not fit in memory (or in `max_bytes`).
    pub fn build(mesh: &Mesh, opts: &GridOptions) -> Result<UniformGrid> {
        let prims = Prims::new(mesh);
        let Some((lo, hi, margin)) = prims.grid_box() else {
            return Ok(UniformGrid {
                prims,
                frame: None,
                start: vec![0],
                refs: Vec::new(),
            });
        };
        let res = resolution(
            hi - lo,
            prims.len(),
            opts.density as f64,
            opts.max_resolution.min(1 << 21),
            opts.max_cells,
        );
        let frame = Frame::new(lo, hi, res, margin);
        let budget = Budget::new(
            format!(
                "a uniform grid of {}×{}×{} cells over {} triangles",
                res[0],
                res[1],
                res[2],
                prims.len()
            ),
            opts.max_bytes,
        );
        let tris = prims.to_f64();
        let ids: Vec<u32> = (0..prims.len() as u32).collect();
        let cells = frame.cells();
        let fixed = prims.bytes() as u128 * 3 + Filled::dense_bytes(cells, 0);
        budget.reserve(fixed)?;
        // Each candidate costs a key now and (at most) a reference later.
        let per = 12;
        let counter = Counter::new((budget.left() / per).min(MAX_REFS));
        let counts = if counter.quick(&frame, &tris, &ids) {
            counter.count(&frame, &tris, &ids)
        } else {
            Vec::new()
        };
        if counter.over() {
            return Err(if budget.left() / per < MAX_REFS {
                budget.too_big(fixed + counter.total() as u128 * per as u128)
            } else {
                budget.too_many_refs(counter.total())
            });
        }
        budget.reserve(Filled::bytes(ids.len(), counter.total()) + counter.total() as u128 * 4)?;
        let filled = Filled::new(&frame, &tris, &ids, &counts);
        drop(tris);
        let (start, refs) = filled.dense(&ids, cells as usize);
        Ok(UniformGrid {
            prims,
            frame: Some(frame),
            start,
            refs,
        })
    }

    /// Cells along each axis ([1, 1, 1] for an empty mesh).
    pub fn resolution(&self) -> [u32; 3] {
        self.frame.map_or([1; 3], |f| f.res)
    }

    /// The box the cells divide (the triangles' bounds grown by a small margin), in f32.
    pub fn grid_box(&self) -> Aabb {
        self.frame.map_or(Aabb::EMPTY, |f| Aabb {
            lo: f.lo.as_vec3(),
            hi: f.hi.as_vec3(),
        })
    }

    /// The cell face `k` (0..=resolution) along axis `a`, rounded to f32.
    pub fn boundary(&self, a: usize, k: u32) -> f32 {
        self.frame.map_or(0.0, |f| f.plane(a, k) as f32)
    }

    /// Cells, references and memory.
    pub fn stats(&self) -> GridStats {
        let cells = self.frame.map_or(0, |f| f.cells());
        let non_empty = self.start.windows(2).filter(|w| w[1] > w[0]).count() as u64;
        let references = self.refs.len() as u64;
        let triangles = self.prims.len() as u64;
        GridStats {
            resolution: self.resolution(),
            cells,
            non_empty_cells: non_empty,
            triangles,
            references,
            duplicated: references.saturating_sub(triangles),
            bytes: self.prims.bytes() + (self.start.len() + self.refs.len()) as u64 * 4,
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
        let (Some(frame), true) = (&self.frame, ray.is_valid()) else {
            return Hit::miss(ray.tmax);
        };
        let dray = DdaRay::new(ray);
        let Some((t0, t1)) = dray.clip(frame, ray.tmin, ray.tmax) else {
            return Hit::miss(ray.tmax);
        };
        let mut st = RayWalk::<MT>::new(ray, query, reject_near, mask, stats);
        dray.walk(frame, t0, t1, |cell, _, exit| {
            st.stats.nodes += 1;
            let c = frame.linear(cell) as usize;
            let refs = &self.refs[self.start[c] as usize..self.start[c + 1] as usize];
            st.test(&self.prims, refs) || st.done(exit)
        });
        st.best
    }
}

impl Accel for UniformGrid {
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
