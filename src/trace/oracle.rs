//! The f64 oracle: brute force over every included triangle in double precision. Tests use
//! it to say whether an f32 tracer's answer is right, or a genuine tie that no f32 tracer
//! can be expected to resolve the same way (a ray within a tiny distance of an edge, two
//! hits at practically equal t, a hit at the end of the ray's interval).

use glam::DVec3;

use crate::geometry::{
    d3, intersect_f64, intersect_watertight_bounded, Hit, Ray, WatertightRay, MISS,
};
use crate::mesh::{Mesh, TriStatus};

/// Relative size of "tiny": 32 f32 ulps of the coordinates involved.
const TIE_REL: f64 = 32.0 * f32::EPSILON as f64;

/// The f32 watertight test's own bound on the error of its t for triangle `p` on `ray`
/// ([`TriHit::t_error`](crate::geometry::TriHit::t_error)), 0 where that test misses the
/// triangle: within it of an interval's end, the f32 test cannot tell which side the hit is
/// on (the near-hit rule, `Robustness::rejects_near_hits`, rejects such a hit at the
/// origin).
fn f32_t_error(mesh: &Mesh, ray: &Ray, p: u32) -> f64 {
    let wr = WatertightRay::new(ray.dir);
    let tri = &mesh.triangles[p as usize];
    intersect_watertight_bounded(tri, ray.origin, &wr, -f32::MAX, f32::MAX)
        .map_or(0.0, |h| h.t_error() as f64)
}

/// Every hit in [tmin, tmax] as (t, prim), in index order.
pub fn all_hits(mesh: &Mesh, ray: &Ray) -> Vec<(f64, u32)> {
    hits(mesh, ray).collect()
}

/// [`all_hits`], one at a time.
fn hits<'a>(mesh: &'a Mesh, ray: &Ray) -> impl Iterator<Item = (f64, u32)> + 'a {
    // A triangle without a status (arrays that disagree) is left out, as `included` does.
    let n = match ray.is_valid() {
        true => mesh.triangles.len().min(mesh.status.len()),
        false => 0,
    };
    let (o, d) = (d3(ray.origin), d3(ray.dir));
    let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
    (0..n)
        .filter(|&p| mesh.status[p] == TriStatus::Ok)
        .filter_map(move |p| hit_in(&mesh.triangles[p], o, d, tmin, tmax).map(|t| (t, p as u32)))
}

/// Where `ray` hits triangle `p` in [tmin, tmax], if it does: [`all_hits`]'s test for one
/// triangle (a valid ray, an included triangle).
fn hit_of(mesh: &Mesh, ray: &Ray, p: u32) -> Option<f64> {
    let tri = mesh.triangles.get(p as usize)?;
    if !ray.is_valid() || mesh.status.get(p as usize) != Some(&TriStatus::Ok) {
        return None;
    }
    let (o, d) = (d3(ray.origin), d3(ray.dir));
    hit_in(tri, o, d, ray.tmin as f64, ray.tmax as f64)
}

/// The f64 hit of a triangle by the line o + t·d, if t lies in [tmin, tmax].
fn hit_in(
    tri: &crate::geometry::Triangle,
    o: DVec3,
    d: DVec3,
    tmin: f64,
    tmax: f64,
) -> Option<f64> {
    let (t, ..) = intersect_f64(&tri.v.map(d3), o, d)?;
    (t >= tmin && t <= tmax).then_some(t)
}

/// The exact-as-f64-allows closest hit in [tmin, tmax]: (t, prim), ties by index.
pub fn closest(mesh: &Mesh, ray: &Ray) -> Option<(f64, u32)> {
    all_hits(mesh, ray)
        .into_iter()
        .fold(None, |best, (t, p)| match best {
            Some((bt, _)) if bt <= t => best,
            _ => Some((t, p)),
        })
}

/// Distance between the ray's line and the closest of a triangle's three edges.
fn edge_distance(v: &[DVec3; 3], o: DVec3, d: DVec3) -> f64 {
    let d = d.normalize();
    (0..3)
        .map(|i| {
            let (p, q) = (v[i], v[(i + 1) % 3]);
            let e = q - p;
            // Closest points of segment p + s·e (s ∈ [0,1]) and line o + t·d.
            let w = p - o;
            let (ee, ed) = (e.dot(e), e.dot(d));
            let denom = ee - ed * ed;
            let s = if denom > 0.0 {
                ((ed * w.dot(d) - w.dot(e)) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let ps = p + e * s;
            let t = (ps - o).dot(d);
            (ps - (o + d * t)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Verdict on an f32 tracer's answer for one ray.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Same primitive (or both miss) and t within a tiny tolerance.
    Agree,
    /// A genuine tie; the reason says which.
    Tie(&'static str),
    /// A wrong answer, described for the test log.
    Wrong(String),
}

/// Judges a closest-hit answer `got` for `ray` against the oracle.
pub fn judge(mesh: &Mesh, ray: &Ray, got: &Hit) -> Verdict {
    judge_against(mesh, ray, closest(mesh, ray), got)
}

/// The oracle's closest hits of a batch of rays, searched once (on all threads) and judged
/// against any number of answers: the search is brute force, every triangle for every ray,
/// and a caller judging several tracers on the same rays pays it once.
pub struct Truths<'a> {
    mesh: &'a Mesh,
    rays: &'a [Ray],
    closest: Vec<Option<(f64, u32)>>,
}

impl<'a> Truths<'a> {
    /// [`closest`] of every ray.
    pub fn new(mesh: &'a Mesh, rays: &'a [Ray]) -> Truths<'a> {
        use rayon::prelude::*;
        let closest = rays.par_iter().map(|r| closest(mesh, r)).collect();
        Truths {
            mesh,
            rays,
            closest,
        }
    }

    /// The mesh the rays were searched in.
    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// The rays, in the order their truths are numbered.
    pub fn rays(&self) -> &'a [Ray] {
        self.rays
    }

    /// The oracle's closest hit of ray `i`: (t, prim).
    pub fn closest(&self, i: usize) -> Option<(f64, u32)> {
        self.closest[i]
    }

    /// [`judge`] of `got` as the answer for ray `i`, without searching again.
    pub fn judge(&self, i: usize, got: &Hit) -> Verdict {
        judge_against(self.mesh, &self.rays[i], self.closest[i], got)
    }
}

/// [`judge`], given the oracle's closest hit `truth`.
fn judge_against(mesh: &Mesh, ray: &Ray, truth: Option<(f64, u32)>, got: &Hit) -> Verdict {
    let o = d3(ray.origin);
    let d = d3(ray.dir);
    let dl = d.length();
    let tri = |p: u32| mesh.triangles[p as usize].v.map(d3);
    // Scale of the numbers involved: coordinates relative to the origin, and the hit point.
    let scale_of = |p: u32, t: f64| {
        tri(p)
            .iter()
            .map(|&q| (q - o).abs().max_element())
            .fold(t.abs() * dl, f64::max)
    };
    let tol = |p: u32, t: f64| TIE_REL * scale_of(p, t).max(f64::MIN_POSITIVE);
    // Tolerance on t for a hit on triangle p: a point error of `tol` across the plane moves
    // t by tol / |cos θ| along a ray meeting the plane at angle θ (large for grazing hits).
    let tol_t = |p: u32, t: f64| {
        let v = tri(p);
        let cos = (v[1] - v[0])
            .cross(v[2] - v[0])
            .normalize()
            .dot(d / dl)
            .abs();
        // Below f32's normal range t keeps no relative precision (its intermediate values
        // underflow too, as for a direction of 1e38): there the tolerance is the same 32
        // ulps, of the subnormal spacing.
        (tol(p, t) / (dl * cos.max(1e-12))).max(TIE_REL * f32::MIN_POSITIVE as f64)
    };
    let near_edge = |p: u32, t: f64| edge_distance(&tri(p), o, d) <= tol(p, t);
    // A hit whose point lies within `tol` of where the interval starts or ends, measured
    // across its plane as every other tolerance here is: the f32 test cannot tell which side
    // of the bound it is on (a ray starting that close to a surface); nor within the f32
    // test's own bound on t's error ([`f32_t_error`]).
    let near_bound = |p: u32, t: f64| {
        let tt = tol_t(p, t).max(f32_t_error(mesh, ray, p));
        (t - ray.tmin as f64).abs() <= tt || (t - ray.tmax as f64).abs() <= tt
    };
    if got.prim != MISS && got.prim as usize >= mesh.len() {
        return Verdict::Wrong(format!("prim {} is no triangle", got.prim));
    }
    let g = (got.prim != MISS).then_some((got.t as f64, got.prim));
    // A reported hit must lie on its triangle's plane at the reported t.
    if let Some((gt, gp)) = g {
        let v = tri(gp);
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let tp = n.dot(v[0] - o) / n.dot(d);
        let on_plane = (tp - gt).abs() <= tol_t(gp, gt); // false for NaN too
        if !on_plane {
            return Verdict::Wrong(format!(
                "prim {gp} reported at t={gt}, its plane is at t={tp}"
            ));
        }
    }
    match (truth, g) {
        (None, None) => Verdict::Agree,
        (Some((tt, tp)), Some((gt, gp))) if tp == gp => {
            if (tt - gt).abs() <= tol_t(tp, tt) {
                Verdict::Agree
            } else {
                Verdict::Wrong(format!("prim {tp}: t={gt}, oracle t={tt}"))
            }
        }
        (Some((tt, tp)), None) => {
            if near_edge(tp, tt) {
                Verdict::Tie("missed a triangle at its edge")
            } else if near_bound(tp, tt) {
                Verdict::Tie("hit at the end of the interval")
            } else {
                Verdict::Wrong(format!("miss, oracle hits prim {tp} at t={tt}"))
            }
        }
        (None, Some((gt, gp))) => {
            if near_edge(gp, gt) {
                Verdict::Tie("hit a triangle at its edge")
            } else if near_bound(gp, gt) {
                Verdict::Tie("hit at the end of the interval")
            } else {
                Verdict::Wrong(format!("hit prim {gp} at t={gt}, oracle misses"))
            }
        }
        (Some((tt, tp)), Some((gt, gp))) => {
            if (tt - gt).abs() <= tol_t(tp, tt).max(tol_t(gp, gt)) {
                Verdict::Tie("two hits at equal t")
            } else if gt < tt && near_edge(gp, gt) {
                Verdict::Tie("a nearer triangle hit at its edge")
            } else if gt > tt && near_edge(tp, tt) {
                Verdict::Tie("the nearest triangle missed at its edge")
            } else if near_bound(tp, tt) || near_bound(gp, gt) {
                Verdict::Tie("hit at the end of the interval")
            } else {
                Verdict::Wrong(format!("prim {gp} at t={gt}, oracle prim {tp} at t={tt}"))
            }
        }
    }
}

/// Judges an any-hit (occlusion) answer: a reported hit must be a real hit of its triangle
/// in the interval (or a tie at its edge / the interval's end); a miss is right only when
/// every hit the oracle finds is such a tie.
pub fn judge_any(mesh: &Mesh, ray: &Ray, got: &Hit) -> Verdict {
    let o = d3(ray.origin);
    let d = d3(ray.dir);
    let dl = d.length();
    let marginal = |p: u32, t: f64| {
        let v = mesh.triangles[p as usize].v.map(d3);
        let scale = v
            .iter()
            .map(|&q| (q - o).abs().max_element())
            .fold(t.abs() * dl, f64::max);
        let tol = TIE_REL * scale.max(f64::MIN_POSITIVE);
        // Across the plane, as in `judge`: a point within tol of the interval's end.
        let cos = (v[1] - v[0])
            .cross(v[2] - v[0])
            .normalize()
            .dot(d / dl)
            .abs();
        let t_err = f32_t_error(mesh, ray, p);
        let near_bound = |b: f32| {
            let dt = (t - b as f64).abs();
            dt * dl * cos.max(1e-12) <= tol || dt <= t_err
        };
        edge_distance(&v, o, d) <= tol || near_bound(ray.tmin) || near_bound(ray.tmax)
    };
    if got.prim == MISS {
        // The first occluder that is no tie, if any (the search stops there).
        let mut any = false;
        let occluder = hits(mesh, ray).find(|&(t, p)| {
            any = true;
            !marginal(p, t)
        });
        match occluder {
            None if !any => Verdict::Agree,
            None => Verdict::Tie("only marginal occluders"),
            Some((t, p)) => Verdict::Wrong(format!("miss, but prim {p} occludes at t={t}")),
        }
    } else if hit_of(mesh, ray, got.prim).is_some() {
        // A real hit of its own triangle: no other triangle need be tested.
        Verdict::Agree
    } else if (got.prim as usize) < mesh.len() && marginal(got.prim, got.t as f64) {
        Verdict::Tie("occluder hit at its edge")
    } else {
        Verdict::Wrong(format!("prim {} does not occlude this ray", got.prim))
    }
}
