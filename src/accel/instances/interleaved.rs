//! The two-level twin's batches over cwbvh bottom levels ([`TwoLevel`]'s `trace_hits`):
//! the walk of `TwoLevel::intersect_masked` a step at a time — a top-level node, or inside
//! an instance a step of cwbvh's own walk — two rays in turn, as cwbvh's batches are walked
//! (`layouts::walk_interleaved`). Every ray takes exactly its one-ray walk's steps, in
//! order, so every answer is that walk's: the interleaving only gives the CPU two
//! independent chains of loads to overlap (the flattened scene's cwbvh batches have it too,
//! so instanced and flattened batches compare like with like).
//!
//! [`TwoLevel`]: super::TwoLevel

use std::mem::MaybeUninit;

use super::top_level::{TopEntry, TopLevel};
use crate::accel::bvh::layouts::{
    walk_interleaved, ChunkWalk, Cwbvh, CwbvhWalk, DfsNodeRay, Stepper, IDLE_RAY, WALKS,
};
use crate::accel::bvh::MAX_DEPTH;
use crate::accel::{Query, RayStats};
use crate::geometry::{prune_bound, Hit, Ray, Robustness};

/// A two-level structure whose bottom levels are all cwbvh: the top level, and each mesh's
/// bottom level by mesh index. Its chunks of rays are walked two rays at a time
/// ([`ChunkWalk`]).
pub(super) struct CwbvhLevels<'a> {
    pub top: &'a TopLevel,
    pub bottoms: Vec<&'a Cwbvh>,
}

impl ChunkWalk for CwbvhLevels<'_> {
    #[inline(always)]
    fn walk_chunk<const TEST: u8, const AVX2: bool>(
        &self,
        rays: &[Ray],
        out: &mut [Hit],
        query: Query,
        robustness: &Robustness,
    ) {
        let walks = [(); WALKS].map(|_| Walk::<TEST, AVX2>::idle(self, query, robustness));
        walk_interleaved(rays, out, walks);
    }
}

/// One ray's two-level walk, a step at a time ([`Stepper`]).
struct Walk<'a, const TEST: u8, const AVX2: bool> {
    levels: &'a CwbvhLevels<'a>,
    robustness: Robustness,
    any: bool,
    /// The ray in world space.
    ray: Ray,
    /// Its top-level box tests.
    boxes: DfsNodeRay,
    /// The closest hit so far, numbered as the flattened scene numbers it.
    best: Hit,
    prune: f32,
    /// The far children pushed. Not zeroed: only pushed entries are read.
    stack: [MaybeUninit<u32>; MAX_DEPTH],
    sp: usize,
    /// The top-level node the next top step visits.
    idx: usize,
    /// The instance whose bottom level `bottom` is walking, if any.
    inside: Option<&'a TopEntry>,
    bottom: CwbvhWalk<'a, TEST, AVX2>,
}

impl<'a, const TEST: u8, const AVX2: bool> Walk<'a, TEST, AVX2> {
    fn idle(levels: &'a CwbvhLevels<'a>, query: Query, robustness: &Robustness) -> Self {
        // The walk's bottom levels are entered with `begin`; any one serves until then.
        let first = levels.bottoms[0];
        Walk {
            levels,
            robustness: *robustness,
            any: query == Query::Any,
            ray: IDLE_RAY,
            boxes: DfsNodeRay::new(&IDLE_RAY, robustness),
            best: Hit::miss(0.0),
            prune: 0.0,
            stack: [MaybeUninit::uninit(); MAX_DEPTH],
            sp: 0,
            idx: 0,
            inside: None,
            bottom: CwbvhWalk::idle(first, query, robustness, None),
        }
    }

    /// Moves to the next node on the stack; true when there is none (the walk has ended).
    #[inline(always)]
    fn pop(&mut self) -> bool {
        if self.sp == 0 {
            return true;
        }
        self.sp -= 1;
        // SAFETY: every entry below the old `sp` was written by a push.
        self.idx = unsafe { self.stack[self.sp].assume_init() } as usize;
        false
    }
}

impl<const TEST: u8, const AVX2: bool> Stepper for Walk<'_, TEST, AVX2> {
    #[inline(always)]
    fn start(&mut self, ray: &Ray) -> bool {
        self.best = Hit::miss(ray.tmax);
        if !ray.is_valid() || self.levels.top.nodes.is_empty() {
            return false;
        }
        self.ray = *ray;
        self.boxes = DfsNodeRay::new(ray, &self.robustness);
        self.prune = prune_bound(self.best.t);
        self.sp = 0;
        self.idx = 0;
        self.inside = None;
        true
    }

    /// A step of the bottom level's walk inside an instance (taking its answer when that
    /// walk ends), else a top-level node: as `TwoLevel::intersect_masked`'s loop.
    #[inline(always)]
    fn step(&mut self, stats: &mut RayStats) -> bool {
        if let Some(e) = self.inside {
            if !self.bottom.step(stats) {
                return false;
            }
            self.inside = None;
            let (h, h_prune) = self.bottom.answer();
            let prim = e.first_prim.wrapping_add(h.prim);
            if h.is_hit() && Hit::beats(h.t, prim, self.best.t, self.best.prim) {
                self.best = Hit { prim, ..h };
                if self.any {
                    return true;
                }
                self.prune = h_prune;
            }
            return self.pop();
        }
        let top = self.levels.top;
        let node = &top.nodes[self.idx];
        stats.nodes += 1;
        if self.boxes.enters(node, self.prune) {
            if !node.is_leaf() {
                let (first, second) = (self.idx + 1, node.a as usize);
                let (near, far) = if self.ray.dir[node.axis()] < 0.0 {
                    (second, first)
                } else {
                    (first, second)
                };
                self.stack[self.sp] = MaybeUninit::new(far as u32);
                self.sp += 1;
                self.idx = near;
                return false;
            }
            // A leaf holds one instance (TopLevel::build).
            let e = &top.entries[node.a as usize];
            let mut local = e.to_object.ray(&self.ray);
            if self.best.is_hit() {
                local.tmax = self.prune;
            }
            if self
                .bottom
                .begin(self.levels.bottoms[e.mesh as usize], &local)
            {
                self.inside = Some(e);
                return false;
            }
            // Nothing to walk in object space: a miss there.
        }
        self.pop()
    }

    #[inline(always)]
    fn best(&self) -> Hit {
        self.best
    }
}
