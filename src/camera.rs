//! The camera: one basis for CPU and GPU, the default view of a mesh, primary rays.

use glam::Vec3;

use crate::geometry::normalize;
use crate::geometry::{Aabb, Ray};

/// tmax of primary rays, as written in ray files.
pub const PRIMARY_TMAX: f32 = 3.4e38;

/// Pinhole camera; pixel centres, row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// The point looked at.
    pub look_at: Vec3,
    /// Up hint (not parallel to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
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

    /// The camera basis both renderers and the ray generator use.
    pub fn frame(&self) -> CameraFrame {
        let fwd = (self.look_at - self.eye).normalize();
        let right = fwd.cross(self.up).normalize();
        let up = right.cross(fwd);
        let hh = (0.5 * self.vfov_deg.to_radians()).tan();
        let hw = hh * self.width as f32 / self.height as f32;
        CameraFrame {
            eye: self.eye,
            fwd,
            right: right * hw,
            up: up * hh,
            inv_w2: 2.0 / self.width as f32,
            inv_h2: 2.0 / self.height as f32,
        }
    }

    /// Primary rays through every pixel centre, row-major from the top-left.
    pub fn primary_rays(&self) -> Vec<Ray> {
        let f = self.frame();
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| f.ray(x, y, 0.5, 0.5))
            .collect()
    }
}

/// The camera as the CPU and the GPU use it: per-pixel steps precomputed once on the CPU
/// (WGSL reads them from the render kernel's `Params`), so both compute every ray with the
/// same operations.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    /// Eye position.
    pub eye: Vec3,
    /// Unit view direction.
    pub fwd: Vec3,
    /// right · half-width of the image plane at distance 1.
    pub right: Vec3,
    /// up · half-height of the image plane at distance 1.
    pub up: Vec3,
    /// 2 / width.
    pub inv_w2: f32,
    /// 2 / height.
    pub inv_h2: f32,
}

impl CameraFrame {
    /// Ray through pixel (x, y) at offset (jx, jy) ∈ [0, 1)² within it (0.5, 0.5: the
    /// centre).
    pub fn ray(&self, x: u32, y: u32, jx: f32, jy: f32) -> Ray {
        let sx = (x as f32 + jx) * self.inv_w2 - 1.0;
        let sy = 1.0 - (y as f32 + jy) * self.inv_h2;
        let d = normalize(self.fwd + self.right * sx + self.up * sy);
        Ray::new(self.eye, d, 0.0, PRIMARY_TMAX)
    }
}
