use glam::Vec3;

/// A ray as stored in ray files and GPU buffers: 32 bytes, origin, tmin, direction, tmax.
/// WGSL twin: `Ray` in shaders/lib/common.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Start of the hit interval: hits need t ≥ tmin.
    pub tmin: f32,
    /// Direction, not necessarily unit: t is measured in multiples of it.
    pub dir: Vec3,
    /// End of the hit interval: hits need t ≤ tmax.
    pub tmax: f32,
}

/// Smallest |d| used as a divisor; a smaller component (incl. ±0) is replaced by ±this,
/// giving a reciprocal of ±1e30: large, finite, sign kept. Same constant in WGSL.
pub const RECIP_FLOOR: f32 = 1e-30;

/// Reciprocal that never yields ±∞ or NaN for finite input and keeps the sign of −0.0.
#[inline]
pub fn safe_recip(d: f32) -> f32 {
    let m = if d.abs() < RECIP_FLOOR {
        RECIP_FLOOR.copysign(d)
    } else {
        d
    };
    1.0 / m
}

impl Ray {
    /// A ray from `origin` along `dir`, hitting only at t in [tmin, tmax].
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Ray {
        Ray {
            origin,
            tmin,
            dir,
            tmax,
        }
    }

    /// Per-axis [`safe_recip`] of the direction, for slab tests (finite for a finite `dir`).
    pub fn inv_dir(&self) -> Vec3 {
        Vec3::new(
            safe_recip(self.dir.x),
            safe_recip(self.dir.y),
            safe_recip(self.dir.z),
        )
    }

    /// A ray the tracers refuse and report as a miss: any non-finite component, an origin
    /// beyond ±[`MAX_ORIGIN`](crate::limits::MAX_ORIGIN) (the supported range), a direction
    /// whose largest component is below [`MIN_DIR`](crate::limits::MIN_DIR) (zero
    /// included), or an empty/NaN interval. Tested on bit patterns so that the WGSL twin
    /// (`ray_is_valid`) behaves the same where NaN comparisons are unreliable.
    pub fn is_valid(&self) -> bool {
        let finite = |x: f32| (x.to_bits() & 0x7fff_ffff) < 0x7f80_0000;
        let in_range = |x: f32| (x.to_bits() & 0x7fff_ffff) <= crate::limits::MAX_ORIGIN.to_bits();
        let all = [self.dir.x, self.dir.y, self.dir.z, self.tmin];
        // tmax may be +inf-free large (3.4e38) but must not be NaN.
        let tmax_ok = (self.tmax.to_bits() & 0x7fff_ffff) <= 0x7f80_0000;
        all.iter().all(|&x| finite(x))
            && [self.origin.x, self.origin.y, self.origin.z]
                .iter()
                .all(|&x| in_range(x))
            && tmax_ok
            && [self.dir.x, self.dir.y, self.dir.z]
                .iter()
                .any(|&x| (x.to_bits() & 0x7fff_ffff) >= crate::limits::MIN_DIR.to_bits())
            && self.tmin <= self.tmax
    }
}
