//! Front-to-back stack traversal of the octree, in f64: each stack entry is a node with the
//! ray's [t_enter, t_exit] interval in its cell. At an inner node the three mid-plane
//! distances t_m = (centre − origin)/d are computed; the first child is the one holding the
//! point at t_enter (per axis, the upper half when the ray is there or heading up from the
//! plane), and each mid-plane crossed strictly inside the interval, in ascending t (three
//! values sorted), flips that axis's bit: the children the ray crosses and their intervals
//! (the octant-mask scheme of Revelles et al. 2000, "An efficient parametric algorithm for
//! octree traversal", with the interval ends computed from the planes, never halved). The
//! nearest is visited next and the others pushed farthest first, so nodes are visited in
//! ray order; empty children are not stored and not visited.
//!
//! Robust by construction:
//! - a child's interval ends are its parent's ends or one computed plane distance, the same
//!   value for the children on both sides of a plane, so the intervals tile the ray's
//!   interval in the cube without gaps, whatever the rounding; a point of a cell's interval
//!   lies in the cell up to f64 rounding, far inside the margin the cells are grown by when
//!   triangles are binned, so a triangle the ray meets in a cell's interval is referenced by
//!   that cell (a triangle exactly on a mid-plane is in the cells on both sides);
//! - an axis the ray is parallel to (d exactly ±0; in f64 any other d has a finite
//!   reciprocal, and t_m stays finite) is decided by the origin's side, the upper one when
//!   the origin lies on the plane: every triangle the ray can meet then touches the plane,
//!   so it is in both children;
//! - crossings at equal t (the ray through an edge or corner of the children) flip their
//!   bits together; the zero-length interval between them is skipped (its point is also in
//!   the previous child).
//!
//! The tie rule is the grids': a closest-hit walk ends after a leaf only when the best hit's
//! t, plus its error bound and [`prune_bound`](crate::geometry::prune_bound)'s slack, lies
//! strictly before the leaf's exit (and a popped node whose entry lies beyond that bound ends
//! it too: every node still on the stack starts later), so a triangle at exactly the best t
//! in a later cell is still tested and equal t goes to the smaller original index. Hits are
//! accepted wherever they lie: a hit beyond the current cell is a correct candidate, only
//! termination needs the intervals.
//!
//! Mailboxing: the grids' per-ray walk state remembers the last triangles tested, so a
//! triangle referenced by consecutive cells is tested once.

use glam::DVec3;

use super::build::child_lo;
use super::{Cube, Octree, MAX_OCTREE_DEPTH};
use crate::accel::grid::ray_walk::RayWalk;
use crate::accel::{Accel, Mask, Query, RayStats};
use crate::geometry::{Aabb, Hit, Ray, Robustness, TriangleTest};

/// Entries the stack can hold: each inner node on the path down leaves at most three
/// siblings pending (the nearest child is visited next, not pushed).
const STACK: usize = 3 * MAX_OCTREE_DEPTH;

/// A node waiting to be visited: its index, depth, low corner and the ray's interval in it.
#[derive(Clone, Copy, Debug)]
struct Entry {
    idx: u32,
    depth: u32,
    lo: DVec3,
    t0: f64,
    t1: f64,
}

/// A ray set up for the traversal, in f64.
#[derive(Clone, Copy, Debug)]
struct CellRay {
    o: [f64; 3],
    /// 1/d, or 0 on an axis the ray is parallel to (d = ±0).
    inv: [f64; 3],
    parallel: [bool; 3],
    up: [bool; 3],
}

impl CellRay {
    fn new(ray: &Ray) -> CellRay {
        let d = ray.dir.as_dvec3().to_array();
        CellRay {
            o: ray.origin.as_dvec3().to_array(),
            inv: d.map(|x| if x == 0.0 { 0.0 } else { 1.0 / x }),
            parallel: d.map(|x| x == 0.0),
            up: d.map(|x| x > 0.0),
        }
    }

    /// The part of [tmin, tmax] inside the cube (faces included), or None when the ray
    /// misses it; on a parallel axis the origin must lie within the cube's slab.
    fn clip(&self, cube: &Cube, tmin: f32, tmax: f32) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (tmin as f64, tmax as f64);
        let side = cube.size[0];
        for a in 0..3 {
            let (lo, hi) = (cube.lo[a], cube.lo[a] + side);
            if self.parallel[a] {
                if !(self.o[a] >= lo && self.o[a] <= hi) {
                    return None;
                }
            } else {
                let ta = (lo - self.o[a]) * self.inv[a];
                let tb = (hi - self.o[a]) * self.inv[a];
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }
}

impl Octree {
    #[inline(always)]
    fn walk<const MT: bool>(
        &self,
        ray: &Ray,
        query: Query,
        reject_near: bool,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let (Some(cube), true) = (&self.cube, ray.is_valid()) else {
            return Hit::miss(ray.tmax);
        };
        let r = CellRay::new(ray);
        let Some((t0, t1)) = r.clip(cube, ray.tmin, ray.tmax) else {
            return Hit::miss(ray.tmax);
        };
        let mut st = RayWalk::<MT>::new(ray, query, reject_near, mask, stats);
        // The node being visited: the root, then the nearest child of each inner node, else
        // the top of the stack.
        let mut e = Entry {
            idx: 0,
            depth: 0,
            lo: cube.lo,
            t0,
            t1,
        };
        let mut stack = [e; STACK];
        let mut sp = 0usize;
        loop {
            // Every node still pending starts at or after this one.
            if st.done(e.t0) {
                break;
            }
            st.stats.nodes += 1;
            let node = self.nodes[e.idx as usize];
            if node.is_leaf() {
                let refs = &self.refs[node.first()..node.first() + node.count()];
                if st.test(&self.prims, refs) || st.done(e.t1) || sp == 0 {
                    break;
                }
                sp -= 1;
                e = stack[sp];
                continue;
            }
            let depth = e.depth as usize;
            let mid = e.lo + DVec3::splat(cube.size[depth + 1]);
            // The child holding the point at t0, and the planes crossed inside (t0, t1).
            let mut child = 0u32;
            let mut cross = [(f64::INFINITY, 0u32); 3];
            let mut n = 0;
            for a in 0..3 {
                let upper = if r.parallel[a] {
                    r.o[a] >= mid[a]
                } else {
                    let tm = (mid[a] - r.o[a]) * r.inv[a];
                    if tm > e.t0 && tm < e.t1 {
                        cross[n] = (tm, 1 << a);
                        n += 1;
                    }
                    // At t0 on the plane: the side the ray heads into.
                    if r.up[a] {
                        tm <= e.t0
                    } else {
                        tm > e.t0
                    }
                };
                child |= (upper as u32) << a;
            }
            // Three values sorted (a network; unused slots hold +∞ and stay last).
            let (x, y) = (cross[0], cross[1]);
            if y.0 < x.0 {
                (cross[0], cross[1]) = (y, x);
            }
            let (x, y) = (cross[1], cross[2]);
            if y.0 < x.0 {
                (cross[1], cross[2]) = (y, x);
            }
            let (x, y) = (cross[0], cross[1]);
            if y.0 < x.0 {
                (cross[0], cross[1]) = (y, x);
            }
            // The stored children the ray crosses, in ray order, with their intervals.
            let mut seq = [e; 4];
            let mut k = 0;
            let mut ta = e.t0;
            // The crossings, then the exit (which flips nothing).
            let ends = cross[..n].iter().copied().chain([(e.t1, 0)]);
            for (j, (tb, flip)) in ends.enumerate() {
                if j == 0 || tb > ta {
                    if let Some(idx) = node.child(child) {
                        seq[k] = Entry {
                            idx: idx as u32,
                            depth: e.depth + 1,
                            lo: child_lo(e.lo, mid, child),
                            t0: ta,
                            t1: tb,
                        };
                        k += 1;
                    }
                }
                child ^= flip;
                ta = tb;
            }
            // The nearest is visited next, the others pushed farthest first.
            if k == 0 {
                if sp == 0 {
                    break;
                }
                sp -= 1;
                e = stack[sp];
                continue;
            }
            for &c in seq[1..k].iter().rev() {
                stack[sp] = c;
                sp += 1;
            }
            e = seq[0];
        }
        st.best
    }
}

impl Accel for Octree {
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
