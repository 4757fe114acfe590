//! A ray set up for traversals that clip its t-interval at axis-aligned planes (the kd-tree's
//! split planes, the BIH's clip planes), and the rounding-aware ends of those intervals.
//!
//! Every interval end is one computed plane distance (or tmin/tmax), never a sum, so its
//! error stays within γ(3) of its value; ends are kept widened outward by [`TIE_SLACK`](crate::geometry::TIE_SLACK) of
//! their magnitude ([`widen_lo`], [`widen_hi`]) and compared with raw plane distances, so a
//! cell the ray truly reaches is never skipped. Distances are measured along the direction
//! scaled by a power of two to a largest component in [1, 2) (exact), so a tiny or huge
//! direction is traversed like its unit twin, and they are kept finite.

use crate::geometry::{prune_bound, safe_recip, Aabb, Ray, PARALLEL_INV};

/// The WGSL twin of this file (`plane_ray.wgsl`), placed in front of the kd-tree's and the
/// BIH's traversals ([`traversal_wgsl`]).
const PLANE_RAY_WGSL: &str = include_str!("plane_ray.wgsl");

/// A plane traversal's WGSL source: its own `u32` constants (generated from their Rust
/// definitions), `PLANE_STACK_SIZE` (the pending-node stack's size, the structure's
/// deepest level), this file's WGSL twin, then the traversal itself.
pub(crate) fn traversal_wgsl(consts: &[(&str, u32)], stack_size: usize, traversal: &str) -> String {
    let mut s = String::new();
    for (name, value) in consts
        .iter()
        .chain(&[("PLANE_STACK_SIZE", stack_size as u32)])
    {
        s.push_str(&format!("const {name}: u32 = {value}u;\n"));
    }
    s + PLANE_RAY_WGSL + traversal
}

/// The override constants of the box a plane traversal clips the ray to first (the
/// structure's bounds): `PLANE_LO_X` … `PLANE_HI_Z` in `plane_ray.wgsl`.
pub(crate) fn root_box_overrides(bounds: &Aabb) -> Vec<(&'static str, f64)> {
    let (lo, hi) = (bounds.lo, bounds.hi);
    vec![
        ("PLANE_LO_X", lo.x as f64),
        ("PLANE_LO_Y", lo.y as f64),
        ("PLANE_LO_Z", lo.z as f64),
        ("PLANE_HI_X", hi.x as f64),
        ("PLANE_HI_Y", hi.y as f64),
        ("PLANE_HI_Z", hi.z as f64),
    ]
}

/// The lower end of an interval that starts at the computed distance `t`, widened by
/// [`TIE_SLACK`](crate::geometry::TIE_SLACK) (2⁻²⁰ ≈ 9.5e-7) of its magnitude. Every distance is one computed plane
/// distance, within γ(3) ≈ 3.6e-7 of its exact value; comparing a widened end with another
/// computed distance covers both errors (2γ(3)/(1 − γ(3)) < 2⁻²⁰), whatever the signs.
/// Never past −f32::MAX (the mirror of [`prune_bound`], which WGSL has too). WGSL `widen_lo` (plane_ray.wgsl).
#[inline(always)]
pub(crate) fn widen_lo(t: f32) -> f32 {
    -prune_bound(-t)
}

/// The upper end of an interval that ends at the computed distance `t`, widened likewise:
/// [`prune_bound`], never past f32::MAX. WGSL `widen_hi`.
#[inline(always)]
pub(crate) fn widen_hi(t: f32) -> f32 {
    prune_bound(t)
}

/// A plane distance, kept finite. WGSL `finite`.
#[inline(always)]
pub(crate) fn finite(t: f32) -> f32 {
    t.clamp(-f32::MAX, f32::MAX)
}

/// (2^k, 2^−k) for the k that brings `m` (> 0, finite) into [1, 2), k within ±126.
/// WGSL `pow2`.
#[inline(always)]
pub(crate) fn pow2_scales(m: f32) -> (f32, f32) {
    let e = ((m.to_bits() >> 23) & 0xff) as i32 - 127;
    let k = (-e).clamp(-126, 126);
    let pow2 = |k: i32| f32::from_bits(((k + 127) as u32) << 23);
    (pow2(k), pow2(-k))
}

/// A valid ray in the traversal's units: t' = t / 2^k for the direction scaled by 2^k so
/// that its largest component lies in [1, 2). Triangles still see the ray unscaled.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlaneRay {
    /// The origin.
    pub o: [f32; 3],
    /// `safe_recip` of the scaled direction: |inv| ≥ [`PARALLEL_INV`] marks an axis the ray
    /// is parallel to (a component below 2e-30 of the largest), sign kept (−0.0 included).
    pub inv: [f32; 3],
    /// The ray's tmin and tmax in scaled units, finite.
    pub tmin: f32,
    /// See `tmin`.
    pub tmax: f32,
    /// 2^−k: multiplies an unscaled t into scaled units.
    unscale: f32,
}

impl PlaneRay {
    /// The ray in scaled units (`ray` must be valid: a finite, nonzero direction).
    #[inline(always)]
    pub fn new(ray: &Ray) -> PlaneRay {
        let (scale, unscale) = pow2_scales(ray.dir.abs().max_element());
        PlaneRay {
            o: ray.origin.to_array(),
            inv: (ray.dir * scale).to_array().map(safe_recip),
            tmin: finite(ray.tmin * unscale),
            tmax: finite(ray.tmax.min(f32::MAX) * unscale),
            unscale,
        }
    }

    /// Whether the ray is parallel to axis `k` (the slab test's rule).
    #[inline(always)]
    pub fn parallel(&self, k: usize) -> bool {
        self.inv[k].abs() >= PARALLEL_INV
    }

    /// An unscaled t (a hit's prune bound) in scaled units.
    #[inline(always)]
    pub fn scaled(&self, t: f32) -> f32 {
        finite(t * self.unscale)
    }

    /// The ray's widened [near, far] interval in `bounds`, or None when it misses them. An
    /// axis the ray is parallel to bounds nothing if the origin lies in its slab.
    #[inline(always)]
    pub fn root_interval(&self, bounds: &Aabb) -> Option<(f32, f32)> {
        let (mut tn, mut tf) = (self.tmin, self.tmax);
        for k in 0..3 {
            let (lo, hi, o, inv) = (bounds.lo[k], bounds.hi[k], self.o[k], self.inv[k]);
            if self.parallel(k) {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let t0 = finite((lo - o) * inv);
            let t1 = finite((hi - o) * inv);
            let (a, b) = if inv > 0.0 { (t0, t1) } else { (t1, t0) };
            tn = tn.max(widen_lo(a));
            tf = tf.min(widen_hi(b));
        }
        (tn <= tf).then_some((tn, tf))
    }
}
