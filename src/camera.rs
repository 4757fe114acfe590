//! The camera: one basis for CPU and GPU, the default view of a mesh, primary rays.

use glam::Vec3;

use crate::geometry::normalize;
use crate::geometry::{Aabb, Ray};

/// tmax of primary rays, as written in ray files.
pub const PRIMARY_TMAX: f32 = 3.4e38;

/// Vertical field of view of the default view, degrees.
pub const DEFAULT_FOV: f32 = 40.0;

/// Where the default view's eye lies from the centre of what it looks at (any length).
const DEFAULT_DIRECTION: Vec3 = Vec3::new(0.0, 0.1, 1.0);

/// The camera of `cameras` (a file's, [`GltfCamera`](crate::mesh::GltfCamera)s) that
/// `choice` names, by index or by name; the first where `choice` is None (None where the
/// file has none). An error names the cameras there are.
pub fn pick_camera<'a>(
    cameras: &'a [crate::mesh::GltfCamera],
    choice: Option<&str>,
) -> Result<Option<&'a crate::mesh::GltfCamera>, String> {
    let Some(choice) = choice else {
        return Ok(cameras.first());
    };
    let found = match choice.parse::<usize>() {
        Ok(i) => cameras.get(i),
        Err(_) => cameras.iter().find(|c| c.name.as_deref() == Some(choice)),
    };
    found.map(Some).ok_or_else(|| {
        let there: Vec<String> = (cameras.iter().enumerate())
            .map(|(i, c)| format!("{i} {:?}", c.name.as_deref().unwrap_or("")))
            .collect();
        match there.is_empty() {
            true => format!("--camera {choice}: the file places no perspective camera"),
            false => format!(
                "--camera {choice}: the file's cameras are {}",
                there.join(", ")
            ),
        }
    })
}

/// A user's changes to a view (`--look-from`, `--look-at`, `--fov`); each one left None
/// keeps the view's own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewChange {
    /// Eye position.
    pub look_from: Option<Vec3>,
    /// The point looked at.
    pub look_at: Option<Vec3>,
    /// Vertical field of view, degrees.
    pub fov: Option<f32>,
    /// Which of a glTF file's cameras, by index or name (None: its first, if any).
    pub camera: Option<String>,
}

impl ViewChange {
    /// Whether it changes nothing.
    pub fn is_empty(&self) -> bool {
        *self == ViewChange::default()
    }

    /// `camera` changed: a new field of view keeps what it frames where the eye is not
    /// given (`keep_framing`: the eye moves along its line so that what filled the image
    /// still does), else only the angle changes. Refuses non-finite points, a field of
    /// view outside (0, 180) degrees, an eye on the point looked at or too far from it for
    /// f32 (given so, or moved there to keep a very narrow view's framing), and a view
    /// straight up or down (parallel to the up hint).
    pub fn apply(&self, camera: &mut Camera, keep_framing: bool) -> Result<(), String> {
        let finite = |v: Option<Vec3>| v.is_none_or(|v| v.is_finite());
        if !finite(self.look_from) || !finite(self.look_at) {
            return Err("--look-from and --look-at must be finite points x,y,z".into());
        }
        if let Some(f) = self.fov {
            if !(f > 0.0 && f < 180.0) {
                return Err(format!(
                    "--fov {f}: give a field of view in (0, 180) degrees"
                ));
            }
            if keep_framing && self.look_from.is_none() {
                let before = camera.narrowest_half_angle().sin();
                camera.vfov_deg = f;
                let after = camera.narrowest_half_angle().sin();
                camera.eye = camera.look_at + (camera.eye - camera.look_at) * (before / after);
            }
            camera.vfov_deg = f;
        }
        camera.eye = self.look_from.unwrap_or(camera.eye);
        camera.look_at = self.look_at.unwrap_or(camera.look_at);
        let fwd = camera.look_at - camera.eye;
        // A distance past f32's range (an eye given far away, or moved there to keep the
        // framing of a very narrow view) has no direction left to look along.
        if !camera.eye.is_finite() || !fwd.is_finite() || !fwd.length().is_finite() {
            return Err(match self.fov {
                Some(f) if keep_framing && self.look_from.is_none() => format!(
                    "--fov {f}: a view this narrow would put the eye too far away for f32 \
                     arithmetic: widen it, or give --look-from"
                ),
                _ => "the eye (--look-from) is too far from the point looked at (--look-at) \
                      for f32 arithmetic: bring it closer"
                    .into(),
            });
        }
        if fwd.length() == 0.0 || !fwd.normalize().is_finite() {
            return Err("the eye (--look-from) is on the point looked at (--look-at)".into());
        }
        if fwd.normalize().cross(camera.up).length() < 1e-4 {
            return Err(format!(
                "the view looks along its up direction {:?}: look from a little aside",
                camera.up.to_array()
            ));
        }
        Ok(())
    }
}

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
    /// The default view of a mesh: it looks at the centre c of the bounding box from above
    /// the +Z side (along (0, 0.1, 1)), up +Y, with a vertical field of view of 40°, from
    /// just far enough that the box's bounding sphere (radius r = half its diagonal) fits
    /// the image at any aspect ratio.
    pub fn default_view(bounds: &Aabb, width: u32, height: u32) -> Camera {
        Camera::fitted(bounds, width, height, DEFAULT_FOV)
    }

    /// [`Camera::default_view`] with a vertical field of view of `vfov_deg` degrees.
    pub fn fitted(bounds: &Aabb, width: u32, height: u32, vfov_deg: f32) -> Camera {
        let c = bounds.center();
        let r = 0.5 * bounds.extent().length();
        let mut cam = Camera {
            eye: c + DEFAULT_DIRECTION.normalize() * r,
            look_at: c,
            up: Vec3::Y,
            vfov_deg,
            width,
            height,
        };
        cam.eye = c + DEFAULT_DIRECTION.normalize() * (r / cam.narrowest_half_angle().sin());
        cam
    }

    /// A glTF file's camera, seen at `width`×`height` pixels.
    pub fn from_gltf(c: &crate::mesh::GltfCamera, width: u32, height: u32) -> Camera {
        Camera {
            eye: c.eye,
            look_at: c.look_at,
            up: c.up,
            vfov_deg: c.yfov_deg,
            width,
            height,
        }
    }

    /// The smaller of the half-angles of the vertical and the horizontal field of view,
    /// radians: a sphere seen from its radius over its sine fills the image that way.
    pub fn narrowest_half_angle(&self) -> f32 {
        let half_v = 0.5 * self.vfov_deg.to_radians();
        let aspect = self.width as f32 / self.height.max(1) as f32;
        let half_h = (half_v.tan() * aspect).atan();
        half_v.min(half_h)
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

    /// Primary rays through every pixel centre, row-major from the top-left: width · height
    /// rays of 32 bytes, allocated at once. A size that comes from input is checked first
    /// ([`check_image`](crate::limits::check_image), as `lancer rays` and the renderer do).
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

#[cfg(test)]
mod tests {
    use super::*;

    fn aabb(lo: Vec3, hi: Vec3) -> Aabb {
        Aabb { lo, hi }
    }

    /// Where `p` lands in the image of `cam`, in [-1, 1]² when it is inside.
    fn project(cam: &Camera, p: Vec3) -> (f32, f32) {
        let f = cam.frame();
        let d = p - f.eye;
        let z = d.dot(f.fwd);
        let sx = d.dot(f.right) / (f.right.length_squared() * z);
        let sy = d.dot(f.up) / (f.up.length_squared() * z);
        (sx, sy)
    }

    #[test]
    fn the_default_view_fits_tall_wide_and_flat_boxes_at_any_aspect() {
        let boxes = [
            aabb(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 4.0, 0.5)),
            aabb(Vec3::new(-4.0, 0.0, -0.5), Vec3::new(4.0, 1.0, 0.5)),
            aabb(Vec3::new(-1.0, 0.0, -3.0), Vec3::new(1.0, 0.1, 3.0)),
            aabb(Vec3::splat(10.0), Vec3::splat(11.0)),
        ];
        for b in boxes {
            for (w, h) in [(640, 480), (480, 640), (1000, 100), (100, 1000), (1, 1)] {
                let cam = Camera::default_view(&b, w, h);
                let mut widest = 0.0f32;
                for i in 0..8 {
                    let pick = |bit: usize, axis: usize| {
                        if i >> bit & 1 == 1 {
                            b.hi[axis]
                        } else {
                            b.lo[axis]
                        }
                    };
                    let corner = Vec3::new(pick(0, 0), pick(1, 1), pick(2, 2));
                    let (sx, sy) = project(&cam, corner);
                    widest = widest.max(sx.abs()).max(sy.abs());
                }
                assert!(widest <= 1.0, "{b:?} at {w}×{h}: a corner at {widest}");
                // Fitted, not merely inside: the bounding sphere touches the narrower sides.
                let r = 0.5 * b.extent().length();
                let seen = (r / (cam.eye - b.center()).length()).asin();
                let fits = cam.narrowest_half_angle();
                assert!(
                    (seen - fits).abs() < 1e-5,
                    "{b:?} at {w}×{h}: {seen} vs {fits}"
                );
            }
        }
        // The old view (eye at 2.5 r, 40°) cut the tall box's top off at 640×480.
        let b = boxes[0];
        let r = 0.5 * b.extent().length();
        let mut old = Camera::default_view(&b, 640, 480);
        old.eye = b.center() + Vec3::new(0.0, 0.25 * r, 2.5 * r);
        let (_, top) = project(&old, Vec3::new(0.5, 4.0, 0.5));
        assert!(top > 1.0, "{top}");
    }

    #[test]
    fn a_new_field_of_view_keeps_a_fitted_view_framed_or_only_narrows() {
        let b = aabb(Vec3::ZERO, Vec3::ONE);
        let cam = Camera::default_view(&b, 64, 48);
        let mut framed = cam;
        let change = ViewChange {
            fov: Some(20.0),
            ..ViewChange::default()
        };
        change.apply(&mut framed, true).unwrap();
        let fitted = Camera::fitted(&b, 64, 48, 20.0);
        assert!(
            (framed.eye - fitted.eye).length() < 1e-5,
            "{framed:?} {fitted:?}"
        );
        assert_eq!((framed.look_at, framed.vfov_deg), (fitted.look_at, 20.0));
        let mut zoomed = cam;
        change.apply(&mut zoomed, false).unwrap();
        assert_eq!((zoomed.eye, zoomed.vfov_deg), (cam.eye, 20.0));
        let bad = |c: ViewChange| c.apply(&mut cam.clone(), true).unwrap_err();
        let at = |p: Vec3| ViewChange {
            look_from: Some(p),
            look_at: Some(p),
            ..ViewChange::default()
        };
        assert!(bad(at(Vec3::ONE)).contains("on the point looked at"));
        let mut up = at(Vec3::ZERO);
        up.look_at = Some(Vec3::Y);
        assert!(bad(up).contains("up direction"));
        for fov in [0.0, 180.0, f32::NAN] {
            let c = ViewChange {
                fov: Some(fov),
                ..ViewChange::default()
            };
            assert!(bad(c).contains("--fov"));
        }
    }
}
