//! The CPU twin of `cwbvh.wgsl`, step for step: the same group stack (a node's remaining
//! hit children pushed before descending into the one with the highest hit-mask bit), the
//! same octant order, child boxes dequantised with the same f32 arithmetic and tested with
//! the shared slab test against the same bound (for a ray with no parallel axis all eight
//! slots in one AVX2 vector where the CPU has AVX2, else four at a time in SSE lanes, equal to
//! it lane for lane), a node's hit leaf triangles tested lowest bit first right after the node
//! (as one leaf: `LeafRay::test_leaf`), and the same tie rule, all in f32. A batch
//! (`trace_hits`) walks two rays at a time, a node step of each in turn (`interleave`).

use std::mem::MaybeUninit;

use glam::{Vec3, Vec3A, Vec4};

use super::quantise::step;
use super::{CwNode, Cwbvh, COUNT_SHIFT, STACK_SIZE, TRI_BITS, WIDTH};
use crate::accel::bvh::layouts::interleave::{
    trace_chunk, walk_interleaved, ChunkWalk, Stepper, IDLE_RAY, WALKS,
};
use crate::accel::leaf_tri::{walk_accel_methods, with_leaf_test, LeafRay, LeafTri};
use crate::accel::{trace_chunks, Accel, Mask, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, SlabRay4, MISS, PARALLEL_INV};

/// Hit-mask bits of internal children.
const NODE_BITS: u32 = !((1 << TRI_BITS) - 1);
/// Hit-mask bits of triangles.
const TRI_MASK: u32 = (1 << TRI_BITS) - 1;
/// A meta byte's bit index field.
const INDEX_MASK: u32 = (1 << COUNT_SHIFT) - 1;

impl Accel for Cwbvh {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    // One specialised loop per triangle test (the choice is not re-made per triangle).
    // The same source compiled for AVX2 where the CPU has it: the eight slots in one
    // vector (identical results: no fused operations either way).
    walk_accel_methods!(avx2);

    fn as_cwbvh(&self) -> Option<&Cwbvh> {
        Some(self)
    }

    fn trace_hits(&self, rays: &[Ray], query: Query, robustness: &Robustness) -> Vec<Hit> {
        trace_chunks(rays, Hit::miss(0.0), |rays, out| {
            trace_chunk(self, rays, out, query, robustness)
        })
    }
}

/// What the child tests of one ray share.
struct RayBox {
    origin: Vec3,
    inv: Vec3,
    tmin: f32,
    widen: f32,
    /// The ray is parallel to an axis: the scalar slab test with its parallel-axis rule.
    parallel: bool,
    /// Else, without AVX2: its lanes for four boxes at a time.
    slab4: SlabRay4,
    /// Per axis: the direction is negative, so the high plane is met first.
    neg: [bool; 3],
    /// 7 ^ octant: XORed into an internal child's slot to give its traversal rank.
    oct_inv: u32,
}

impl RayBox {
    /// The set-up for `ray` with the far widening `widen`.
    #[inline(always)]
    fn new(ray: &Ray, widen: f32) -> RayBox {
        let inv = ray.inv_dir();
        let octant = (ray.dir.x < 0.0) as u32
            | ((ray.dir.y < 0.0) as u32) << 1
            | ((ray.dir.z < 0.0) as u32) << 2;
        RayBox {
            origin: ray.origin,
            inv,
            tmin: ray.tmin,
            widen,
            parallel: inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any(),
            // Built for every ray (one set-up, no branch); never used for a parallel one.
            slab4: SlabRay4::new(ray.origin, inv, ray.tmin, widen),
            neg: [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0],
            oct_inv: (WIDTH as u32 - 1) ^ octant,
        }
    }

    /// Bit s set: slot s's box (used or not) is entered before `prune`.
    #[inline(always)]
    fn entered(&self, node: &CwNode, prune: f32) -> u32 {
        if self.parallel {
            return (0..WIDTH).fold(0, |bits, s| {
                let (lo, hi) = node.child_box(s);
                let b = Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                };
                let hit = b.slab_hit(self.origin, self.inv, self.tmin, prune, self.widen);
                bits | (hit as u32) << s
            });
        }
        // Slots 0–3 and 4–7 in SIMD lanes: per lane the dequantisation p + q · step of
        // `CwNode::child_box` and the slab test of `SlabRay4`, which equal the scalar ones.
        let s = &self.slab4;
        let (p, step) = (Vec3A::from_array(node.p), step(node.e));
        let mut bits = 0;
        for half in 0..2 {
            let lanes = |q: &[[u8; WIDTH]; 3], axis: usize| {
                let b = &q[axis][4 * half..4 * half + 4];
                let q = Vec4::new(b[0] as f32, b[1] as f32, b[2] as f32, b[3] as f32);
                Vec4::splat(p[axis]) + q * Vec4::splat(step[axis])
            };
            let lo = [0, 1, 2].map(|a| lanes(&node.q_lo, a));
            let hi = [0, 1, 2].map(|a| lanes(&node.q_hi, a));
            let (enter, exit) = s.intervals(lo, hi, prune);
            bits |= enter.cmple(exit).bitmask() << (4 * half);
        }
        bits
    }

    /// [`RayBox::child_hits`] for a ray with no parallel axis, the eight slots in one AVX
    /// vector: per lane the same operations as `SlabRay4::intervals` on the planes
    /// `p + q · step`, in the same order (the max as `a > b ? a : b` and the min as
    /// `a < b ? a : b`, which is what `maxps` and `minps` compute), so the same slots entered; then each entered slot's hit-mask bits,
    /// ORed together.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt,bmi1,lzcnt")]
    #[inline]
    unsafe fn child_hits_avx2(&self, node: &CwNode, prune: f32) -> u32 {
        use std::arch::x86_64::*;
        // Eight bytes widened to eight lanes.
        let lanes =
            |b: &[u8; WIDTH]| _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(i64::from_le_bytes(*b)));
        let step = step(node.e);
        let planes = |q: &[u8; WIDTH], axis: usize| {
            let plane = _mm256_add_ps(
                _mm256_set1_ps(node.p[axis]),
                _mm256_mul_ps(_mm256_cvtepi32_ps(lanes(q)), _mm256_set1_ps(step[axis])),
            );
            let o = _mm256_set1_ps(self.origin[axis]);
            _mm256_mul_ps(_mm256_sub_ps(plane, o), _mm256_set1_ps(self.inv[axis]))
        };
        let (mut enter, mut exit) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        for axis in 0..3 {
            let (qa, qb) = match self.neg[axis] {
                true => (&node.q_hi[axis], &node.q_lo[axis]),
                false => (&node.q_lo[axis], &node.q_hi[axis]),
            };
            let (near, far) = (planes(qa, axis), planes(qb, axis));
            (enter, exit) = match axis {
                0 => (near, far),
                _ => (_mm256_max_ps(enter, near), _mm256_min_ps(exit, far)),
            };
        }
        let exit = _mm256_max_ps(
            _mm256_mul_ps(exit, _mm256_set1_ps(self.widen)),
            _mm256_mul_ps(exit, _mm256_set1_ps(2.0 - self.widen)),
        );
        let enter = _mm256_max_ps(enter, _mm256_set1_ps(self.tmin));
        let exit = _mm256_min_ps(exit, _mm256_set1_ps(prune));
        let entered = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit));
        // Per slot, as the scalar loop: (m >> COUNT_SHIFT) << ((m & INDEX_MASK) ^ (oct_inv
        // if internal)), kept where the slot is entered.
        let slot = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let inner = _mm256_and_si256(
            _mm256_srlv_epi32(_mm256_set1_epi32(node.imask as i32), slot),
            _mm256_set1_epi32(1),
        );
        let flip = _mm256_mullo_epi32(inner, _mm256_set1_epi32(self.oct_inv as i32));
        let m = lanes(&node.child_meta);
        let shift = _mm256_xor_si256(
            _mm256_and_si256(m, _mm256_set1_epi32(INDEX_MASK as i32)),
            flip,
        );
        let bits = _mm256_sllv_epi32(_mm256_srli_epi32::<{ COUNT_SHIFT as i32 }>(m), shift);
        let bits = _mm256_and_si256(bits, entered);
        let four = _mm_or_si128(
            _mm256_castsi256_si128(bits),
            _mm256_extracti128_si256::<1>(bits),
        );
        let two = _mm_or_si128(four, _mm_unpackhi_epi64(four, four));
        let one = _mm_or_si128(two, _mm_shuffle_epi32::<0b01>(two));
        _mm_cvtsi128_si32(one) as u32
    }

    /// The hit mask of `node`'s children whose boxes the ray enters before `prune`:
    /// internal children at bit TRI_BITS + (slot ^ oct_inv), leaf triangles at their offsets.
    #[inline(always)]
    fn child_hits<const AVX2: bool>(&self, node: &CwNode, prune: f32) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if AVX2 && !self.parallel {
            // SAFETY: `AVX2` is true only below `intersect_avx2` and
            // `interleave::trace_chunk_avx2`, which run only where `has_avx2()` said the CPU
            // has it.
            return unsafe { self.child_hits_avx2(node, prune) };
        }
        let mut entered = self.entered(node, prune);
        let mut hits = 0;
        while entered != 0 {
            let s = entered.trailing_zeros() as usize;
            entered &= entered - 1;
            // An empty slot (meta 0) adds nothing.
            let m = node.child_meta[s] as u32;
            let inner = (node.imask as u32 >> s) & 1;
            hits |= (m >> COUNT_SHIFT) << ((m & INDEX_MASK) ^ (self.oct_inv * inner));
        }
        hits
    }
}

impl Cwbvh {
    /// [`Accel::intersect_pruned`] with the node test in SSE (`AVX2` false: the target's
    /// baseline) or AVX2 lanes. `AVX2` true is for `intersect_avx2` alone (and, for
    /// batches, `interleave::trace_chunk_avx2`): the AVX2 code it reaches needs the CPU to
    /// have AVX2.
    #[inline(always)]
    fn intersect_with<const AVX2: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        // One specialised loop per triangle test (the choice is not re-made per triangle).
        with_leaf_test!(
            robustness,
            self.walk::<_, AVX2>(ray, query, robustness, mask, stats)
        )
    }

    /// [`Accel::intersect_pruned`] compiled with AVX2 (and the bit instructions every AVX2 CPU
    /// has); the CPU must have them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt,bmi1,lzcnt")]
    unsafe fn intersect_avx2(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        self.intersect_with::<true>(ray, query, robustness, mask, stats)
    }

    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8, const AVX2: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> (Hit, f32) {
        let mut w = Walk::<TEST, AVX2>::idle(self, query, robustness, mask);
        if w.start(ray) {
            while !w.step(stats) {}
        }
        (w.best, w.prune)
    }
}

impl ChunkWalk for Cwbvh {
    /// [`Accel::trace_hits`] on one chunk of rays, [`Cwbvh::walk`] for a few at once.
    #[inline(always)]
    fn walk_chunk<const TEST: u8, const AVX2: bool>(
        &self,
        rays: &[Ray],
        out: &mut [Hit],
        query: Query,
        robustness: &Robustness,
    ) {
        let walks = [(); WALKS].map(|_| Walk::<TEST, AVX2>::idle(self, query, robustness, None));
        walk_interleaved(rays, out, walks);
    }
}

/// One ray's traversal of `cw`, a node step at a time ([`Stepper`]), with the triangle
/// test `TEST` and the node test in SSE or AVX2 lanes (`AVX2` true only where the CPU has
/// AVX2). The two-level twin walks its cwbvh bottom levels with it ([`Walk::begin`]).
pub(crate) struct Walk<'a, const TEST: u8, const AVX2: bool> {
    cw: &'a Cwbvh,
    /// The ray's leaf-step set-up.
    leaf: LeafRay<'a>,
    /// Its child-test set-up.
    rb: RayBox,
    /// An any-hit query.
    any: bool,
    /// The closest hit so far.
    best: Hit,
    /// Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
    /// exactly the best t in a later box is still tested: equal t → smaller index.
    prune: f32,
    /// Pushed groups. Not zeroed (512 bytes): an entry is read only below `sp`, where it
    /// was written.
    stack: [MaybeUninit<[u32; 2]>; STACK_SIZE],
    sp: usize,
    /// The group: [first child node, hit internal children (high byte) | imask]. Before a
    /// step it always holds a node: first the root, alone in the top bit.
    group: [u32; 2],
}

impl<'a, const TEST: u8, const AVX2: bool> Walk<'a, TEST, AVX2> {
    /// A walk with no ray yet, answering `query` under `robustness`, hits tested by `mask`.
    #[inline(always)]
    pub(crate) fn idle(
        cw: &'a Cwbvh,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'a>,
    ) -> Self {
        Walk {
            cw,
            leaf: LeafRay::new(&IDLE_RAY, robustness, mask),
            rb: RayBox::new(&IDLE_RAY, robustness.far_widen()),
            any: query == Query::Any,
            best: Hit::miss(0.0),
            prune: 0.0,
            stack: [MaybeUninit::uninit(); STACK_SIZE],
            sp: 0,
            group: [0, 0],
        }
    }

    /// Begins the walk of `ray` through `cw` instead (a two-level walk entering an
    /// instance): false when there is nothing to walk (an invalid ray: the answer, a miss,
    /// is then ready).
    #[inline(always)]
    pub(crate) fn begin(&mut self, cw: &'a Cwbvh, ray: &Ray) -> bool {
        self.cw = cw;
        self.start(ray)
    }

    /// The answer and the prune bound of its hit, once the walk has ended (what
    /// `intersect_pruned` returns).
    #[inline(always)]
    pub(crate) fn answer(&self) -> (Hit, f32) {
        (self.best, self.prune)
    }
}

impl<const TEST: u8, const AVX2: bool> Stepper for Walk<'_, TEST, AVX2> {
    #[inline(always)]
    fn start(&mut self, ray: &Ray) -> bool {
        self.best = Hit::miss(ray.tmax);
        if !ray.is_valid() {
            return false;
        }
        self.leaf.reset(ray);
        // The widening is the batch's robustness setting, kept from the last set-up.
        self.rb = RayBox::new(ray, self.rb.widen);
        self.prune = prune_bound(self.best.t);
        self.sp = 0;
        self.group = [0, 1 << 31];
        true
    }

    /// Visits the group's next node and tests its hit leaf triangles.
    #[inline(always)]
    fn step(&mut self, stats: &mut RayStats) -> bool {
        let cw = self.cw;
        let group = &mut self.group;
        let bit = 31 - group[1].leading_zeros();
        group[1] &= !(1 << bit);
        if group[1] & NODE_BITS != 0 {
            self.stack[self.sp].write(*group);
            self.sp += 1;
        }
        let slot = (bit - TRI_BITS) ^ self.rb.oct_inv;
        let idx = group[0] + (group[1] & ((1 << slot) - 1)).count_ones();
        let node = &cw.nodes[idx as usize];
        stats.nodes += 1;
        let hits = self.rb.child_hits::<AVX2>(node, self.prune);
        *group = [node.child_base, (hits & NODE_BITS) | node.imask as u32];
        // The hit leaf triangles, lowest bit first, tested as one leaf (`test_leaf`):
        // in place when they are one run (a leaf's triangles are hit all together, so one
        // hit leaf is one run), else gathered.
        let mut tri_hits = hits & TRI_MASK;
        if tri_hits != 0 {
            let first = tri_hits.trailing_zeros();
            let run = tri_hits >> first;
            let mut gathered = [MaybeUninit::<LeafTri>::uninit(); TRI_BITS as usize];
            let tris = if run & (run + 1) == 0 {
                let start = (node.tri_base + first) as usize;
                &cw.tris[start..start + run.trailing_ones() as usize]
            } else {
                let mut n = 0;
                while tri_hits != 0 {
                    let b = tri_hits.trailing_zeros();
                    tri_hits &= tri_hits - 1;
                    gathered[n].write(cw.tris[(node.tri_base + b) as usize]);
                    n += 1;
                }
                // SAFETY: the first n entries were written just above.
                unsafe { std::slice::from_raw_parts(gathered.as_ptr().cast(), n) }
            };
            let (best, prune) = (&mut self.best, &mut self.prune);
            if self
                .leaf
                .test_leaf::<TEST>(tris, self.any, best, prune, stats)
            {
                return true;
            }
        }
        if group[1] & NODE_BITS == 0 {
            if self.sp == 0 {
                debug_assert!(self.best.prim == MISS || self.best.t >= self.leaf.ray.tmin);
                return true;
            }
            self.sp -= 1;
            // SAFETY: every entry below the stack pointer was written by a push.
            *group = unsafe { self.stack[self.sp].assume_init() };
        }
        false
    }

    #[inline(always)]
    fn best(&self) -> Hit {
        self.best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh::build;
    #[cfg(target_arch = "x86_64")]
    use crate::accel::bvh::layouts::has_avx2;
    #[cfg(target_arch = "x86_64")]
    use crate::accel::bvh::layouts::interleave::trace_chunk_avx2;
    use crate::accel::bvh::layouts::interleave::trace_chunk_with;
    use crate::geometry::Triangle;
    use crate::mesh::Mesh;

    /// The AVX2 build (where this CPU has it) and the baseline build answer and count
    /// work alike, ray for ray, walked alone or two at a time, under every robustness
    /// setting that changes the walk.
    #[test]
    fn avx2_and_baseline_builds_agree() {
        #[cfg(target_arch = "x86_64")]
        let avx2 = has_avx2();
        // A lattice of tilted triangles, and rays from a pseudo-random walk around it,
        // a few parallel to an axis.
        let tris = (0..2000)
            .map(|i| {
                let c = Vec3::new((i % 20) as f32, (i / 20 % 10) as f32, (i / 200) as f32);
                Triangle::new(
                    c,
                    c + Vec3::new(0.9, 0.1, 0.3),
                    c + Vec3::new(0.2, 0.8, -0.4),
                )
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let cw = Cwbvh::flatten(&build(&mesh, &Default::default()), &mesh);
        let mut seed = 1u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1 << 24) as f32
        };
        let rays: Vec<Ray> = (0..3000)
            .map(|i| {
                let o = Vec3::new(
                    next() * 30.0 - 5.0,
                    next() * 20.0 - 5.0,
                    next() * 20.0 - 5.0,
                );
                let mut d = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
                if i % 10 == 0 {
                    d[i / 10 % 3] = 0.0;
                }
                Ray::new(o, d, 0.0, 1e4)
            })
            .collect();
        let robust = Robustness::default();
        let settings = [
            robust,
            Robustness {
                triangle_test: crate::geometry::TriangleTest::MollerTrumbore,
                ..robust
            },
            Robustness {
                slab_test: crate::geometry::SlabTest::Plain,
                ..robust
            },
            Robustness {
                precision: crate::geometry::Precision::F64,
                ..robust
            },
        ];
        let b = bytemuck::bytes_of::<Hit>;
        for rob in &settings {
            for query in [Query::Closest, Query::Any] {
                let mut chunk = vec![Hit::miss(0.0); rays.len()];
                trace_chunk_with::<_, false>(&cw, &rays, &mut chunk, query, rob);
                #[cfg(target_arch = "x86_64")]
                let mut chunk_avx2 = chunk.clone();
                #[cfg(target_arch = "x86_64")]
                if avx2 {
                    // SAFETY: the CPU has AVX2.
                    unsafe { trace_chunk_avx2(&cw, &rays, &mut chunk_avx2, query, rob) };
                }
                let mut hits = 0;
                for (i, r) in rays.iter().enumerate() {
                    let mut s = RayStats::default();
                    let (h, prune) = cw.intersect_with::<false>(r, query, rob, None, &mut s);
                    assert_eq!(b(&h), b(&chunk[i]), "ray {i}, two at a time: {r:?}");
                    #[cfg(target_arch = "x86_64")]
                    if avx2 {
                        let mut s2 = RayStats::default();
                        // SAFETY: as above.
                        let (h2, prune2) =
                            unsafe { cw.intersect_avx2(r, query, rob, None, &mut s2) };
                        assert_eq!(b(&h), b(&h2), "ray {i}, AVX2: {r:?}");
                        if h.prim != MISS {
                            assert_eq!(prune.to_bits(), prune2.to_bits(), "ray {i}, AVX2 prune");
                        }
                        assert_eq!(s, s2, "ray {i}, AVX2 work: {r:?}");
                        assert_eq!(b(&h), b(&chunk_avx2[i]), "ray {i}, AVX2 two at a time");
                    }
                    hits += (h.prim != MISS) as usize;
                }
                assert!(hits > 300, "{rob:?} {query:?}: {hits} hits");
            }
        }
    }
}
