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

    /// The intervals of eight boxes at once, in AVX2 lanes (each plane at least eight
    /// floats long, of which the first eight are read): lane k is what [`intervals`] gives
    /// for box k (the same operations in the same order). Returns the entries and the bit
    /// set of the boxes entered (`enter[k] <= exit[k]`).
    ///
    /// # Safety
    /// The CPU must have AVX2.
    ///
    /// [`intervals`]: SlabRay4::intervals
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub unsafe fn intervals8(
        &self,
        lo: [&[f32]; 3],
        hi: [&[f32]; 3],
        tmax: f32,
    ) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        let splat = |v: Vec4| _mm256_set1_ps(v.x);
        // SAFETY: the slice is eight floats long (the bounds check fails otherwise).
        let load = |a: &[f32]| unsafe { _mm256_loadu_ps(a[..8].as_ptr()) };
        let mut enter = _mm256_setzero_ps();
        let mut exit = _mm256_setzero_ps();
        for axis in 0..3 {
            let (a, b) = if self.neg[axis] {
                (hi[axis], lo[axis])
            } else {
                (lo[axis], hi[axis])
            };
            let (o, inv) = (splat(self.origin[axis]), splat(self.inv_dir[axis]));
            let near = _mm256_mul_ps(_mm256_sub_ps(load(a), o), inv);
            let far = _mm256_mul_ps(_mm256_sub_ps(load(b), o), inv);
            (enter, exit) = match axis {
                0 => (near, far),
                _ => (_mm256_max_ps(enter, near), _mm256_min_ps(exit, far)),
            };
        }
        let exit = _mm256_max_ps(
            _mm256_mul_ps(exit, splat(self.widen)),
            _mm256_mul_ps(exit, splat(self.shrink)),
        );
        let enter = _mm256_max_ps(enter, splat(self.tmin));
        let exit = _mm256_min_ps(exit, _mm256_set1_ps(tmax));
        let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit)) as u32;
        let mut out = [0.0f32; 8];
        _mm256_storeu_ps(out.as_mut_ptr(), enter);
        (out, hit)
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

    /// `intervals8` gives, lane for lane, what `intervals` gives for the two halves: the
    /// bvh8 twin's AVX2 walk and its baseline walk agree bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn eight_lanes_equal_two_times_four() {
        assert!(
            std::arch::is_x86_feature_detected!("avx2"),
            "this test needs a CPU with AVX2 (the machines lancer's CI runs on have it)"
        );
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut f = |scale: f32| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * scale
        };
        for _ in 0..2000 {
            let mut planes = [[0.0f32; 8]; 6];
            let (los, his) = planes.split_at_mut(3);
            for (lo, hi) in los.iter_mut().zip(his.iter_mut()) {
                for (l, h) in lo.iter_mut().zip(hi.iter_mut()) {
                    let (p, q) = (f(10.0), f(10.0));
                    (*l, *h) = (p.min(q), p.max(q));
                }
            }
            // Some empty boxes, as unused slots hold (zero boxes).
            planes[0][3] = 0.0;
            planes[3][3] = 0.0;
            let o = Vec3::new(f(30.0), f(30.0), f(30.0));
            let d = Vec3::new(f(2.0), f(2.0), f(2.0));
            let (tmin, tmax) = (f(1.0), 40.0 + f(20.0));
            let ray = SlabRay4::new(o, d.recip(), tmin, 1.0 + f(1e-6).abs());
            let lo = [&planes[0][..], &planes[1][..], &planes[2][..]];
            let hi = [&planes[3][..], &planes[4][..], &planes[5][..]];
            // SAFETY: the CPU has AVX2 (asserted above).
            let (enter, hit) = unsafe { ray.intervals8(lo, hi, tmax) };
            for half in 0..2 {
                let four = |p: &[f32]| Vec4::from_slice(&p[4 * half..4 * half + 4]);
                let (e, x) = ray.intervals(lo.map(four), hi.map(four), tmax);
                for l in 0..4 {
                    let k = 4 * half + l;
                    assert_eq!(enter[k].to_bits(), e[l].to_bits(), "lane {k}");
                    assert_eq!(hit >> k & 1 == 1, e[l] <= x[l], "lane {k}");
                }
            }
        }
    }
}
