//! Accuracy, measured: the hard cases and the error each setting leaves on them, judged by
//! the f64 oracle. The tests assert on these counts (0 with the robust defaults, more than 0
//! with the fast settings where they should fail); `lancer bench accuracy` prices them.
//!
//! - [`closed`]: closed meshes and rays aimed exactly at their vertices and shared edges:
//!   every miss is a **leak**; [`close_holes`] makes a real mesh closed.
//! - [`cases`]: constructed rays — axis-parallel and signed-zero directions, origins on slab
//!   planes, flat boxes, grazing rays, rays through a box corner, boxes behind the origin,
//!   rays in a triangle's plane — whose **false misses** (the oracle and the triangle test
//!   both hit, the traversal misses) are the box test's and the traversal's error.
//! - [`secondary`]: shadow and bounce rays leaving surface points: **self-hits**.

pub mod cases;
pub mod close_holes;
pub mod closed;
pub mod secondary;

use glam::Vec3;

use crate::geometry::{intersect_triangle_bounded, Hit, Precision, Ray, Robustness, WatertightRay};
use crate::mesh::{Mesh, TriStatus};
use crate::render::Rng;
use crate::trace::oracle::{self, judge, Verdict};

/// A uniform direction on the unit sphere (rejection sampling in the cube).
pub fn random_dir(rng: &mut Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        let l = v.length_squared();
        if l > 1e-4 && l <= 1.0 {
            return v / l.sqrt();
        }
    }
}

/// Whether a brute-force pass over every usable triangle, with the same triangle test,
/// precision and near-hit rejection as a tracer under `robustness`, finds any hit: what a
/// traversal with perfect box tests would find.
pub fn triangle_test_hits(mesh: &Mesh, ray: &Ray, robustness: &Robustness) -> bool {
    if !ray.is_valid() {
        return false;
    }
    let wr = WatertightRay::new(ray.dir);
    let test = robustness.triangle_test;
    mesh.triangles
        .iter()
        .zip(&mesh.status)
        .filter(|(_, s)| **s == TriStatus::Ok)
        .any(|(tri, _)| {
            let h = match robustness.precision {
                Precision::F64 => crate::geometry::triangle_hit_f64(tri, ray, ray.tmin, ray.tmax),
                Precision::F32 => {
                    intersect_triangle_bounded(test, tri, ray, &wr, ray.tmin, ray.tmax)
                }
            };
            h.is_some_and(|h| !(robustness.rejects_near_hits_of(ray) && h.maybe_behind_origin()))
        })
}

/// False misses: rays a tracer (run with `robustness`) missed although the f64 oracle hits
/// a triangle and the tracer's own triangle test, tried on every triangle, hits one too —
/// hits lost by the box tests or the traversal, not by the triangle test.
/// On all threads (the oracle is brute force).
pub fn false_misses(mesh: &Mesh, rays: &[Ray], hits: &[Hit], robustness: &Robustness) -> usize {
    use rayon::prelude::*;
    rays.par_iter()
        .zip(hits)
        .filter(|(r, h)| {
            !h.is_hit()
                && oracle::closest(mesh, r).is_some()
                && triangle_test_hits(mesh, r, robustness)
        })
        .count()
}

/// Closest-hit answers the oracle judges wrong (not even a genuine tie), judged on all
/// threads (the oracle is brute force).
pub fn wrong_answers(mesh: &Mesh, rays: &[Ray], hits: &[Hit]) -> usize {
    use rayon::prelude::*;
    rays.par_iter()
        .zip(hits)
        .filter(|(r, h)| matches!(judge(mesh, r, h), Verdict::Wrong(_)))
        .count()
}
