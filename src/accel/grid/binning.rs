//! Binning triangles into the cells of a [`Frame`]: a conservative scan of the cells a
//! triangle can touch (column by column along its plane's dominant axis, so the work follows
//! the triangle's area, not its bounding box's volume), an exact triangle–box test on each,
//! and the cell → triangles lists built from the result.
//!
//! Binning runs in two passes. The first counts candidate cells (an upper bound on the
//! references) and stops as soon as the count passes a cap, so that the size of a grid that
//! would not fit is known before anything is allocated and without unbounded work. The
//! second writes each triangle's cells into its own slice of one array, in parallel.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::frame::Frame;
use super::overlap::tri_box_overlap;

/// Marks an unused slot of a triangle's slice (a candidate cell the exact test rejected).
const NONE: u64 = u64::MAX;

/// Triangles per parallel task in the second pass.
const CHUNK: usize = 256;

/// Calls `f(cell, k0, k1)` for the cells `cell` with `cell[w]` in `k0..=k1` that may hold
/// triangle `v` (cells grown by the frame's margin), `w` being the dominant axis of the
/// triangle's normal; returns false as soon as `f` does.
#[inline]
fn for_each_column(
    frame: &Frame,
    v: &[DVec3; 3],
    mut f: impl FnMut([u32; 3], usize, u32, u32) -> bool,
) -> bool {
    let m = frame.margin;
    let blo = v[0].min(v[1]).min(v[2]) - m;
    let bhi = v[0].max(v[1]).max(v[2]) + m;
    // Outside the frame, or NaN (never for included triangles).
    if !(blo.cmple(frame.hi).all() && bhi.cmpge(frame.lo).all()) {
        return true;
    }
    let i0 = [0, 1, 2].map(|a| frame.index(a, blo[a]));
    let i1 = [0, 1, 2].map(|a| frame.index(a, bhi[a]));
    let n = (v[1] - v[0]).cross(v[2] - v[0]);
    let an = n.abs();
    let w = if an.x >= an.y && an.x >= an.z {
        0
    } else if an.y >= an.z {
        1
    } else {
        2
    };
    let (u, t) = ((w + 1) % 3, (w + 2) % 3);
    let d = n.dot(v[0]);
    let plane = n[w] != 0.0;
    for iu in i0[u]..=i1[u] {
        let (ua, ub) = (frame.plane(u, iu) - m[u], frame.plane(u, iu + 1) + m[u]);
        // The triangle's extent along t within the slab ua ≤ x[u] ≤ ub: its edges clipped.
        let (mut tmin, mut tmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for e in 0..3 {
            let (p, q) = (v[e], v[(e + 1) % 3]);
            if (p[u] < ua && q[u] < ua) || (p[u] > ub && q[u] > ub) {
                continue;
            }
            let (s0, s1) = if p[u] == q[u] {
                (0.0, 1.0)
            } else {
                let sa = (ua - p[u]) / (q[u] - p[u]);
                let sb = (ub - p[u]) / (q[u] - p[u]);
                (sa.min(sb).max(0.0), sa.max(sb).min(1.0))
            };
            let ta = p[t] + (q[t] - p[t]) * s0;
            let tb = p[t] + (q[t] - p[t]) * s1;
            tmin = tmin.min(ta.min(tb));
            tmax = tmax.max(ta.max(tb));
        }
        if tmin > tmax {
            continue;
        }
        let j0 = frame.index(t, tmin - m[t]).max(i0[t]);
        let j1 = frame.index(t, tmax + m[t]).min(i1[t]);
        for jt in j0..=j1 {
            let (ta, tb) = (frame.plane(t, jt) - m[t], frame.plane(t, jt + 1) + m[t]);
            // The plane's extent along w over the column (a linear function: its corners).
            let (mut wlo, mut whi) = (blo[w], bhi[w]);
            if plane {
                let at = |x: f64, y: f64| (d - n[u] * x - n[t] * y) / n[w];
                let c = [at(ua, ta), at(ua, tb), at(ub, ta), at(ub, tb)];
                let lo = c[0].min(c[1]).min(c[2]).min(c[3]) - m[w];
                let hi = c[0].max(c[1]).max(c[2]).max(c[3]) + m[w];
                wlo = wlo.max(lo);
                whi = whi.min(hi);
            }
            if wlo > whi {
                continue;
            }
            let k0 = frame.index(w, wlo).max(i0[w]);
            let k1 = frame.index(w, whi).min(i1[w]);
            if k0 > k1 {
                continue;
            }
            let mut cell = [0u32; 3];
            cell[u] = iu;
            cell[t] = jt;
            if !f(cell, w, k0, k1) {
                return false;
            }
        }
    }
    true
}

/// Calls `f` with each cell triangle `v` overlaps (cells grown by the frame's margin).
#[inline]
pub(crate) fn for_each_cell(frame: &Frame, v: &[DVec3; 3], mut f: impl FnMut([u32; 3])) {
    let h = frame.cs * 0.5 + frame.margin;
    for_each_column(frame, v, |mut cell, w, k0, k1| {
        for k in k0..=k1 {
            cell[w] = k;
            let (lo, hi) = frame.cell_box(cell);
            if tri_box_overlap((lo + hi) * 0.5, h, v) {
                f(cell);
            }
        }
        true
    });
}

/// The first pass, shared by all the binnings of one build: candidate cells counted against
/// one cap.
#[derive(Debug)]
pub(crate) struct Counter {
    cap: u64,
    total: AtomicU64,
    over: AtomicBool,
}

impl Counter {
    /// A counter that gives up once more than `cap` candidates are counted in all.
    pub fn new(cap: u64) -> Counter {
        Counter {
            cap,
            total: AtomicU64::new(0),
            over: AtomicBool::new(false),
        }
    }

    /// Whether the count passed the cap (the counts returned are then incomplete).
    pub fn over(&self) -> bool {
        self.over.load(Ordering::Relaxed)
    }

    /// Candidates counted so far.
    pub fn total(&self) -> u64 {
        self.total.load(Ordering::Relaxed)
    }

    /// A quick lower bound on the references of triangles `ids` in `frame`, in O(1) each:
    /// a triangle covers at least its projected area's worth of columns along the dominant
    /// axis of its normal, and has a cell in each. Adds it to the count (so that a grid far
    /// over the cap is refused without counting cell by cell) and returns whether it fits.
    pub fn quick(&self, frame: &Frame, tris: &[[DVec3; 3]], ids: &[u32]) -> bool {
        let area = |v: &[DVec3; 3]| {
            let n = (v[1] - v[0]).cross(v[2] - v[0]).abs();
            let col = DVec3::new(
                frame.cs.y * frame.cs.z,
                frame.cs.z * frame.cs.x,
                frame.cs.x * frame.cs.y,
            );
            (0.5 * n / col).max_element()
        };
        let lower: f64 = ids.iter().map(|&id| area(&tris[id as usize]).floor()).sum();
        if lower > self.cap as f64 {
            self.total
                .store(lower.min(u64::MAX as f64) as u64, Ordering::Relaxed);
            self.over.store(true, Ordering::Relaxed);
            return false;
        }
        true
    }

    /// Candidate cells of each triangle `ids[i]` in `frame` (zeros once over the cap).
    pub fn count(&self, frame: &Frame, tris: &[[DVec3; 3]], ids: &[u32]) -> Vec<u32> {
        let one = |&id: &u32| -> u32 {
            if self.over() {
                return 0;
            }
            let mut n = 0u64;
            let done = for_each_column(frame, &tris[id as usize], |_, _, k0, k1| {
                n += (k1 - k0 + 1) as u64;
                n <= self.cap
            });
            let total = self.total.fetch_add(n, Ordering::Relaxed) + n;
            if !done || total > self.cap {
                self.over.store(true, Ordering::Relaxed);
                return 0;
            }
            n as u32
        };
        if ids.len() >= 2 * CHUNK {
            ids.par_iter().map(one).collect()
        } else {
            ids.iter().map(one).collect()
        }
    }
}

/// The cells of each triangle `ids[i]`: linear cell indices in
/// `keys[offsets[i]..offsets[i + 1]]`, unused slots [`NONE`].
pub(crate) struct Filled {
    offsets: Vec<usize>,
    keys: Vec<u64>,
}

impl Filled {
    /// Bytes the second pass allocates for `candidates` candidates of `n` triangles.
    pub fn bytes(n: usize, candidates: u64) -> u128 {
        (n as u128 + 1) * 8 + candidates as u128 * 8
    }

    /// The second pass: the cells each triangle overlaps, from its candidate `counts`.
    pub fn new(frame: &Frame, tris: &[[DVec3; 3]], ids: &[u32], counts: &[u32]) -> Filled {
        let mut offsets = Vec::with_capacity(ids.len() + 1);
        let mut acc = 0usize;
        offsets.push(0);
        for &c in counts {
            acc += c as usize;
            offsets.push(acc);
        }
        let mut keys = vec![NONE; acc];
        let fill = |first: usize, slice: &mut [u64], ids: &[u32]| {
            let base = offsets[first];
            for (i, &id) in ids.iter().enumerate() {
                let (a, b) = (offsets[first + i] - base, offsets[first + i + 1] - base);
                let out = &mut slice[a..b];
                let mut j = 0;
                for_each_cell(frame, &tris[id as usize], |c| {
                    if j < out.len() {
                        out[j] = frame.linear(c);
                        j += 1;
                    }
                });
            }
        };
        if ids.len() < 2 * CHUNK {
            fill(0, &mut keys, ids);
        } else {
            let mut parts = Vec::new();
            let mut rest: &mut [u64] = &mut keys;
            for first in (0..ids.len()).step_by(CHUNK) {
                let last = (first + CHUNK).min(ids.len());
                let (head, tail) = rest.split_at_mut(offsets[last] - offsets[first]);
                parts.push((first, head, &ids[first..last]));
                rest = tail;
            }
            parts
                .into_par_iter()
                .for_each(|(first, slice, ids)| fill(first, slice, ids));
        }
        Filled { offsets, keys }
    }

    /// References found (candidates the exact test kept).
    pub fn references(&self) -> u64 {
        self.keys.iter().filter(|&&k| k != NONE).count() as u64
    }

    /// The cells of `ids[i]`.
    fn cells(&self, i: usize) -> impl Iterator<Item = u64> + '_ {
        self.keys[self.offsets[i]..self.offsets[i + 1]]
            .iter()
            .copied()
            .filter(|&k| k != NONE)
    }

    /// Bytes [`dense`](Self::dense) allocates for `cells` cells and `refs` references.
    pub fn dense_bytes(cells: u64, refs: u64) -> u128 {
        (cells as u128 + 1) * 4 + refs as u128 * 4
    }

    /// Cell lists of a dense grid of `cells` cells: cell c holds
    /// `refs[start[c]..start[c + 1]]`, the ids in ascending order of `i`.
    pub fn dense(&self, ids: &[u32], cells: usize) -> (Vec<u32>, Vec<u32>) {
        let mut start = vec![0u32; cells + 1];
        for i in 0..ids.len() {
            for k in self.cells(i) {
                start[k as usize + 1] += 1;
            }
        }
        for c in 0..cells {
            start[c + 1] += start[c];
        }
        let mut refs = vec![0u32; start[cells] as usize];
        for (i, &id) in ids.iter().enumerate() {
            for k in self.cells(i) {
                refs[start[k as usize] as usize] = id;
                start[k as usize] += 1;
            }
        }
        // start[c] is now the end of c: shift back by one cell.
        for c in (1..=cells).rev() {
            start[c] = start[c - 1];
        }
        start[0] = 0;
        (start, refs)
    }

    /// Bytes [`sparse`](Self::sparse) allocates for `refs` references.
    pub fn sparse_bytes(refs: u64) -> u128 {
        refs as u128 * (16 + 8 + 4 + 4)
    }

    /// Cell lists of the non-empty cells only: `keys` ascending, cell `keys[j]` holds
    /// `refs[start[j]..start[j + 1]]`.
    pub fn sparse(&self, ids: &[u32]) -> (Vec<u64>, Vec<u32>, Vec<u32>) {
        let mut pairs: Vec<(u64, u32)> = Vec::with_capacity(self.references() as usize);
        for (i, &id) in ids.iter().enumerate() {
            pairs.extend(self.cells(i).map(|k| (k, id)));
        }
        pairs.par_sort_unstable();
        let mut keys = Vec::new();
        let mut start = Vec::new();
        let refs: Vec<u32> = pairs.iter().map(|p| p.1).collect();
        for (j, p) in pairs.iter().enumerate() {
            if keys.last() != Some(&p.0) {
                keys.push(p.0);
                start.push(j as u32);
            }
        }
        start.push(refs.len() as u32);
        (keys, start, refs)
    }
}
