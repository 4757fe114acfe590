//! The triangle tests' decision for four triangles at once, for the CPU twins' leaves: one
//! SIMD lane per triangle. Lane k does what [`intersect_watertight_bounded`] (or
//! [`intersect_moller_trumbore`]) does for triangle k up to its verdict (the same operations
//! on the same operands in the same order, none fused), so its "may hit" is exactly the
//! single test's `Some`. For the watertight test the lanes that pass also give their hits
//! and error bounds ([`Watertight4::hits`], computed as the single test computes them), so
//! the twins run the single test only where a bound reaches back past the origin (rare);
//! for Möller–Trumbore they run it again for the few lanes that pass. Either way the result
//! is the sequential loop's, bit for bit, at a fraction of its cost (the lanes' hits gave
//! bvh4's twin 1.1x the rays/s on the bunny's primary rays that hit). Both tests have the
//! verdict, so that `bench accuracy` prices them alike.

use glam::{Vec3, Vec4};

use super::triangle::t_error_numerator;
use super::WatertightRay;
use super::TIE_SLACK;
#[cfg(doc)]
use super::{intersect_moller_trumbore, intersect_watertight_bounded};

/// A ray and its watertight set-up splatted across four lanes once per ray.
#[derive(Clone, Copy, Debug)]
pub struct TriangleRay4 {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
    /// The shear `(s.x, s.y, s.z)` of [`WatertightRay`].
    shear: [Vec4; 3],
    tmin: Vec4,
    /// Which of the six axis permutations the ray takes (an index into `PERMUTATIONS`).
    perm: u8,
}

/// The axis permutations `[kx, ky, kz]` [`WatertightRay::new`] can choose (the order
/// [`TriangleRay4::new`] indexes them in; `may_hit` names each as constants).
const PERMUTATIONS: [[usize; 3]; 6] = [
    [1, 2, 0],
    [2, 1, 0],
    [2, 0, 1],
    [0, 2, 1],
    [0, 1, 2],
    [1, 0, 2],
];

impl TriangleRay4 {
    /// The lanes for a ray from `origin` along `dir` with watertight set-up `wr`, whose hits
    /// must lie at or after `tmin`.
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3, wr: &WatertightRay, tmin: f32) -> TriangleRay4 {
        // PERMUTATIONS' order: two per dominant axis kz, the second with kx, ky swapped.
        let [kx, ky, kz] = wr.k;
        let perm = (2 * kz + (ky != (kx + 1) % 3) as usize) as u8;
        debug_assert_eq!(PERMUTATIONS[perm as usize], wr.k);
        TriangleRay4 {
            origin: [origin.x, origin.y, origin.z].map(Vec4::splat),
            dir: [dir.x, dir.y, dir.z].map(Vec4::splat),
            shear: [wr.s.x, wr.s.y, wr.s.z].map(Vec4::splat),
            tmin: Vec4::splat(tmin),
            perm,
        }
    }

    /// The lanes whose triangle the single watertight test hits within [tmin, `tmax`], as a
    /// bit set. `v[i][axis]` holds vertex i's coordinate on `axis` of the four triangles.
    #[inline(always)]
    pub fn watertight(&self, v: &[[Vec4; 3]; 3], tmax: f32) -> u32 {
        self.watertight_lanes(v, tmax).mask
    }

    /// [`TriangleRay4::watertight`] with the lanes' values kept, from which
    /// [`Watertight4::hits`] gives the passing lanes' hits.
    #[inline(always)]
    pub fn watertight_lanes(&self, v: &[[Vec4; 3]; 3], tmax: f32) -> Watertight4 {
        // The permutation as constants: a branch per call that a ray always takes the same
        // way, and no shuffling of coordinates per triangle.
        match self.perm {
            0 => self.may_hit_in::<1, 2, 0>(v, tmax),
            1 => self.may_hit_in::<2, 1, 0>(v, tmax),
            2 => self.may_hit_in::<2, 0, 1>(v, tmax),
            3 => self.may_hit_in::<0, 2, 1>(v, tmax),
            4 => self.may_hit_in::<0, 1, 2>(v, tmax),
            _ => self.may_hit_in::<1, 0, 2>(v, tmax),
        }
    }

    #[inline(always)]
    fn may_hit_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        v: &[[Vec4; 3]; 3],
        tmax: f32,
    ) -> Watertight4 {
        let [sx, sy, sz] = self.shear;
        // Vertex i relative to the origin, permuted, sheared: (x, y) and the unscaled z.
        let rel = |i: usize| {
            let p = [0, 1, 2].map(|axis| v[i][axis] - self.origin[axis]);
            [p[KX] - sx * p[KZ], p[KY] - sy * p[KZ], p[KZ]]
        };
        let (a, b, c) = (rel(0), rel(1), rel(2));
        let [ax, ay, _] = a;
        let [bx, by, _] = b;
        let [cx, cy, _] = c;
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = Vec4::ZERO;
        let negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
        let positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
        let det = u + v + w;
        let t = (u * (sz * a[2]) + v * (sz * b[2]) + w * (sz * c[2])) / det;
        let inside = !(negative & positive) & det.cmpne(zero);
        // Written so that a NaN t fails, as in the single test.
        let in_range = t.cmpge(self.tmin) & t.cmple(Vec4::splat(tmax));
        Watertight4 {
            mask: (inside & in_range).bitmask(),
            vertices: [a, b, c],
            sz,
            edges: [u, v, w],
            det,
            t,
        }
    }

    /// The lanes whose triangle the single Möller–Trumbore test hits within [tmin, `tmax`],
    /// as a bit set (`v` as for [`TriangleRay4::watertight`]).
    #[inline(always)]
    pub fn moller_trumbore(&self, v: &[[Vec4; 3]; 3], tmax: f32) -> u32 {
        // glam's cross and dot, operation for operation.
        let cross = |a: [Vec4; 3], b: [Vec4; 3]| {
            [
                a[1] * b[2] - b[1] * a[2],
                a[2] * b[0] - b[2] * a[0],
                a[0] * b[1] - b[0] * a[1],
            ]
        };
        let dot = |a: [Vec4; 3], b: [Vec4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let e1 = [0, 1, 2].map(|axis| v[1][axis] - v[0][axis]);
        let e2 = [0, 1, 2].map(|axis| v[2][axis] - v[0][axis]);
        let p = cross(self.dir, e2);
        let det = dot(e1, p);
        let inv = Vec4::ONE / det;
        let s = [0, 1, 2].map(|axis| self.origin[axis] - v[0][axis]);
        let u = dot(s, p) * inv;
        let q = cross(s, e1);
        let w = dot(self.dir, q) * inv;
        let t = dot(e2, q) * inv;
        let (zero, one) = (Vec4::ZERO, Vec4::ONE);
        // The single test's rejections, NaN handling included: u must be in [0, 1]; v is
        // rejected only when below 0 or past 1 − u; t must be in [tmin, tmax].
        let pass = det.cmpne(zero)
            & u.cmpge(zero)
            & u.cmple(one)
            & !(w.cmplt(zero) | (u + w).cmpgt(one))
            & t.cmpge(self.tmin)
            & t.cmple(Vec4::splat(tmax));
        pass.bitmask()
    }
}

/// The watertight test of four triangles up to its verdict ([`TriangleRay4::watertight_lanes`]),
/// with the values a passing lane's hit is made of.
#[derive(Clone, Copy, Debug)]
pub struct Watertight4 {
    /// The lanes the single test hits within its bounds, as a bit set.
    pub mask: u32,
    /// Per vertex: sheared x, y and the unscaled z (`(v − o)[kz]`).
    vertices: [[Vec4; 3]; 3],
    /// The shear's z scale, 1/d_kz.
    sz: Vec4,
    /// The edge functions u, v, w.
    edges: [Vec4; 3],
    det: Vec4,
    t: Vec4,
}

/// Four lanes' hits ([`Watertight4::hits`]): lane k is what [`intersect_watertight_bounded`]
/// returns for triangle k (for a lane in [`Watertight4::mask`]), but for `in_front`, which
/// is false: where `near[k]` (the bound reaches back past the origin) only the single test
/// can say.
#[derive(Clone, Copy, Debug)]
pub struct TriHits4 {
    /// Distance along the ray.
    pub t: [f32; 4],
    /// Barycentric weight of vertex 1.
    pub u: [f32; 4],
    /// Barycentric weight of vertex 2.
    pub v: [f32; 4],
    /// Numerator of the t error bound.
    pub err_num: [f32; 4],
    /// |det|.
    pub det: [f32; 4],
    /// [`TriHit::prune`](super::TriHit::prune).
    pub prune: [f32; 4],
    /// The lanes whose `in_front` the single test has to decide, as a bit set.
    pub near: u32,
}

impl Watertight4 {
    /// The lanes' hits, computed as the single test computes them once it has passed (the
    /// same operations on the same operands; maxima and minima of values that, in a
    /// passing lane, are never NaN).
    #[inline(always)]
    pub fn hits(&self) -> TriHits4 {
        let [a, b, c] = self.vertices;
        let [u, v, w] = self.edges;
        let sz = self.sz;
        let largest = |x: Vec4, y: Vec4, z: Vec4| x.abs().max(y.abs()).max(z.abs());
        let mx = largest(a[0], b[0], c[0]);
        let my = largest(a[1], b[1], c[1]);
        let mz = largest(sz * a[2], sz * b[2], sz * c[2]);
        let mzu = largest(a[2], b[2], c[2]);
        let me = largest(u, v, w);
        let err_num = t_error_numerator(mx, my, mz, mzu, me);
        let det = self.det.abs();
        // TriHit::t_error and prune_bound, lane for lane (of values that are not NaN).
        let big = (err_num * Vec4::splat(1e-30)).cmpge(det);
        let t_error = Vec4::select(big, Vec4::splat(1e30), err_num / det);
        let b = (self.t + t_error).min(Vec4::splat(f32::MAX));
        let a = b.abs();
        let prune = b + (a * Vec4::splat(TIE_SLACK)).min(Vec4::splat(f32::MAX) - a);
        TriHits4 {
            t: self.t.to_array(),
            u: (v / self.det).to_array(),
            v: (w / self.det).to_array(),
            err_num: err_num.to_array(),
            det: det.to_array(),
            prune: prune.to_array(),
            near: (self.t.abs() * det).cmple(err_num).bitmask(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{
        intersect_moller_trumbore, intersect_watertight_bounded, Ray, TriHit, Triangle,
    };

    /// Four triangles' vertices in lanes.
    fn lanes(tris: &[Triangle; 4]) -> [[Vec4; 3]; 3] {
        [0, 1, 2].map(|i| [0, 1, 2].map(|axis| Vec4::from_array(tris.map(|t| t.v[i][axis]))))
    }

    /// Lane k of `hits` is the single test's hit `one` bit for bit (but `in_front`, which
    /// the lanes leave to the single test where `near` says the bound reaches the origin).
    fn lane_is_hit(hits: &TriHits4, k: usize, one: Option<TriHit>) -> Result<(), String> {
        let Some(h) = one else {
            return Ok(());
        };
        let lane = [
            hits.t[k],
            hits.u[k],
            hits.v[k],
            hits.err_num[k],
            hits.det[k],
            hits.prune[k],
        ];
        let single = [h.t, h.u, h.v, h.err_num, h.det, h.prune()];
        if lane.map(f32::to_bits) != single.map(f32::to_bits) {
            return Err(format!("lane {k}: {lane:?}, single test {single:?}"));
        }
        let near = h.t.abs() * h.det <= h.err_num;
        if (hits.near >> k & 1 != 0) != near || (h.in_front && !near) {
            return Err(format!(
                "lane {k}: near {}, single test {h:?}",
                hits.near >> k & 1
            ));
        }
        Ok(())
    }

    #[test]
    fn permutation_index_names_the_ray_s_permutation() {
        for d in [
            Vec3::X,
            Vec3::NEG_X,
            Vec3::Y,
            Vec3::NEG_Y,
            Vec3::Z,
            Vec3::NEG_Z,
        ] {
            let wr = WatertightRay::new(d);
            let w4 = TriangleRay4::new(Vec3::ZERO, d, &wr, 0.0);
            assert_eq!(PERMUTATIONS[w4.perm as usize], wr.k, "direction {d}");
        }
    }

    #[test]
    fn lanes_equal_the_single_test_for_every_permutation() {
        // Hits, misses, an edge and a vertex hit exactly, a degenerate and a parallel
        // triangle, one behind and one past tmax, in every lane position.
        let tris = [
            Triangle::new(
                Vec3::new(-1.0, -1.0, 5.0),
                Vec3::new(1.0, -1.0, 5.0),
                Vec3::new(0.0, 1.0, 5.0),
            ),
            Triangle::new(
                Vec3::new(0.0, 0.0, 3.0),
                Vec3::new(1.0, 0.0, 3.0),
                Vec3::new(0.0, 1.0, 3.0),
            ),
            Triangle::new(
                Vec3::new(2.0, 2.0, 1.0),
                Vec3::new(3.0, 2.0, 1.0),
                Vec3::new(2.0, 3.0, 1.0),
            ),
            Triangle::new(
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(3.0, 0.0, 0.0),
            ),
            Triangle::new(
                Vec3::new(-1.0, -1.0, -4.0),
                Vec3::new(1.0, -1.0, -4.0),
                Vec3::new(0.0, 1.0, -4.0),
            ),
            Triangle::new(
                Vec3::new(-1.0, -1.0, 90.0),
                Vec3::new(1.0, -1.0, 90.0),
                Vec3::new(0.0, 1.0, 90.0),
            ),
            Triangle::new(
                Vec3::new(0.0, -1.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(0.0, 0.0, 9.0),
            ),
            Triangle::new(
                Vec3::new(0.1, 0.2, 7.0),
                Vec3::new(-3.0, 0.5, 6.0),
                Vec3::new(0.4, -2.0, 8.0),
            ),
        ];
        let dirs = [
            Vec3::Z,
            Vec3::NEG_Z,
            Vec3::new(0.1, 0.05, 1.0),
            Vec3::new(1.0, 0.2, 0.3),
            Vec3::new(-1.0, 0.2, 0.3),
            Vec3::new(0.2, 1.0, -0.3),
            Vec3::new(0.2, -1.0, -0.3),
            Vec3::new(f32::NAN, 0.0, 1.0),
        ];
        let origins = [
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, -2.0),
            Vec3::new(0.3, -0.1, 0.5),
        ];
        for o in origins {
            for d in dirs {
                let wr = WatertightRay::new(d);
                let w4 = TriangleRay4::new(o, d, &wr, 0.0);
                let ray = Ray::new(o, d, 0.0, f32::INFINITY);
                for start in 0..tris.len() {
                    let four = [0, 1, 2, 3].map(|k| tris[(start + k) % tris.len()]);
                    for tmax in [50.0, f32::INFINITY] {
                        let got = w4.watertight(&lanes(&four), tmax);
                        let hits = w4.watertight_lanes(&lanes(&four), tmax).hits();
                        let mt = w4.moller_trumbore(&lanes(&four), tmax);
                        for (k, t) in four.iter().enumerate() {
                            let one = intersect_watertight_bounded(t, o, &wr, 0.0, tmax);
                            if let Err(e) = lane_is_hit(&hits, k, one) {
                                panic!("{e}, origin {o}, dir {d}");
                            }
                            let one = one.is_some();
                            assert_eq!(got >> k & 1 != 0, one, "lane {k}, origin {o}, dir {d}");
                            let one = intersect_moller_trumbore(t, &ray, 0.0, tmax).is_some();
                            assert_eq!(mt >> k & 1 != 0, one, "MT lane {k}, origin {o}, dir {d}");
                        }
                    }
                }
            }
        }
    }

    proptest::proptest! {
        /// Random triangles around a random ray (about half of them hit): lane k's verdict
        /// is the single test's, wherever the triangle sits among the four.
        #[test]
        fn random_lanes_equal_the_single_test(
            o in proptest::array::uniform3(-2.0f32..2.0),
            d in proptest::array::uniform3(-1.0f32..1.0),
            v in proptest::array::uniform4(proptest::array::uniform3(proptest::array::uniform3(-3.0f32..3.0))),
            tmax in 0.5f32..8.0,
        ) {
            let (o, d) = (Vec3::from(o), Vec3::from(d));
            proptest::prop_assume!(d != Vec3::ZERO);
            let wr = WatertightRay::new(d);
            // Triangles around the point 2 units along the ray.
            let at = o + 2.0 * d;
            let four = v.map(|t| Triangle::new(at + Vec3::from(t[0]), at + Vec3::from(t[1]), at + Vec3::from(t[2])));
            let r4 = TriangleRay4::new(o, d, &wr, 0.0);
            let got = r4.watertight(&lanes(&four), tmax);
            let hits = r4.watertight_lanes(&lanes(&four), tmax).hits();
            let mt = r4.moller_trumbore(&lanes(&four), tmax);
            let ray = Ray::new(o, d, 0.0, f32::INFINITY);
            for (k, t) in four.iter().enumerate() {
                let one = intersect_watertight_bounded(t, o, &wr, 0.0, tmax);
                proptest::prop_assert!(lane_is_hit(&hits, k, one).is_ok(), "{:?}", lane_is_hit(&hits, k, one));
                let one = one.is_some();
                proptest::prop_assert_eq!(got >> k & 1 != 0, one, "lane {}", k);
                let one = intersect_moller_trumbore(t, &ray, 0.0, tmax).is_some();
                proptest::prop_assert_eq!(mt >> k & 1 != 0, one, "MT lane {}", k);
            }
        }
    }
}
