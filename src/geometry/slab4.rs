//! The slab test of four boxes at once, for the CPU twins of wide layouts: the boxes are
//! given as structure of arrays (the four x minima, the four y minima, …), one SIMD lane per
//! box. Lane k gives what [`Aabb::slab_interval_nonparallel`] gives for box k, with fewer
//! operations whose results are equal, for the non-NaN values such a ray produces (a
//! zero's sign may differ, which no comparison can see):
//! - per axis, the plane entered first is picked by the direction's sign instead of
//!   taking the min and max of both planes' distances (the rounded product of an ordered
//!   pair by one sign keeps or reverses the order);
//! - the far widening is applied once, to the least exit, instead of to each axis's exit
//!   (the widening never decreases, so the two are equal);
//! - the max (min) over the three axes associates differently.

use glam::{Vec3, Vec4};

#[cfg(doc)]
use super::Aabb;

/// A ray with no axis it is parallel to, splatted across four lanes once per ray.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay4 {
    origin: [Vec4; 3],
    inv_dir: [Vec4; 3],
    tmin: Vec4,
    widen: Vec4,
    shrink: Vec4,
    /// Per axis: the direction is negative, so the maximum plane is entered first.
    neg: [bool; 3],
}

impl SlabRay4 {
    /// The lanes for a ray from `origin` with reciprocal direction `inv_dir` (no component
    /// at or above `PARALLEL_INV` in magnitude), its `tmin` and the far widening `widen`.
    #[inline(always)]
    pub fn new(origin: Vec3, inv_dir: Vec3, tmin: f32, widen: f32) -> SlabRay4 {
        SlabRay4 {
            origin: [origin.x, origin.y, origin.z].map(Vec4::splat),
            inv_dir: [inv_dir.x, inv_dir.y, inv_dir.z].map(Vec4::splat),
            tmin: Vec4::splat(tmin),
            widen: Vec4::splat(widen),
            shrink: Vec4::splat(2.0 - widen),
            neg: [inv_dir.x < 0.0, inv_dir.y < 0.0, inv_dir.z < 0.0],
        }
    }

    /// The intervals `(enter, exit)` of the four boxes `lo[axis]`–`hi[axis]` cut to
    /// [tmin, tmax]; lane k is entered iff `enter[k] <= exit[k]`.
    #[inline(always)]
    pub fn intervals(&self, lo: [Vec4; 3], hi: [Vec4; 3], tmax: f32) -> (Vec4, Vec4) {
        let mut enter = Vec4::ZERO;
        let mut exit = Vec4::ZERO;
        for axis in 0..3 {
            let (a, b) = if self.neg[axis] {
                (hi[axis], lo[axis])
            } else {
                (lo[axis], hi[axis])
            };
            let near = (a - self.origin[axis]) * self.inv_dir[axis];
            let far = (b - self.origin[axis]) * self.inv_dir[axis];
            (enter, exit) = match axis {
                0 => (near, far),
                _ => (enter.max(near), exit.min(far)),
            };
        }
        // Widened once: the widening `x ↦ max(x·w, x·(2 − w))` never decreases (nor does
        // rounding), so widening the least exit equals the least widened exit.
        let exit = (exit * self.widen).max(exit * self.shrink);
        // `max(a, b)` is `a > b ? a : b` lane-wise: the scalar test's
        // `if enter > tmin { enter } else { tmin }`, and likewise for the exit.
        (enter.max(self.tmin), exit.min(Vec4::splat(tmax)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Aabb, FAR_WIDEN};
    use glam::Vec3A;

    #[test]
    fn lanes_equal_the_single_box_test() {
        let boxes = [
            (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0)),
            (Vec3::new(2.0, -0.5, 0.0), Vec3::new(3.0, 0.5, 0.0)),
            (Vec3::new(-5.0, 4.0, -2.0), Vec3::new(-4.0, 6.0, 9.0)),
            (Vec3::new(1e6, 1e6, 1e6), Vec3::new(1e6, 1e6, 1e6)),
        ];
        let lo = [0, 1, 2].map(|a| Vec4::from_array(boxes.map(|b| b.0[a])));
        let hi = [0, 1, 2].map(|a| Vec4::from_array(boxes.map(|b| b.1[a])));
        let origins = [
            Vec3::new(0.1, -7.0, 0.3),
            Vec3::new(-3.0, 0.0, 0.0),
            Vec3::ZERO,
            Vec3::new(7.0, 8.0, 9.0),
        ];
        let dirs = [
            Vec3::new(0.3, 1.0, -0.2),
            Vec3::new(1.0, 1e-3, 2e-3),
            Vec3::ONE,
            Vec3::new(-1.0, -0.5, -2.0),
        ];
        for (o, d) in origins.iter().zip(&dirs) {
            for widen in [1.0, FAR_WIDEN] {
                let inv = d.recip();
                let (enter, exit) = SlabRay4::new(*o, inv, -1.0, widen).intervals(lo, hi, 50.0);
                for (k, b) in boxes.iter().enumerate() {
                    let one = Aabb::slab_interval_nonparallel(
                        b.0.into(),
                        b.1.into(),
                        Vec3A::from(*o),
                        Vec3A::from(inv),
                        -1.0,
                        50.0,
                        widen,
                    );
                    assert_eq!((enter[k], exit[k]), one, "box {k}, ray {o} {d}");
                }
            }
        }
    }
}
