//! An instance's placement (`accel::instances`): an affine map as three rows of four f32 (48 bytes, the form a
//! GPU reads too), applied in a fixed operation order so that every device rounds alike.

use glam::{DMat3, DVec3, Mat4, Vec3};

use super::{Aabb, Ray};

/// An affine map x' = A·x + b as three rows `[a0, a1, a2, b]`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Affine {
    /// Row i gives coordinate i of the image: `rows[i][0..3]` · x + `rows[i][3]`.
    pub rows: [[f32; 4]; 3],
}

/// Relative padding of an instance's world box ([`Affine::bound_box`]): the object-space ray
/// is the world ray moved by an f32 map, a few ulps away from the exact one, so the world
/// box holds the geometry that ray can meet, not only the exact image of the object box.
const BOX_PAD: f64 = 1.0 / (1u64 << 20) as f64;

impl Affine {
    /// The identity map.
    pub const IDENTITY: Affine = Affine {
        rows: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// The map of a 4×4 matrix whose last row is (0, 0, 0, 1) (glam, column-major); the last
    /// row is not read.
    pub fn from_mat4(m: &Mat4) -> Affine {
        let r = m.transpose();
        Affine {
            rows: [
                r.x_axis.to_array(),
                r.y_axis.to_array(),
                r.z_axis.to_array(),
            ],
        }
    }

    /// The map p ↦ m·p + t.
    pub fn from_mat3_translation(m: glam::Mat3, t: Vec3) -> Affine {
        let r = m.transpose();
        Affine {
            rows: [
                r.x_axis.extend(t.x).to_array(),
                r.y_axis.extend(t.y).to_array(),
                r.z_axis.extend(t.z).to_array(),
            ],
        }
    }

    /// A translation by `t`.
    pub fn translation(t: Vec3) -> Affine {
        let mut a = Affine::IDENTITY;
        for (row, t) in a.rows.iter_mut().zip(t.to_array()) {
            row[3] = t;
        }
        a
    }

    /// The map with every entry replaced by its magnitude: `abs().point(|x|)` bounds the
    /// magnitude of each coordinate of the image of x (the renderer's transform error,
    /// `render::scene::Placements`).
    pub fn abs(&self) -> Affine {
        Affine {
            rows: self.rows.map(|r| r.map(f32::abs)),
        }
    }

    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rows.iter().flatten().all(|x| x.is_finite())
    }

    /// The image of point `p`, each coordinate `((a0·x + a1·y) + a2·z) + b` in f32, unfused
    /// (the GPU twin computes the same).
    #[inline(always)]
    pub fn point(&self, p: Vec3) -> Vec3 {
        let f = |r: &[f32; 4]| r[0] * p.x + r[1] * p.y + r[2] * p.z + r[3];
        Vec3::new(f(&self.rows[0]), f(&self.rows[1]), f(&self.rows[2]))
    }

    /// The image of direction `v` (the linear part), `(a0·x + a1·y) + a2·z` in f32, unfused.
    #[inline(always)]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        let f = |r: &[f32; 4]| r[0] * v.x + r[1] * v.y + r[2] * v.z;
        Vec3::new(f(&self.rows[0]), f(&self.rows[1]), f(&self.rows[2]))
    }

    /// The image of `ray`: origin and direction mapped, the interval kept. The direction is
    /// not renormalised, so t measures the same points in both spaces (up to rounding).
    #[inline(always)]
    pub fn ray(&self, ray: &Ray) -> Ray {
        Ray::new(
            self.point(ray.origin),
            self.vector(ray.dir),
            ray.tmin,
            ray.tmax,
        )
    }

    /// The linear part and the offset in f64.
    fn to_f64(self) -> (DMat3, DVec3) {
        let r = self.rows.map(|r| r.map(f64::from));
        let linear = DMat3::from_cols_array_2d(&[
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ]);
        (linear, DVec3::new(r[0][3], r[1][3], r[2][3]))
    }

    /// The image of `p` in f64 (what the oracle takes for the instance's geometry).
    pub fn point_f64(&self, p: DVec3) -> DVec3 {
        let (linear, offset) = self.to_f64();
        linear * p + offset
    }

    /// The determinant of the linear part (negative for a mirroring map).
    pub fn determinant(&self) -> f64 {
        self.to_f64().0.determinant()
    }

    /// Whether the linear part keeps the axes (each row has at most one non-zero entry: a
    /// scale, a mirror, a swap of axes), so that a box maps onto a box exactly.
    pub fn keeps_axes(&self) -> bool {
        self.rows
            .iter()
            .all(|r| r[..3].iter().filter(|&&x| x != 0.0).count() <= 1)
    }

    /// The inverse map, computed in f64 and rounded to f32; None when the map is singular
    /// or its inverse does not fit in f32.
    pub fn inverse(&self) -> Option<Affine> {
        if !self.is_finite() {
            return None;
        }
        let (linear, offset) = self.to_f64();
        let det = linear.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = linear.inverse();
        let b = -(inv * offset);
        let row = |i: usize| {
            let r = inv.row(i);
            [r.x as f32, r.y as f32, r.z as f32, b[i] as f32]
        };
        let out = Affine {
            rows: [row(0), row(1), row(2)],
        };
        out.is_finite().then_some(out)
    }

    /// The box of the image of box `b`: its eight corners mapped in f64, rounded to f32.
    pub fn image_box(&self, b: &Aabb) -> Aabb {
        match self.corners_box(b) {
            None => Aabb::EMPTY,
            Some((lo, hi)) => Aabb {
                lo: lo.as_vec3(),
                hi: hi.as_vec3(),
            },
        }
    }

    /// The f64 box of box `b`'s eight corners mapped, or None for an empty box.
    fn corners_box(&self, b: &Aabb) -> Option<(DVec3, DVec3)> {
        if b.is_empty() {
            return None;
        }
        let (lo, hi) = (b.lo.as_dvec3(), b.hi.as_dvec3());
        let (mut out_lo, mut out_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for k in 0..8 {
            let corner = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let p = self.point_f64(corner);
            out_lo = out_lo.min(p);
            out_hi = out_hi.max(p);
        }
        Some((out_lo, out_hi))
    }

    /// A box holding the image of box `b` (its eight corners mapped in f64), padded by a
    /// relative 2⁻²⁰ of its largest coordinate and rounded outwards to f32.
    pub fn bound_box(&self, b: &Aabb) -> Aabb {
        let Some((out_lo, out_hi)) = self.corners_box(b) else {
            return Aabb::EMPTY;
        };
        let pad = out_lo.abs().max(out_hi.abs()).max_element() * BOX_PAD;
        Aabb {
            lo: (out_lo - pad).as_vec3().map(|x| x.next_down()),
            hi: (out_hi + pad).as_vec3().map(|x| x.next_up()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_undoes_the_map_and_singular_maps_have_none() {
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, -3.0),
            glam::Quat::from_rotation_y(0.7),
            Vec3::new(10.0, -4.0, 1.5),
        );
        let a = Affine::from_mat4(&m);
        let p = Vec3::new(0.3, -1.2, 4.0);
        assert!((a.point(p) - m.transform_point3(p)).abs().max_element() < 1e-5);
        let back = a.inverse().unwrap().point(a.point(p));
        assert!((back - p).abs().max_element() < 1e-5, "{back}");
        assert!(a.determinant() < 0.0);
        let flat = Affine::from_mat4(&Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)));
        assert_eq!(flat.inverse(), None);
        let mut nan = Affine::IDENTITY;
        nan.rows[1][3] = f32::NAN;
        assert_eq!(nan.inverse(), None);
    }

    #[test]
    fn bound_box_holds_every_mapped_vertex() {
        let a = Affine::from_mat4(&Mat4::from_rotation_translation(
            glam::Quat::from_rotation_z(0.3) * glam::Quat::from_rotation_x(1.1),
            Vec3::new(-7.0, 2.0, 0.25),
        ));
        let b = Aabb {
            lo: Vec3::new(-1.0, 0.0, 2.0),
            hi: Vec3::new(1.0, 3.0, 2.5),
        };
        let w = a.bound_box(&b);
        for k in 0..8u32 {
            let c = Vec3::new(
                if k & 1 == 0 { b.lo.x } else { b.hi.x },
                if k & 2 == 0 { b.lo.y } else { b.hi.y },
                if k & 4 == 0 { b.lo.z } else { b.hi.z },
            );
            let p = a.point(c);
            assert!(
                p.cmpge(w.lo).all() && p.cmple(w.hi).all(),
                "{p} outside {w:?}"
            );
        }
        assert_eq!(a.bound_box(&Aabb::EMPTY), Aabb::EMPTY);
    }
}
