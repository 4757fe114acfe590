//! One ray's state while it walks a grid: the best hit (tie rule [`Hit::beats`]), the bound
//! the walk may stop at, the mailbox, and the work counted. Triangles are tested as the
//! BVH's twin tests them: the chosen test with its t error bound, hits within that bound of
//! the origin rejected when
//! [`Robustness::rejects_near_hits`](crate::Robustness::rejects_near_hits).

use super::prims::Prims;
use crate::accel::{Mask, Query, RayStats};
use crate::geometry::{intersect_triangle_bounded, Hit, Ray, TriHit, TriangleTest, WatertightRay};

/// Mailbox entries: the last triangles tested, skipped when a later cell references them.
const MAILBOX: usize = 8;

/// A ray walking a grid; `MT` selects Möller–Trumbore, else the watertight test.
pub(crate) struct RayWalk<'a, const MT: bool> {
    ray: &'a Ray,
    wr: WatertightRay,
    query: Query,
    /// Hits within their own error bound of the origin are rejected (as the BVH does).
    reject_near: bool,
    /// The alpha mask a hit must pass ([`crate::accel::HitMask`]), if any.
    mask: Mask<'a>,
    /// The best hit so far (a miss at tmax at first).
    pub best: Hit,
    /// The walk may end after a cell whose exit is beyond this: the best t plus its error
    /// bound and the tie slack (∞ while nothing is hit).
    bound: f64,
    mailbox: [u32; MAILBOX],
    slot: usize,
    /// Work done.
    pub stats: &'a mut RayStats,
}

impl<'a, const MT: bool> RayWalk<'a, MT> {
    /// The start of a walk for a valid ray.
    #[inline(always)]
    pub fn new(
        ray: &'a Ray,
        query: Query,
        reject_near: bool,
        mask: Mask<'a>,
        stats: &'a mut RayStats,
    ) -> Self {
        RayWalk {
            ray,
            wr: WatertightRay::new(ray.dir),
            query,
            reject_near,
            mask,
            best: Hit::miss(ray.tmax),
            bound: f64::INFINITY,
            mailbox: [u32::MAX; MAILBOX],
            slot: 0,
            stats,
        }
    }

    /// Tests the triangles `refs` (local indices) not tested lately; returns true when the
    /// query is answered (an any-hit query found a hit).
    #[inline(always)]
    pub fn test(&mut self, prims: &Prims, refs: &[u32]) -> bool {
        let test = if MT {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        for &r in refs {
            if self.mailbox.contains(&r) {
                continue;
            }
            self.mailbox[self.slot] = r;
            self.slot = (self.slot + 1) % MAILBOX;
            self.stats.tris += 1;
            let tri = &prims.tris[r as usize];
            let (ray, tmin, tmax) = (self.ray, self.ray.tmin, self.best.t);
            let Some(h) = intersect_triangle_bounded(test, tri, ray, &self.wr, tmin, tmax) else {
                continue;
            };
            let TriHit { t, u, v, .. } = h;
            let prim = prims.prims[r as usize];
            if !Hit::beats(t, prim, self.best.t, self.best.prim)
                || (self.reject_near && h.maybe_behind_origin())
                || self.mask.is_some_and(|m| !m.keeps(prim, u, v))
            {
                continue;
            }
            self.best = Hit { t, prim, u, v };
            if self.query == Query::Any {
                return true;
            }
            self.bound = h.prune() as f64;
        }
        false
    }

    /// Whether a closest-hit walk may end after a cell that ends at `exit`: the best hit
    /// (and any triangle at the same t) lies before it, so no later cell can do better.
    #[inline(always)]
    pub fn done(&self, exit: f64) -> bool {
        self.bound < exit
    }
}
