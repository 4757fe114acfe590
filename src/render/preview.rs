//! A direct-light preview of a mesh: Lambert shading from one point light with hard
//! shadows and a little ambient light, traced on any device through a closure. The full
//! renderer (materials, TOML scenes, path tracing) builds on the same tracers.

use glam::Vec3;

use crate::error::Result;
use crate::geometry::{Hit, Ray};
use crate::scene::{Camera, Mesh};
use crate::trace::rays::shadow_rays;
use crate::trace::Query;

#[derive(Clone, Copy, Debug)]
pub struct PreviewOptions {
    pub light: Vec3,
    pub ambient: f32,
    pub albedo: Vec3,
    pub background: Vec3,
}

fn srgb(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Renders the preview; `trace` runs a batch of rays on the chosen device.
pub fn preview(
    mesh: &Mesh,
    camera: &Camera,
    opts: &PreviewOptions,
    mut trace: impl FnMut(&[Ray], Query) -> Result<Vec<Hit>>,
) -> Result<image::RgbImage> {
    let primary = camera.primary_rays();
    let hits = trace(&primary, Query::Closest)?;
    let shadow = shadow_rays(&primary, &hits, opts.light);
    let blocked = trace(&shadow, Query::Any)?;
    let mut img = image::RgbImage::new(camera.width, camera.height);
    let mut s = blocked.iter();
    for ((px, r), h) in img.pixels_mut().zip(&primary).zip(&hits) {
        let c = if h.is_hit() {
            let t = &mesh.triangles[h.prim as usize];
            let mut n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize();
            if n.dot(r.dir) > 0.0 {
                n = -n; // two-sided
            }
            let p = r.origin + r.dir * h.t;
            let lit = !s.next().expect("one shadow ray per hit").is_hit();
            let diffuse = if lit {
                n.dot((opts.light - p).normalize()).max(0.0)
            } else {
                0.0
            };
            opts.albedo * (opts.ambient + (1.0 - opts.ambient) * diffuse)
        } else {
            opts.background
        };
        *px = image::Rgb([srgb(c.x), srgb(c.y), srgb(c.z)]);
    }
    Ok(img)
}
