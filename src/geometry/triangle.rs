use glam::Vec3;

use super::{Aabb, Ray};

/// A triangle by its three vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// The vertices; a hit's `u` and `v` weight `v[1]` and `v[2]`.
    pub v: [Vec3; 3],
}

impl Triangle {
    /// The triangle with vertices `a`, `b`, `c`, in that order.
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
        Triangle { v: [a, b, c] }
    }

    /// Area (half the edge cross product's length), in f32.
    pub fn area(&self) -> f32 {
        0.5 * (self.v[1] - self.v[0])
            .cross(self.v[2] - self.v[0])
            .length()
    }

    /// Bounds of the three vertices.
    pub fn bbox(&self) -> Aabb {
        Aabb::from_points(&self.v)
    }

    /// Whether every vertex coordinate is finite (no NaN or ±∞).
    pub fn is_finite(&self) -> bool {
        self.v.iter().all(|p| p.is_finite())
    }

    /// Exactly zero area in f32 (coincident or collinear vertices): such a triangle can
    /// never be hit and is kept out of the BVH.
    pub fn is_degenerate(&self) -> bool {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0]) == Vec3::ZERO
    }
}

/// Which ray/triangle test the tracers run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum TriangleTest {
    /// Woop, Benthin & Wald 2013, "Watertight Ray/Triangle Intersection", JCGT 2(1).
    #[default]
    Watertight,
    /// Möller & Trumbore 1997: fewer operations, can leak through shared edges.
    MollerTrumbore,
}

/// Per-ray set-up of the watertight test: permute so that the dominant direction axis is
/// z, then shear so the ray becomes +z. The WGSL `watertight_setup` mirrors this.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    /// Axis permutation `[kx, ky, kz]`; `kz` is the direction's dominant axis.
    pub k: [usize; 3],
    /// Shear constants: `(d[kx] / d[kz], d[ky] / d[kz], 1 / d[kz])` for direction `d`.
    pub s: Vec3,
}

impl WatertightRay {
    /// The set-up for rays of direction `dir` (non-zero).
    pub fn new(dir: Vec3) -> WatertightRay {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding: swap when the dominant component is negative.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / dir[kz];
        WatertightRay {
            k: [kx, ky, kz],
            s: Vec3::new(dir[kx] * sz, dir[ky] * sz, sz),
        }
    }

    /// `(p[kx], p[ky], p[kz])`: an array lookup (indices masked into a 4-array, so no bounds
    /// check), not glam's per-component `match`, which put three branches per coordinate
    /// into the hot loop of every tracer.
    #[inline(always)]
    pub fn permute(&self, p: Vec3) -> [f32; 3] {
        let a = p.extend(0.0).to_array();
        self.k.map(|k| a[k & 3])
    }
}

/// Watertight test. Returns (t, u, v) when the hit lies in [tmin, tmax]; u and v weight
/// vertices 1 and 2. Edges shared by two triangles are tested with the same products in
/// opposite sign, so a ray through an edge hits at least one of them (no f64 fallback:
/// the GPU has none, and an exact zero is resolved by the sign rule on both sides alike).
#[inline(always)]
pub fn intersect_watertight(
    tri: &Triangle,
    origin: Vec3,
    wr: &WatertightRay,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    intersect_watertight_bounded(tri, origin, wr, tmin, tmax).map(|h| (h.t, h.u, h.v))
}

/// A triangle hit with what bounds its t's error: |t − t_exact| ≤ `err_num` / `det`
/// ([`t_error_bound`]), kept as a quotient so that the hot path divides only when it must.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Distance along the ray.
    pub t: f32,
    /// Barycentric weight of vertex 1.
    pub u: f32,
    /// Barycentric weight of vertex 2.
    pub v: f32,
    /// Numerator of the t error bound.
    pub err_num: f32,
    /// |det| of the watertight test, the bound's denominator.
    pub det: f32,
    /// A hit whose t error bound reaches back past the origin that is nonetheless proven in
    /// front of it ([`grazing_in_front`]); false for every other hit.
    pub in_front: bool,
}

impl TriHit {
    /// Whether the exact t may be ≤ 0 (the hit may lie at or behind the origin, as the
    /// surface a secondary ray leaves does): |t|·det ≤ err_num (no division), unless the
    /// hit is proven in front (a ray grazing a triangle far ahead, whose bound is loose).
    #[inline(always)]
    pub fn maybe_behind_origin(&self) -> bool {
        self.t.abs() * self.det <= self.err_num && !self.in_front
    }

    /// The bound boxes are cut against once this hit is the best:
    /// [`prune_bound`](super::prune_bound)`(t + t_error)`.
    #[inline(always)]
    pub fn prune(&self) -> f32 {
        super::prune_bound(self.t + self.t_error())
    }

    /// The bound on t's error, never infinite (past 1e30 it is 1e30).
    #[inline(always)]
    pub fn t_error(&self) -> f32 {
        if self.err_num * 1e-30 >= self.det {
            1e30
        } else {
            self.err_num / self.det
        }
    }
}

/// [`intersect_watertight`], also returning the bound on t's error, computed from the
/// test's own intermediate values (only for a hit). WGSL `intersect_watertight` is the same.
/// Always inlined: a call passes the triangle through memory, and its reload stalled on the
/// stores just made (a quarter of the test's time in a profile).
#[inline(always)]
pub fn intersect_watertight_bounded(
    tri: &Triangle,
    origin: Vec3,
    wr: &WatertightRay,
    tmin: f32,
    tmax: f32,
) -> Option<TriHit> {
    let a = wr.permute(tri.v[0] - origin);
    let b = wr.permute(tri.v[1] - origin);
    let c = wr.permute(tri.v[2] - origin);
    let ax = a[0] - wr.s.x * a[2];
    let ay = a[1] - wr.s.y * a[2];
    let bx = b[0] - wr.s.x * b[2];
    let by = b[1] - wr.s.y * b[2];
    let cx = c[0] - wr.s.x * c[2];
    let cy = c[1] - wr.s.y * c[2];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = wr.s.z * a[2];
    let bz = wr.s.z * b[2];
    let cz = wr.s.z * c[2];
    let tt = u * az + v * bz + w * cz;
    let t = tt / det;
    // Written so that a NaN t fails.
    if t >= tmin && t <= tmax {
        let mx = ax.abs().max(bx.abs()).max(cx.abs());
        let my = ay.abs().max(by.abs()).max(cy.abs());
        let mz = az.abs().max(bz.abs()).max(cz.abs());
        let mzu = a[2].abs().max(b[2].abs()).max(c[2].abs());
        let me = u.abs().max(v.abs()).max(w.abs());
        let err_num = t_error_numerator(mx, my, mz, mzu, me);
        // Only a hit whose bound reaches back past the origin needs the proof (rare).
        let in_front = t.abs() * det.abs() <= err_num
            && grazing_in_front(
                [ax, ay, a[2]],
                [bx, by, b[2]],
                [cx, cy, c[2]],
                wr.s.z,
                t,
                mzu,
            );
        Some(TriHit {
            t,
            u: v / det,
            v: w / det,
            err_num,
            det: det.abs(),
            in_front,
        })
    } else {
        None
    }
}

/// Möller–Trumbore, kept as the selectable cheaper alternative.
#[inline(always)]
pub fn intersect_moller_trumbore(
    tri: &Triangle,
    ray: &Ray,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    let e1 = tri.v[1] - tri.v[0];
    let e2 = tri.v[2] - tri.v[0];
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.v[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    if t >= tmin && t <= tmax {
        Some((t, u, v))
    } else {
        None
    }
}

/// The chosen triangle test with its t error bound (for Möller–Trumbore, the watertight
/// computation's bound, [`t_error_bound`]).
#[inline(always)]
pub fn intersect_triangle_bounded(
    test: TriangleTest,
    tri: &Triangle,
    ray: &Ray,
    wr: &WatertightRay,
    tmin: f32,
    tmax: f32,
) -> Option<TriHit> {
    match test {
        TriangleTest::Watertight => intersect_watertight_bounded(tri, ray.origin, wr, tmin, tmax),
        TriangleTest::MollerTrumbore => {
            intersect_moller_trumbore(tri, ray, tmin, tmax).map(|(t, u, v)| TriHit {
                t,
                u,
                v,
                // The watertight computation's bound, as a quotient over 1.
                err_num: t_error_bound(tri, ray.origin, wr),
                det: 1.0,
                in_front: false,
            })
        }
    }
}

/// The chosen triangle test, as every tracer calls it: `Some((t, u, v))` for a hit with
/// t in [tmin, tmax]. `wr` is the ray's watertight set-up (unused by Möller–Trumbore).
#[inline(always)]
pub fn intersect_triangle(
    test: TriangleTest,
    tri: &Triangle,
    ray: &Ray,
    wr: &WatertightRay,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    match test {
        TriangleTest::Watertight => intersect_watertight(tri, ray.origin, wr, tmin, tmax),
        TriangleTest::MollerTrumbore => intersect_moller_trumbore(tri, ray, tmin, tmax),
    }
}

/// γ(n) = n·ε / (1 − n·ε), ε = 2⁻²⁴: the relative error bound of n f32 operations.
pub(crate) const fn gamma(n: f32) -> f32 {
    n * f32::EPSILON * 0.5 / (1.0 - n * f32::EPSILON * 0.5)
}

/// A bound on the error of the t the watertight test computes for this triangle and ray
/// (the derivation of pbrt-v4, §6.8.7): how far the exact t may lie beyond it. Grazing rays
/// make it large. Traversals add it to the best t before cutting boxes, so the box holding a
/// triangle at the same exact t is never cut (the tie rule). WGSL `t_error_bound` is the
/// same, operation for operation.
#[inline]
pub fn t_error_bound(tri: &Triangle, origin: Vec3, wr: &WatertightRay) -> f32 {
    let (mut mx, mut my, mut mz, mut mzu) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let mut sheared = [(0.0f32, 0.0f32); 3];
    for (i, v) in tri.v.iter().enumerate() {
        let a = wr.permute(*v - origin);
        let x = a[0] - wr.s.x * a[2];
        let y = a[1] - wr.s.y * a[2];
        let z = wr.s.z * a[2];
        mx = mx.max(x.abs());
        my = my.max(y.abs());
        mz = mz.max(z.abs());
        mzu = mzu.max(a[2].abs());
        sheared[i] = (x, y);
    }
    let [(ax, ay), (bx, by), (cx, cy)] = sheared;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let me = u.abs().max(v.abs()).max(w.abs());
    TriHit {
        t: 0.0,
        u: 0.0,
        v: 0.0,
        err_num: t_error_numerator(mx, my, mz, mzu, me),
        det: (u + v + w).abs(),
        in_front: false,
    }
    .t_error()
}

/// For a watertight hit at `t` whose error bound reaches back past the origin (pbrt-v4
/// would drop it as a possible self-hit): whether it is proven in front of the origin all
/// the same. Two checks, both of which a ray leaving a surface fails on that surface:
/// 1. every vertex lies ahead of the origin along the ray: the signs of `s_z·(v − o)[kz]`
///    are exact in floating point, and an exact hit's t is a convex combination of these
///    values, so it is > 0;
/// 2. the hit point lies on the triangle's plane within [`NEAR_HIT_PLANE_REL`] of the
///    vertices' distance (checked in the shear frame, where its x, y are 0), with what
///    rounding can do to the check (4 ε of the normal's and the vertices' size, times the
///    point's distance from a vertex) counted against it. A ray grazing a well-shaped
///    triangle far ahead passes (its t is uncertain only along the surface, and the bound
///    is loose); a hit on a needle, a sliver or a triangle a few ulps across at its
///    distance, whose t or plane is rounding noise, does not.
///
/// `a`, `b`, `c`: the vertices' sheared x and y and unscaled z (`(v − o)[kz]`); `sz` =
/// 1/d_kz; `mzu` the largest |z|. Never inlined: it runs for a few rays in a million.
/// WGSL `grazing_in_front` is the same, operation for operation.
#[inline(never)]
pub fn grazing_in_front(a: [f32; 3], b: [f32; 3], c: [f32; 3], sz: f32, t: f32, mzu: f32) -> bool {
    if !(sz * a[2] > 0.0 && sz * b[2] > 0.0 && sz * c[2] > 0.0) {
        return false;
    }
    let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let nx = e1[1] * e2[2] - e1[2] * e2[1];
    let ny = e1[2] * e2[0] - e1[0] * e2[2];
    let nz = e1[0] * e2[1] - e1[1] * e2[0];
    // The plane's equation at the hit point (0, 0, t·d_kz), relative to vertex a, and what
    // rounding can do to it: the normal's own rounding (ε of the edges' product) and the
    // vertices' (ε of their distance, moving the edges), times the point's distance from
    // a. A triangle a few ulps across at its distance, or a sliver, has a normal that is
    // rounding noise, and then nothing is proven.
    let (px, py, pz) = (0.0 - a[0], 0.0 - a[1], t / sz - a[2]);
    let plane = nx * px + ny * py + nz * pz;
    let n = nx.abs().max(ny.abs()).max(nz.abs());
    let max3 = |v: [f32; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
    let (l1, l2) = (max3(e1), max3(e2));
    let noise = max3([px, py, pz]) * (l1 * l2 + mzu * (l1 + l2));
    plane.abs() + 0.125 * NEAR_HIT_PLANE_REL * noise <= NEAR_HIT_PLANE_REL * mzu * n
}

/// How far off its triangle's plane (relative to the vertices' distance from the origin)
/// the point of a grazing hit may lie and still be kept by [`grazing_in_front`]: 32 ε, the
/// f64 oracle's tolerance for a point on a triangle.
pub const NEAR_HIT_PLANE_REL: f32 = 32.0 * f32::EPSILON;

/// The t error bound's numerator from the largest sheared coordinates (x, y, scaled z), the
/// largest unscaled z (`mzu`: the error of the shear x − s·z scales with z before the 1/d_z
/// scaling, so the bound holds for directions of any length) and the largest edge function:
/// 3·(γ₃·e·z + δe·z + δz·e); the bound is it over |det|.
/// Generic over f32 and SIMD lanes of f32 (`TriangleRay4`'s), whose lanes compute the same.
#[inline(always)]
pub(crate) fn t_error_numerator<T>(mx: T, my: T, mz: T, mzu: T, me: T) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
    f32: std::ops::Mul<T, Output = T>,
{
    const G2: f32 = gamma(2.0);
    const G3: f32 = gamma(3.0);
    const G5: f32 = gamma(5.0);
    let dz = G3 * mz;
    let dx = G5 * (mx + mzu);
    let dy = G5 * (my + mzu);
    let de = 2.0 * (G2 * mx * my + dy * mx + dx * my);
    3.0 * (G3 * me * mz + de * mz + dz * me)
}
