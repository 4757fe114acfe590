//! A chunk of rays walked a few at a time: a CPU twin's `trace_hits` (cwbvh's, and the
//! two-level twin's over cwbvh bottom levels). A twin's
//! walk of one ray is a chain of dependent steps (each node's test waits on its loads and
//! the one before); taking a step of each of two rays in turn gives the CPU independent work
//! to overlap. Every ray still takes exactly its own walk's steps, in order, so the answers are
//! those of walking it alone.

#[cfg(target_arch = "x86_64")]
use super::has_avx2;
use crate::accel::leaf_tri::with_leaf_test;
use crate::accel::{Query, RayStats};
use crate::geometry::{Hit, Ray, Robustness};

/// Walks of one twin that [`walk_interleaved`] drives: `start` begins a ray's walk (false
/// when there is nothing to walk: its answer is then ready), `step` takes one step (true
/// when the walk has ended), `best` is the answer.
pub(crate) trait Stepper {
    /// Begins the walk of `ray`; false when it has nothing to walk (an invalid ray).
    fn start(&mut self, ray: &Ray) -> bool;
    /// Takes one step; true when the walk has ended.
    fn step(&mut self, stats: &mut RayStats) -> bool;
    /// The answer, once `start` gave false or `step` true.
    fn best(&self) -> Hit;
}

/// The ray an idle walk is set up with before its first `start` (never walked).
pub(crate) const IDLE_RAY: Ray = Ray {
    origin: glam::Vec3::ZERO,
    dir: glam::Vec3::X,
    tmin: 0.0,
    tmax: 0.0,
};

/// Rays walked at once. On this project's 2-core AMD EPYC, two gave cwbvh's twin 1.2x the
/// rays/s of one, three and four less than two (each step moves its walk's state through
/// memory); bvh4's twin, whose steps are a node or a leaf, gained nothing (not used there).
pub(crate) const WALKS: usize = 2;

/// Answers `rays` into `out` (as long) with the walks `walks`, each taking the next ray
/// when its own has ended.
#[inline(always)]
pub(crate) fn walk_interleaved<W: Stepper>(rays: &[Ray], out: &mut [Hit], walks: [W; WALKS]) {
    debug_assert_eq!(rays.len(), out.len());
    let mut stats = RayStats::default();
    let mut walks = walks.map(|w| (usize::MAX, w));
    let mut next = 0;
    loop {
        let mut busy = false;
        for (i, w) in walks.iter_mut() {
            // An idle walk takes the next ray that needs one.
            while *i == usize::MAX && next < rays.len() {
                if w.start(&rays[next]) {
                    *i = next;
                } else {
                    out[next] = w.best();
                }
                next += 1;
            }
            if *i == usize::MAX {
                continue;
            }
            busy = true;
            if w.step(&mut stats) {
                out[*i] = w.best();
                *i = usize::MAX;
            }
        }
        if !busy {
            break;
        }
    }
}

/// A twin that answers a chunk of rays a few at a time ([`walk_interleaved`]), specialised
/// by the triangle test `TEST` (`leaf_tri::leaf_test`) and by whether its node test uses
/// AVX2 lanes (`AVX2` true only below [`trace_chunk_avx2`]).
pub(crate) trait ChunkWalk {
    /// Answers `rays` into `out` (as long).
    fn walk_chunk<const TEST: u8, const AVX2: bool>(
        &self,
        rays: &[Ray],
        out: &mut [Hit],
        query: Query,
        robustness: &Robustness,
    );
}

/// Answers a chunk of rays with `twin`: the triangle test `robustness` asks for (chosen once,
/// not per triangle), the node test in AVX2 lanes where the CPU has them.
pub(crate) fn trace_chunk<T: ChunkWalk>(
    twin: &T,
    rays: &[Ray],
    out: &mut [Hit],
    query: Query,
    robustness: &Robustness,
) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { trace_chunk_avx2(twin, rays, out, query, robustness) };
    }
    trace_chunk_with::<T, false>(twin, rays, out, query, robustness);
}

/// [`trace_chunk`] with the node test in SSE (`AVX2` false: the target's baseline) or AVX2
/// lanes; `AVX2` true only below [`trace_chunk_avx2`].
#[inline(always)]
pub(crate) fn trace_chunk_with<T: ChunkWalk, const AVX2: bool>(
    twin: &T,
    rays: &[Ray],
    out: &mut [Hit],
    query: Query,
    robustness: &Robustness,
) {
    with_leaf_test!(
        robustness,
        twin.walk_chunk::<_, AVX2>(rays, out, query, robustness)
    )
}

/// [`trace_chunk_with`] compiled with AVX2 (and the bit instructions every AVX2 CPU has);
/// the CPU must have them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt,bmi1,lzcnt")]
pub(crate) unsafe fn trace_chunk_avx2<T: ChunkWalk>(
    twin: &T,
    rays: &[Ray],
    out: &mut [Hit],
    query: Query,
    robustness: &Robustness,
) {
    trace_chunk_with::<T, true>(twin, rays, out, query, robustness)
}
