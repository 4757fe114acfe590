//! The f64 watertight triangle test: the oracle's test (`trace::oracle`), and a tracer's
//! test at [`Precision::F64`](crate::geometry::Precision).

use glam::DVec3;

use super::{t_error_bound, Ray, TriHit, Triangle, WatertightRay};

/// A point or direction in f64.
pub fn d3(v: glam::Vec3) -> DVec3 {
    v.as_dvec3()
}

/// Watertight test (Woop et al. 2013) in f64, no interval: (t, u, v) of a hit, u and v
/// the weights of vertices 1 and 2.
pub fn intersect_f64(v: &[DVec3; 3], o: DVec3, d: DVec3) -> Option<(f64, f64, f64)> {
    let a = d.abs();
    let kz = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    let p = v.map(|q| q - o);
    let x = |q: DVec3| q[kx] - sx * q[kz];
    let y = |q: DVec3| q[ky] - sy * q[kz];
    let (ax, ay, bx, by, cx, cy) = (x(p[0]), y(p[0]), x(p[1]), y(p[1]), x(p[2]), y(p[2]));
    let u = cx * by - cy * bx;
    let vv = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || vv < 0.0 || w < 0.0) && (u > 0.0 || vv > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + vv + w;
    if det == 0.0 {
        return None;
    }
    let t = (u * sz * p[0][kz] + vv * sz * p[1][kz] + w * sz * p[2][kz]) / det;
    Some((t, vv / det, w / det))
}

/// The oracle's test as a tracer's triangle test ([`Precision::F64`](crate::geometry::Precision)):
/// a hit with t in [tmin, tmax], t, u and v rounded to f32 (rounding keeps t in the
/// interval). Its t error bound is the f32 test's scaled by ε(f64)/ε(f32) = 2⁻²⁹ (the same
/// derivation, γ(n) ∝ ε): the near-hit rejection needs it, since a secondary ray starting
/// exactly on its surface (a zero offset where the hit point is exact) computes t = ±1e-17,
/// not 0.
#[inline]
pub fn triangle_hit_f64(tri: &Triangle, ray: &Ray, tmin: f32, tmax: f32) -> Option<TriHit> {
    const F64_OVER_F32: f32 = 1.0 / (1u64 << 29) as f32;
    let (t, u, v) = intersect_f64(&tri.v.map(d3), d3(ray.origin), d3(ray.dir))?;
    (t >= tmin as f64 && t <= tmax as f64).then(|| TriHit {
        t: t as f32,
        u: u as f32,
        v: v as f32,
        err_num: t_error_bound(tri, ray.origin, &WatertightRay::new(ray.dir)) * F64_OVER_F32,
        det: 1.0,
        in_front: false,
    })
}
