//! The triangle array every layout shares: triangles in leaf order, each with its original
//! index (WGSL `Tri` and `load_tri` in `shaders/lib/traversal.wgsl`).

use glam::{Mat4, Vec4};
use rayon::prelude::*;

use crate::accel::bvh::Bvh;
use crate::accel::{Mask, RayStats};
use crate::geometry::{
    intersect_triangle_bounded, Hit, Ray, Robustness, TriHit, TriHits4, Triangle, TriangleRay4,
    TriangleTest, WatertightRay,
};
use crate::mesh::Mesh;

/// One triangle, 48 bytes: three vertices, the original index in v0's slot w.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LeafTri {
    /// Vertex 0.
    pub v0: [f32; 3],
    /// Original (file-order) triangle index.
    pub prim: u32,
    /// Vertex 1.
    pub v1: [f32; 3],
    /// Padding (zero).
    pub pad1: u32,
    /// Vertex 2.
    pub v2: [f32; 3],
    /// Padding (zero).
    pub pad2: u32,
}

impl LeafTri {
    /// Triangle `prim` with vertices `v`.
    pub fn new(v: [glam::Vec3; 3], prim: u32) -> LeafTri {
        LeafTri {
            v0: v[0].into(),
            prim,
            v1: v[1].into(),
            pad1: 0,
            v2: v[2].into(),
            pad2: 0,
        }
    }

    /// The triangle's vertices.
    #[inline(always)]
    pub fn triangle(&self) -> Triangle {
        Triangle::new(self.v0.into(), self.v1.into(), self.v2.into())
    }

    /// The triangles of `bvh`'s leaves, in leaf order (in parallel).
    /// Allocated with room for a device to read them in place (see
    /// [`ROOM_BYTES`](super::ROOM_BYTES)).
    pub fn gather(bvh: &Bvh, mesh: &Mesh) -> Vec<LeafTri> {
        let mut tris =
            Vec::with_capacity(super::gpu_form::capacity_for::<LeafTri>(bvh.order.len()));
        tris.par_extend(
            (bvh.order.par_iter()).map(|&id| LeafTri::new(mesh.triangles[id as usize].v, id)),
        );
        tris
    }
}

/// The triangle tests a twin's traversal is specialised for (a const generic: the choice is
/// not re-made per triangle).
pub(crate) mod leaf_test {
    use crate::geometry::{Precision, Robustness, TriangleTest};

    /// The watertight test (f32).
    pub const WATERTIGHT: u8 = 0;
    /// Möller–Trumbore (f32).
    pub const MOLLER_TRUMBORE: u8 = 1;
    /// The f64 oracle's test ([`Precision::F64`]).
    pub const F64: u8 = 2;

    /// The test `robustness` asks for.
    #[inline(always)]
    pub fn of(robustness: &Robustness) -> u8 {
        match (robustness.precision, robustness.triangle_test) {
            (Precision::F64, _) => F64,
            (_, TriangleTest::Watertight) => WATERTIGHT,
            (_, TriangleTest::MollerTrumbore) => MOLLER_TRUMBORE,
        }
    }
}

/// Calls `$walk::<TEST>($args)` with the const triangle test `robustness` asks for
/// (`$walk::<TEST, $more>` when the call names one more const argument as `::<_, $more>`).
macro_rules! with_leaf_test {
    (@ $robustness:expr, $self:ident . $walk:ident [$($more:ident)?] ( $($arg:expr),* )) => {{
        use $crate::accel::leaf_tri::leaf_test;
        match leaf_test::of($robustness) {
            leaf_test::F64 => $self.$walk::<{ leaf_test::F64 } $(, $more)?>($($arg),*),
            leaf_test::MOLLER_TRUMBORE => {
                $self.$walk::<{ leaf_test::MOLLER_TRUMBORE } $(, $more)?>($($arg),*)
            }
            _ => $self.$walk::<{ leaf_test::WATERTIGHT } $(, $more)?>($($arg),*),
        }
    }};
    ($robustness:expr, $self:ident . $walk:ident ( $($arg:expr),* )) => {
        $crate::accel::leaf_tri::with_leaf_test!(@ $robustness, $self.$walk [] ($($arg),*))
    };
    ($robustness:expr, $self:ident . $walk:ident ::<_, $more:ident> ( $($arg:expr),* )) => {
        $crate::accel::leaf_tri::with_leaf_test!(@ $robustness, $self.$walk [$more] ($($arg),*))
    };
}
pub(crate) use with_leaf_test;

/// The two tracing methods of a BVH layout's [`Accel`](crate::accel::Accel) impl:
/// `intersect_pruned`, the hit and its prune bound, and `intersect_masked`, which keeps the
/// hit. `walk_accel_methods!()` runs the layout's
/// `walk::<TEST>(ray, query, robustness, mask, stats) -> (Hit, f32)` with the triangle test
/// `robustness` asks for (one specialised loop per test, the choice not re-made per
/// triangle); `walk_accel_methods!(avx2)` runs its `intersect_avx2` where the CPU has AVX2,
/// else its `intersect_with::<false>` (both returning `(Hit, f32)`).
macro_rules! walk_accel_methods {
    (@methods |$s:ident, $ray:ident, $query:ident, $rob:ident, $mask:ident, $stats:ident| $pruned:block) => {
        #[inline]
        fn intersect_masked(
            &self,
            ray: &$crate::geometry::Ray,
            query: $crate::accel::Query,
            robustness: &$crate::geometry::Robustness,
            mask: $crate::accel::Mask<'_>,
            stats: &mut $crate::accel::RayStats,
        ) -> $crate::geometry::Hit {
            self.intersect_pruned(ray, query, robustness, mask, stats).0
        }

        #[inline]
        fn intersect_pruned(
            &$s,
            $ray: &$crate::geometry::Ray,
            $query: $crate::accel::Query,
            $rob: &$crate::geometry::Robustness,
            $mask: $crate::accel::Mask<'_>,
            $stats: &mut $crate::accel::RayStats,
        ) -> ($crate::geometry::Hit, Option<f32>) {
            let (hit, prune) = $pruned;
            (hit, Some(prune))
        }
    };
    () => {
        $crate::accel::leaf_tri::walk_accel_methods!(@methods
            |self, ray, query, robustness, mask, stats| {
                $crate::accel::leaf_tri::with_leaf_test!(
                    robustness,
                    self.walk(ray, query, robustness, mask, stats)
                )
            });
    };
    (avx2) => {
        $crate::accel::leaf_tri::walk_accel_methods!(@methods
            |self, ray, query, robustness, mask, stats| {
                #[cfg(target_arch = "x86_64")]
                if $crate::accel::bvh::layouts::has_avx2() {
                    // SAFETY: the CPU has AVX2.
                    unsafe { self.intersect_avx2(ray, query, robustness, mask, stats) }
                } else {
                    self.intersect_with::<false>(ray, query, robustness, mask, stats)
                }
                #[cfg(not(target_arch = "x86_64"))]
                self.intersect_with::<false>(ray, query, robustness, mask, stats)
            });
    };
}
pub(crate) use walk_accel_methods;

/// One ray's fixed state in a twin's leaf step: the triangle test's ray set-up and whether
/// near hits are rejected (see [`Robustness::rejects_near_hits`]).
pub(crate) struct LeafRay<'a> {
    /// The ray (a copy: a two-level walk sets up each instance's object-space ray here).
    pub ray: Ray,
    /// Its watertight set-up.
    pub wr: WatertightRay,
    /// The ray and its set-up in four lanes (the triangle tests' verdict for four triangles
    /// at once).
    pub ray4: TriangleRay4,
    /// Whether a hit that may lie behind the origin is dropped (for this ray).
    pub reject_near: bool,
    /// The settings, for the next ray's `reject_near`.
    robustness: Robustness,
    /// The alpha mask a hit must pass ([`crate::accel::HitMask`]), if any.
    mask: Mask<'a>,
}

/// Triangles tested at once by the four-lane verdicts ([`TriangleRay4`]).
const LANES: usize = 4;

/// One to four triangles' vertices in lanes (`v[i][axis]`, lane k = `tris[k]`; lanes past
/// the end repeat the last triangle): each vertex row loaded whole and transposed. `tris`
/// is a chunk of a leaf (`chunks` yields no empty one).
#[inline(always)]
fn lanes(tris: &[LeafTri]) -> [[Vec4; 3]; 3] {
    let last = tris.len() - 1;
    let rows = [0, 1, 2, 3].map(|k| {
        let t: [[f32; 4]; 3] = bytemuck::cast(tris[k.min(last)]);
        t.map(Vec4::from_array)
    });
    [0, 1, 2].map(|i| {
        let m = Mat4::from_cols(rows[0][i], rows[1][i], rows[2][i], rows[3][i]).transpose();
        [m.x_axis, m.y_axis, m.z_axis]
    })
}

impl<'a> LeafRay<'a> {
    /// The set-up for `ray` under `robustness`, hits tested by `mask`.
    #[inline(always)]
    pub fn new(ray: &Ray, robustness: &Robustness, mask: Mask<'a>) -> Self {
        let wr = WatertightRay::new(ray.dir);
        LeafRay {
            ray: *ray,
            wr,
            ray4: TriangleRay4::new(ray.origin, ray.dir, &wr, ray.tmin),
            reject_near: robustness.rejects_near_hits_of(ray),
            robustness: *robustness,
            mask,
        }
    }

    /// The same set-up for another ray (the robustness settings kept).
    #[inline(always)]
    pub fn reset(&mut self, ray: &Ray) {
        self.ray = *ray;
        self.wr = WatertightRay::new(ray.dir);
        self.ray4 = TriangleRay4::new(ray.origin, ray.dir, &self.wr, ray.tmin);
        self.reject_near = self.robustness.rejects_near_hits_of(ray);
    }

    /// The leaf step every twin takes (WGSL `test_leaf` in shaders/lib/traversal.wgsl):
    /// tests `tris` in order with the test `TEST` ([`leaf_test`]); a hit
    /// that beats `best` by the tie rule replaces it and moves `prune`. Returns true when an
    /// any-hit query is answered (the traversal ends).
    ///
    /// The f32 triangle tests first take their verdict on four triangles at once
    /// ([`TriangleRay4`], lane for lane the single test's) against the best t on entry,
    /// then takes those that may hit in order (the watertight test's hits from the lanes,
    /// `take_lane`; Möller–Trumbore's by the single test): a triangle the verdict rules out
    /// would miss against the smaller best t of the sequential loop too, so the result is
    /// the loop's.
    #[inline(always)]
    pub fn test_leaf<const TEST: u8>(
        &self,
        tris: &[LeafTri],
        any_hit: bool,
        best: &mut Hit,
        prune: &mut f32,
        stats: &mut RayStats,
    ) -> bool {
        if TEST == leaf_test::F64 {
            for lt in tris {
                stats.tris += 1;
                if self.test_one::<TEST>(lt, any_hit, best, prune) {
                    return true;
                }
            }
            return false;
        }
        for four in tris.chunks(LANES) {
            let all = (1u32 << four.len()) - 1;
            let v = lanes(four);
            if TEST == leaf_test::WATERTIGHT {
                let lanes = self.ray4.watertight_lanes(&v, best.t);
                let mut may = all & lanes.mask;
                if may != 0 {
                    let hits = lanes.hits();
                    while may != 0 {
                        let k = may.trailing_zeros() as usize;
                        may &= may - 1;
                        if self.take_lane(&hits, k, &four[k], any_hit, best, prune) {
                            stats.tris += k as u32 + 1;
                            return true;
                        }
                    }
                }
                stats.tris += four.len() as u32;
                continue;
            }
            let mut may = all & self.ray4.moller_trumbore(&v, best.t);
            while may != 0 {
                let k = may.trailing_zeros() as usize;
                may &= may - 1;
                if self.test_one::<TEST>(&four[k], any_hit, best, prune) {
                    stats.tris += k as u32 + 1;
                    return true;
                }
            }
            stats.tris += four.len() as u32;
        }
        false
    }

    /// [`LeafRay::test_one`] of the watertight test for lane k of `hits`, whose triangle
    /// `lt` passed the four-lane verdict against a best t at least the current one: the
    /// single test's hit is the lane's (its t is checked against the current best t, as
    /// the single test's bound), but where only the single test can decide `in_front`.
    #[inline(always)]
    fn take_lane(
        &self,
        hits: &TriHits4,
        k: usize,
        lt: &LeafTri,
        any_hit: bool,
        best: &mut Hit,
        prune: &mut f32,
    ) -> bool {
        if hits.near >> k & 1 != 0 {
            return self.test_one::<{ leaf_test::WATERTIGHT }>(lt, any_hit, best, prune);
        }
        let h = TriHit {
            t: hits.t[k],
            u: hits.u[k],
            v: hits.v[k],
            err_num: hits.err_num[k],
            det: hits.det[k],
            in_front: false,
        };
        // (Neither is NaN: the lane passed, and a best t never is.)
        if h.t > best.t {
            return false;
        }
        self.take(h, hits.prune[k], lt, any_hit, best, prune)
    }

    /// One triangle of the leaf step; true when an any-hit query is answered.
    #[inline(always)]
    fn test_one<const TEST: u8>(
        &self,
        lt: &LeafTri,
        any_hit: bool,
        best: &mut Hit,
        prune: &mut f32,
    ) -> bool {
        let test = if TEST == leaf_test::MOLLER_TRUMBORE {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        let ray = &self.ray;
        let tri = lt.triangle();
        let h = if TEST == leaf_test::F64 {
            crate::geometry::triangle_hit_f64(&tri, ray, ray.tmin, best.t)
        } else {
            intersect_triangle_bounded(test, &tri, ray, &self.wr, ray.tmin, best.t)
        };
        let Some(h) = h else {
            return false;
        };
        self.take(h, h.prune(), lt, any_hit, best, prune)
    }

    /// A triangle's hit `h` by the tie rule: whether it replaces `best` (and moves `prune`
    /// to `h_prune`, which is `h.prune()`); true when an any-hit query is answered.
    #[inline(always)]
    fn take(
        &self,
        h: TriHit,
        h_prune: f32,
        lt: &LeafTri,
        any_hit: bool,
        best: &mut Hit,
        prune: &mut f32,
    ) -> bool {
        if !Hit::beats(h.t, lt.prim, best.t, best.prim)
            || (self.reject_near && h.maybe_behind_origin())
            || self.mask.is_some_and(|m| !m.keeps(lt.prim, h.u, h.v))
        {
            return false;
        }
        *best = Hit {
            t: h.t,
            prim: lt.prim,
            u: h.u,
            v: h.v,
        };
        *prune = h_prune;
        any_hit
    }
}
