//! Secondary rays — a bounce and a shadow ray from random surface points, on both sides
//! of the surface — leaving by a [`RayOffset`], with the triangle each leaves: a hit on
//! that triangle is a **self-hit** (acne).

use super::random_dir;
use crate::geometry::{Hit, Ray, RayOffset, FIXED_OFFSET};
use crate::mesh::Mesh;
use crate::render::{offset_origin, point_error, Rng};

/// Secondary rays from `n` random surface points: a bounce (random direction on the normal's
/// side) and a shadow ray toward a random point of the mesh, each leaving by `offset`.
/// Returns (rays, the triangle each leaves).
pub fn secondary_rays(mesh: &Mesh, n: usize, offset: RayOffset, seed: u32) -> (Vec<Ray>, Vec<u32>) {
    let mut rng = Rng::new(seed, 0, 0);
    let fixed = FIXED_OFFSET * mesh.bounds().extent().length();
    let (mut rays, mut own) = (Vec::new(), Vec::new());
    let usable = mesh.included();
    if usable.is_empty() {
        return (rays, own);
    }
    for _ in 0..n {
        let prim = usable[rng.next_u32() as usize % usable.len()];
        let t = &mesh.triangles[prim as usize];
        let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let w = 1.0 - u - v;
        let p = t.v[0] * w + t.v[1] * u + t.v[2] * v;
        let err = point_error(&t.v, w, u, v);
        let ng = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize();
        for side in [ng, -ng] {
            let o = match offset {
                RayOffset::ErrorBound => offset_origin(p, err, side),
                RayOffset::Fixed => p + side * fixed,
                RayOffset::None => p,
            };
            let mut d = random_dir(&mut rng);
            if d.dot(side) < 0.0 {
                d = -d;
            }
            rays.push(Ray::new(o, d, 0.0, 3.4e38));
            let q = &mesh.triangles[usable[rng.next_u32() as usize % usable.len()] as usize];
            let target = (q.v[0] + q.v[1] + q.v[2]) / 3.0;
            if (target - o).dot(side) > 0.0 {
                rays.push(Ray::new(o, target - o, 0.0, 1.0));
            }
            own.resize(rays.len(), prim);
        }
    }
    (rays, own)
}

/// Self-hits: rays whose hit is the triangle they leave (`own`).
pub fn self_hits(hits: &[Hit], own: &[u32]) -> usize {
    hits.iter().zip(own).filter(|(h, o)| h.prim == **o).count()
}
