//! The hashed grid: a fine regular grid ([`GridOptions::hashed_density`] cells per triangle)
//! of which only the non-empty cells are stored, in an open-addressing hash table keyed by
//! the cell's linear index (linear probing, at most half full). Memory follows the
//! references, not the cell count; traversal walks the virtual grid and looks each cell up.

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

/// Key of an empty slot (no cell has this linear index: at most (2²¹)³ cells).
const EMPTY: u64 = u64::MAX;

/// A hashed grid over a mesh's included triangles.
#[derive(Clone, Debug)]
pub struct HashedGrid {
    prims: Prims,
    /// The virtual grid; None when there are no triangles.
    frame: Option<Frame>,
    /// The table's keys (a power of two of slots; [`EMPTY`] in free ones), apart from
    /// their ranges so that the probes of empty cells, most lookups, touch only keys.
    keys: Vec<u64>,
    /// Each slot's cell references `refs[start..end]`.
    ranges: Vec<[u32; 2]>,
    /// log2 of the slot count.
    bits: u32,
    /// Non-empty cells stored.
    stored: u64,
    refs: Vec<u32>,
}

/// The home slot of `key` in a table of 2^bits slots (Fibonacci hashing).
#[inline(always)]
fn home(key: u64, bits: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
}

impl HashedGrid {
    /// Builds the grid, refusing one whose references and table would not fit in memory
    /// (or in `max_bytes`).
    pub fn build(mesh: &Mesh, opts: &GridOptions) -> Result<HashedGrid> {
        let prims = Prims::new(mesh);
        let Some((lo, hi, margin)) = prims.grid_box() else {
            return Ok(HashedGrid {
                prims,
                frame: None,
                keys: Vec::new(),
                ranges: Vec::new(),
                bits: 0,
                stored: 0,
                refs: Vec::new(),
            });
        };
        let res = resolution(
            hi - lo,
            prims.len(),
            opts.hashed_density as f64,
            opts.max_resolution.min(1 << 21),
            u64::MAX,
        );
        let frame = Frame::new(lo, hi, res, margin);
        let budget = Budget::new(
            format!(
                "a hashed grid of {}×{}×{} cells over {} triangles",
                res[0],
                res[1],
                res[2],
                prims.len()
            ),
            opts.max_bytes,
        );
        let tris = prims.to_f64();
        let ids: Vec<u32> = (0..prims.len() as u32).collect();
        let fixed = prims.bytes() as u128 * 3;
        budget.reserve(fixed)?;
        // A candidate costs a key, then a sort pair, a reference and (at most) a slot pair.
        let per = 8 + Filled::sparse_bytes(1) as u64 + 32;
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
        budget.reserve(counter.total() as u128 * per as u128 + ids.len() as u128 * 8)?;
        let filled = Filled::new(&frame, &tris, &ids, &counts);
        drop(tris);
        let (keys, start, refs) = filled.sparse(&ids);
        drop(filled);
        let bits = (2 * keys.len())
            .max(16)
            .next_power_of_two()
            .trailing_zeros();
        let mut table = vec![EMPTY; 1 << bits];
        let mut ranges = vec![[0u32; 2]; 1 << bits];
        let mask = table.len() - 1;
        for (j, &key) in keys.iter().enumerate() {
            let mut s = home(key, bits);
            while table[s] != EMPTY {
                s = (s + 1) & mask;
            }
            table[s] = key;
            ranges[s] = [start[j], start[j + 1]];
        }
        Ok(HashedGrid {
            prims,
            frame: Some(frame),
            keys: table,
            ranges,
            bits,
            stored: keys.len() as u64,
            refs,
        })
    }

    /// The references of the cell with linear index `key` (empty when it is not stored).
    #[inline(always)]
    fn lookup(&self, key: u64) -> &[u32] {
        let mask = self.keys.len() - 1;
        let mut s = home(key, self.bits);
        loop {
            let k = self.keys[s];
            if k == key {
                let [a, b] = self.ranges[s];
                return &self.refs[a as usize..b as usize];
            }
            if k == EMPTY {
                return &[];
            }
            s = (s + 1) & mask;
        }
    }

    /// Cells of the virtual grid along each axis ([1, 1, 1] for an empty mesh).
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

    /// Cells (of the virtual grid), stored cells, references and memory.
    pub fn stats(&self) -> GridStats {
        let references = self.refs.len() as u64;
        let triangles = self.prims.len() as u64;
        GridStats {
            resolution: self.resolution(),
            cells: self.frame.map_or(0, |f| f.cells()),
            non_empty_cells: self.stored,
            triangles,
            references,
            duplicated: references.saturating_sub(triangles),
            bytes: self.prims.bytes() + self.keys.len() as u64 * 16 + references * 4,
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
            let refs = self.lookup(frame.linear(cell));
            (!refs.is_empty() && st.test(&self.prims, refs)) || st.done(exit)
        });
        st.best
    }
}

impl Accel for HashedGrid {
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
