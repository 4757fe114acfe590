//! Child boxes in 8 bits per plane: each wide node has a frame (origin `p` = its box's low
//! corner, a power-of-two step per axis) and stores every child plane as a byte `q`; the
//! plane is `p + q·step` in f32 ([`dequantise`]), the arithmetic the twin and the WGSL both
//! run. A power-of-two step times a byte is exact, so a fused multiply-add gives the same
//! value as a multiply then an add: no compiler contraction can make the GPU disagree.
//!
//! Conservative: each low plane decodes to the largest value ≤ the exact plane, each high
//! plane to the smallest value ≥ it, both found with [`dequantise`] itself, so the decoded
//! box always contains the exact one.

use glam::{Vec3, Vec3A};

use crate::geometry::Aabb;

/// The largest byte.
const Q_MAX: u32 = 255;

/// Smallest and largest unbiased exponent of a step (a normal f32: 2⁻¹²⁶ ..= 2¹²⁷).
const E_MIN: i32 = -126;
const E_MAX: i32 = 127;

/// A child plane: `p + q·step`, each component in f32.
#[inline(always)]
pub(crate) fn dequantise(p: Vec3A, step: Vec3A, q: Vec3A) -> Vec3A {
    p + q * step
}

/// The step 2^(e − 127) of a biased exponent byte (WGSL: `bitcast<f32>(e << 23)`).
#[inline(always)]
pub(crate) fn step(e: [u8; 3]) -> Vec3A {
    Vec3A::new(
        f32::from_bits((e[0] as u32) << 23),
        f32::from_bits((e[1] as u32) << 23),
        f32::from_bits((e[2] as u32) << 23),
    )
}

/// One node's frame: origin and per-axis step (as biased exponent bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Frame {
    /// The node box's low corner.
    pub p: Vec3,
    /// Biased f32 exponents of the steps, each in 1..=254.
    pub e: [u8; 3],
}

impl Frame {
    /// The frame of a node whose children all lie in `bbox` (non-empty, finite): on each
    /// axis the smallest step with `p + 255·step ≥ hi` in f32.
    pub fn new(bbox: &Aabb) -> Frame {
        let p = bbox.lo;
        let mut e = [0u8; 3];
        for (axis, e) in e.iter_mut().enumerate() {
            let (lo, hi) = (p[axis], bbox.hi[axis]);
            let covers = |x: i32| plane(lo, pow2(x), Q_MAX) >= hi;
            // A guess from the extent, then walk to the smallest exponent that covers.
            let ext = (hi as f64 - lo as f64) / Q_MAX as f64;
            let guess = if ext > 0.0 {
                ext.log2().ceil() as i32
            } else {
                E_MIN
            };
            let mut x = guess.clamp(E_MIN, E_MAX);
            while x < E_MAX && !covers(x) {
                x += 1;
            }
            while x > E_MIN && covers(x - 1) {
                x -= 1;
            }
            *e = (x + 127) as u8;
        }
        Frame { p, e }
    }

    /// The bytes of a child box inside the frame: (low planes, high planes), conservative.
    pub fn quantise(&self, child: &Aabb) -> ([u8; 3], [u8; 3]) {
        let s = step(self.e);
        let (mut lo, mut hi) = ([0u8; 3], [0u8; 3]);
        for axis in 0..3 {
            let (p, s) = (self.p[axis], s[axis]);
            let value = |q: u32| plane(p, s, q);
            let estimate = |x: f32| ((x as f64 - p as f64) / s as f64).clamp(0.0, Q_MAX as f64);
            // Largest q with value(q) ≤ child lo (q = 0 gives p ≤ child lo).
            let mut q = estimate(child.lo[axis]).floor() as u32;
            while q > 0 && value(q) > child.lo[axis] {
                q -= 1;
            }
            while q < Q_MAX && value(q + 1) <= child.lo[axis] {
                q += 1;
            }
            // Where a step is below the f32 spacing of the planes, several bytes decode to
            // one value: take the first (and the last for hi), so that lo ≤ hi as bytes.
            while q > 0 && value(q - 1) == value(q) {
                q -= 1;
            }
            lo[axis] = q as u8;
            // Smallest q with value(q) ≥ child hi (q = 255 covers the whole frame).
            let mut q = estimate(child.hi[axis]).ceil() as u32;
            while q < Q_MAX && value(q) < child.hi[axis] {
                q += 1;
            }
            while q > 0 && value(q - 1) >= child.hi[axis] {
                q -= 1;
            }
            while q < Q_MAX && value(q + 1) == value(q) {
                q += 1;
            }
            hi[axis] = q as u8;
        }
        (lo, hi)
    }
}

/// 2^x for x in E_MIN..=E_MAX.
fn pow2(x: i32) -> f32 {
    f32::from_bits(((x + 127) as u32) << 23)
}

/// One plane, through [`dequantise`] so that the check is the traversal's own arithmetic.
fn plane(p: f32, step: f32, q: u32) -> f32 {
    dequantise(Vec3A::splat(p), Vec3A::splat(step), Vec3A::splat(q as f32)).x
}
