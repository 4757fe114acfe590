//! The 3D-DDA cell walk (Amanatides & Woo, "A Fast Voxel Traversal Algorithm for Ray
//! Tracing", Eurographics 1987), in f64. Each cell's exit t is computed from its face's
//! index, `(lo − origin)/d + k · size/d`, never accumulated, so neighbouring cells agree on
//! the t of their shared face. An axis the ray is parallel to (|safe_recip(d)| ≥
//! PARALLEL_INV, zero and −0 included) never steps; the ray is clipped to the grid's box
//! first, so origins inside and outside the grid are the same case. Every step moves one
//! cell further along one axis, so a walk ends after at most `res.x + res.y + res.z` cells,
//! whatever the ray.

use super::frame::Frame;
use crate::geometry::{safe_recip, Ray, PARALLEL_INV};

/// A ray set up for cell walks.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DdaRay {
    // Arrays, not vectors: indexed by a run-time axis in the hot loop.
    o: [f64; 3],
    d: [f64; 3],
    /// 1/d in f64 on stepping axes (0 on parallel ones).
    inv: [f64; 3],
    /// Cell step along each axis: +1, −1, or 0 where the ray is parallel to the axis.
    step: [i32; 3],
}

impl DdaRay {
    /// The set-up for a valid ray.
    pub fn new(ray: &Ray) -> DdaRay {
        let mut inv = [0.0; 3];
        let mut step = [0; 3];
        for a in 0..3 {
            let r = safe_recip(ray.dir[a]);
            if r.abs() < PARALLEL_INV {
                inv[a] = 1.0 / ray.dir[a] as f64;
                step[a] = if r < 0.0 { -1 } else { 1 };
            }
        }
        DdaRay {
            o: ray.origin.as_dvec3().to_array(),
            d: ray.dir.as_dvec3().to_array(),
            inv,
            step,
        }
    }

    /// The part of [tmin, tmax] inside the frame's box, or None when the ray misses it. On a
    /// parallel axis the origin must lie within the box's slab (faces included).
    #[inline]
    pub fn clip(&self, f: &Frame, tmin: f32, tmax: f32) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (tmin as f64, tmax as f64);
        for a in 0..3 {
            if self.step[a] == 0 {
                if !(self.o[a] >= f.lo[a] && self.o[a] <= f.hi[a]) {
                    return None;
                }
            } else {
                let ta = (f.lo[a] - self.o[a]) * self.inv[a];
                let tb = (f.hi[a] - self.o[a]) * self.inv[a];
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// Walks the cells of `f` the ray crosses for t in [t_start, t_end] (inside the frame's
    /// box), in order, calling `visit(cell, t_enter, t_exit)`; stops when `visit` returns
    /// true and then returns true. The first cell holds the point at t_start (on a face, the
    /// cell the ray is heading into); the last one's exit is t_end.
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-proof comparisons, on purpose
    pub fn walk(
        &self,
        f: &Frame,
        t_start: f64,
        t_end: f64,
        mut visit: impl FnMut([u32; 3], f64, f64) -> bool,
    ) -> bool {
        let mut cell = [0u32; 3];
        let mut t_next = [f64::INFINITY; 3];
        // t of face k along axis a: base[a] + k·dt[a], a function of k alone (never
        // accumulated), so the cells on either side of a face agree on its t.
        let mut base = [0.0; 3];
        let mut dt = [0.0; 3];
        for a in 0..3 {
            base[a] = (f.plane(a, 0) - self.o[a]) * self.inv[a];
            dt[a] = f.cs[a] * self.inv[a];
        }
        let t_face = |a: usize, k: u32| base[a] + k as f64 * dt[a];
        // (The loop below computes the same expression with k in f64.)
        for a in 0..3 {
            let p = if self.step[a] == 0 {
                self.o[a]
            } else {
                self.o[a] + self.d[a] * t_start
            };
            cell[a] = if self.step[a] < 0 {
                // On a face, heading down: the cell below it.
                f.index_below(a, p)
            } else {
                f.index(a, p)
            };
            match self.step[a] {
                1 => t_next[a] = t_face(a, cell[a] + 1),
                -1 => t_next[a] = t_face(a, cell[a]),
                _ => {}
            }
        }
        let mut enter = t_start;
        // In registers: the t of each axis's next face and of the face after it, so that a
        // step only moves values (the new "after" is computed off the critical path), and
        // the axis to step is chosen without branches (its pattern is what a branch
        // predictor cannot learn).
        let sf = self.step.map(|s| s as f64);
        let mut kn = [0.0; 3];
        let mut after = [f64::INFINITY; 3];
        let mut last = [0u32; 3];
        for a in 0..3 {
            if self.step[a] != 0 {
                kn[a] = (cell[a] + (self.step[a] > 0) as u32) as f64;
                after[a] = base[a] + (kn[a] + sf[a]) * dt[a];
                last[a] = if self.step[a] > 0 { f.res[a] - 1 } else { 0 };
            }
        }
        let [mut tx, mut ty, mut tz] = t_next;
        let [mut ax, mut ay, mut az] = after;
        let steps = f.res.iter().map(|&r| r as u64).sum::<u64>() + 1;
        for _ in 0..steps {
            let bx = tx <= ty && tx <= tz;
            let by = !bx & (ty <= tz);
            let a = 2 - 2 * bx as usize - by as usize;
            // No NaN reaches here (finite faces, origins and reciprocals; ∞ for parallel
            // axes), so the minimum is the chosen axis's t.
            let tn = tx.min(ty).min(tz);
            let exit = if tn < t_end { tn } else { t_end };
            if visit(cell, enter, exit) {
                return true;
            }
            // The ray ends in this cell, or leaves the grid (a parallel axis is never
            // chosen here: its t is ∞, not below t_end).
            if !(tn < t_end) || cell[a] == last[a] {
                return false;
            }
            cell[a] = cell[a].wrapping_add_signed(self.step[a]);
            enter = enter.max(exit);
            kn[a] += sf[a];
            let t2 = base[a] + (kn[a] + sf[a]) * dt[a];
            tx = if a == 0 { ax } else { tx };
            ty = if a == 1 { ay } else { ty };
            tz = if a == 2 { az } else { tz };
            ax = if a == 0 { t2 } else { ax };
            ay = if a == 1 { t2 } else { ay };
            az = if a == 2 { t2 } else { az };
        }
        false
    }
}
