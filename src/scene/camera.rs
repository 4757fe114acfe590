use glam::Vec3;

use crate::geometry::{Aabb, Ray};

/// tmax of primary rays, as written in ray files.
pub const PRIMARY_TMAX: f32 = 3.4e38;

/// Pinhole camera; pixel centres, row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub vfov_deg: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// The default view of a mesh: r = half the bbox diagonal, c = bbox centre,
    /// eye = c + (0, 0.25r, 2.5r), looking at c, up +Y, vertical fov 40°.
    pub fn default_view(bounds: &Aabb, width: u32, height: u32) -> Camera {
        let c = bounds.center();
        let r = 0.5 * bounds.extent().length();
        Camera {
            eye: c + Vec3::new(0.0, 0.25 * r, 2.5 * r),
            look_at: c,
            up: Vec3::Y,
            vfov_deg: 40.0,
            width,
            height,
        }
    }

    /// Orthonormal basis (right, up, forward) and the half extents of the image plane.
    fn frame(&self) -> (Vec3, Vec3, Vec3, f32, f32) {
        let fwd = (self.look_at - self.eye).normalize();
        let right = fwd.cross(self.up).normalize();
        let up = right.cross(fwd);
        let half_h = (0.5 * self.vfov_deg.to_radians()).tan();
        let half_w = half_h * self.width as f32 / self.height as f32;
        (right, up, fwd, half_w, half_h)
    }

    /// Primary rays of every pixel, row-major from the top-left.
    pub fn primary_rays(&self) -> Vec<Ray> {
        let (right, up, fwd, hw, hh) = self.frame();
        let (w, h) = (self.width as f32, self.height as f32);
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| {
                let sx = 2.0 * (x as f32 + 0.5) / w - 1.0;
                let sy = 1.0 - 2.0 * (y as f32 + 0.5) / h;
                let d = (fwd + right * (sx * hw) + up * (sy * hh)).normalize();
                Ray::new(self.eye, d, 0.0, PRIMARY_TMAX)
            })
            .collect()
    }
}
