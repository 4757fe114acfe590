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

/// `n` rays from origins uniform in the mesh's bounds, directions uniform on the sphere
/// (the same rays every run).
pub fn random_rays(mesh: &Mesh, n: u32) -> Vec<Ray> {
    let b = mesh.bounds();
    (0..n)
        .map(|i| {
            let mut rng = Rng::new(0x5eed, i, 0);
            let f = glam::Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let o = b.lo + (b.hi - b.lo) * f;
            Ray::new(o, random_dir(&mut rng), 0.0, f32::MAX)
        })
        .collect()
}
