//! The rays the benches trace: the default view's primary rays and the shadow and bounce
//! rays from their hits, and random rays through a mesh's bounds.

use crate::accel::{Accel, Query};
use crate::accuracy::random_dir;
use crate::camera::Camera;
use crate::geometry::{Ray, Robustness};
use crate::mesh::Mesh;
use crate::render::Rng;
use crate::trace::files::{default_light, shadow_rays};

pub use crate::trace::files::{view_ray_sets, RaySet};

/// Primary rays of `camera` and the shadow rays from their hits (by `accel`, default
/// robustness) to the default light of `mesh`.
pub fn primary_and_shadow(mesh: &Mesh, accel: &dyn Accel, camera: &Camera) -> (Vec<Ray>, Vec<Ray>) {
    let primary = camera.primary_rays();
    let (hits, _) = accel.trace_batch(&primary, Query::Closest, &Robustness::default());
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    (primary, shadow)
}

/// The seed of the benches' random rays, so every run traces the same ones.
pub const BENCH_SEED: u32 = 0x5eed;

/// `n` incoherent rays through `mesh`'s bounds, the same for the same `seed`. Ray `i` draws
/// from its own stream ([`Rng::new`]`(seed, i, 0)`): it starts on a shell around the bounds'
/// centre, 0.2 to 2 half-diagonals out (so some start inside and most enter from outside),
/// and aims at a point uniform in the bounds. The one random-ray generator of the benches
/// and the tests.
pub fn random_rays(mesh: &Mesh, n: usize, seed: u32) -> Vec<Ray> {
    let b = mesh.bounds();
    let centre = b.center();
    let radius = 0.5 * b.extent().length();
    (0..n)
        .map(|i| {
            let mut rng = Rng::new(seed, i as u32, 0);
            let o = centre + random_dir(&mut rng) * radius * (0.2 + 1.8 * rng.next_f32());
            let f = glam::Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let target = b.lo + (b.hi - b.lo) * f;
            let d = (target - o).normalize_or_zero();
            let d = if d == glam::Vec3::ZERO {
                glam::Vec3::X
            } else {
                d
            };
            Ray::new(o, d, 0.0, f32::MAX)
        })
        .collect()
}
