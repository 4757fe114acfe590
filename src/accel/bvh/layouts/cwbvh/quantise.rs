//! Child boxes in 8 bits per plane: each wide node has a frame (origin `p` = its box's low
//! corner, a power-of-two step per axis) and stores every child plane as a byte `q`; the
//! plane is `p + q·step` in f32 ([`dequantise`]), the arithmetic the twin and the WGSL both
//! run. A power-of-two step times a byte is exact, so a fused multiply-add gives the same
//! value as a multiply then an add: no compiler contraction can make the GPU disagree.
//!
//! Conservative: each low plane decodes to the largest value ≤ the exact plane, each high
//! plane to the smallest value ≥ it, both found with [`dequantise`] itself, so the decoded
//! box always contains the exact one.

use glam::{BVec3A, Vec3, Vec3A};

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
    /// axis the smallest step with `p + 255·step ≥ hi` in f32. The axes walk side by side
    /// in the lanes of a vector, from a guess, by doubling and halving the step (exact for
    /// the normal powers of two the walks stay within).
    pub fn new(bbox: &Aabb) -> Frame {
        let p = bbox.lo;
        let (lo, hi) = (Vec3A::from(p), Vec3A::from(bbox.hi));
        let covers = |s: Vec3A| dequantise(lo, s, Vec3A::splat(Q_MAX as f32)).cmpge(hi);
        // A guess from the extent, then walk to the smallest step that covers.
        let guess = |axis: usize| {
            let ext = (bbox.hi[axis] as f64 - p[axis] as f64) / Q_MAX as f64;
            let x = if ext > 0.0 { ceil_log2(ext) } else { E_MIN };
            pow2(x.clamp(E_MIN, E_MAX))
        };
        let s = Vec3A::new(guess(0), guess(1), guess(2));
        let (least, most) = (Vec3A::splat(pow2(E_MIN)), Vec3A::splat(pow2(E_MAX)));
        let s = walk(s, |s| s * 2.0, |s| s.cmplt(most) & !covers(s));
        let s = walk(s, |s| s * 0.5, |s| s.cmpgt(least) & covers(s * 0.5));
        let e = |x: f32| (x.to_bits() >> 23) as u8;
        Frame {
            p,
            e: [e(s.x), e(s.y), e(s.z)],
        }
    }

    /// The bytes of a child box inside the frame: (low planes, high planes), conservative.
    /// The three axes walk side by side, one per lane of a vector (a lane moves only while
    /// its own condition holds). The walks start from an estimate, and end on the same
    /// byte wherever they start: `value(q) = p + q·step` never decreases as q grows (`q·step`
    /// is exact, rounding keeps the order, an overflow goes to +∞), so each walk finds the
    /// byte its condition defines.
    pub fn quantise(&self, child: &Aabb) -> ([u8; 3], [u8; 3]) {
        let p = Vec3A::from(self.p);
        let s = step(self.e);
        let value = |q: Vec3A| dequantise(p, s, q);
        let (zero, one, top) = (Vec3A::ZERO, Vec3A::ONE, Vec3A::splat(Q_MAX as f32));
        // 1/step is exact (a power of two). An estimate below 0, or NaN, starts at 0.
        let inv = one / s;
        let estimate = |x: Vec3A| {
            let e = (x - p) * inv;
            Vec3A::select(e.cmpge(zero), e.min(top), zero)
        };
        // Largest q with value(q) ≤ child lo (q = 0 gives p ≤ child lo). The estimate is
        // not negative: truncation is its floor.
        let x = Vec3A::from(child.lo);
        let (down, up) = (|q: Vec3A| q - one, |q: Vec3A| q + one);
        let lo = estimate(x).trunc();
        let lo = walk(lo, down, |q| q.cmpgt(zero) & value(q).cmpgt(x));
        let lo = walk(lo, up, |q| q.cmplt(top) & value(q + one).cmple(x));
        // Where a step is below the f32 spacing of the planes, several bytes decode to one
        // value: take the first (and the last for hi), so that lo ≤ hi as bytes.
        let lo = walk(lo, down, |q| q.cmpgt(zero) & value(q - one).cmpeq(value(q)));
        // Smallest q with value(q) ≥ child hi (q = 255 covers the whole frame).
        let x = Vec3A::from(child.hi);
        let e = estimate(x);
        let t = e.trunc();
        let hi = Vec3A::select(t.cmplt(e), t + one, t);
        let hi = walk(hi, up, |q| q.cmplt(top) & value(q).cmplt(x));
        let hi = walk(hi, down, |q| q.cmpgt(zero) & value(q - one).cmpge(x));
        let hi = walk(hi, up, |q| q.cmplt(top) & value(q + one).cmpeq(value(q)));
        let bytes = |q: Vec3A| [q.x as u8, q.y as u8, q.z as u8];
        (bytes(lo), bytes(hi))
    }
}

/// Moves each lane of `q` by `next` while its lane of `go` holds (the lanes side by side,
/// each as its own scalar walk would go).
#[inline(always)]
fn walk(mut q: Vec3A, next: impl Fn(Vec3A) -> Vec3A, go: impl Fn(Vec3A) -> BVec3A) -> Vec3A {
    loop {
        let moving = go(q);
        if !moving.any() {
            return q;
        }
        q = Vec3A::select(moving, next(q), q);
    }
}

/// ⌈log₂ x⌉ of a positive, normal f64, from its bits (no libm call: a frame is made for
/// every wide node).
fn ceil_log2(x: f64) -> i32 {
    let bits = x.to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as i32 - 1023;
    exponent + (bits & ((1 << 52) - 1) != 0) as i32
}

/// 2^x for x in E_MIN..=E_MAX.
fn pow2(x: i32) -> f32 {
    f32::from_bits(((x + 127) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// One plane, through [`dequantise`] so that the check is the traversal's own arithmetic.
    fn plane(p: f32, step: f32, q: u32) -> f32 {
        dequantise(Vec3A::splat(p), Vec3A::splat(step), Vec3A::splat(q as f32)).x
    }

    /// The frame's exponents by definition, every exponent tried: the smallest whose 255th
    /// plane reaches the box's top (the largest where none does).
    fn exponents_by_definition(bbox: &Aabb) -> [u8; 3] {
        [0, 1, 2].map(|axis| {
            let covers = |x: i32| plane(bbox.lo[axis], pow2(x), Q_MAX) >= bbox.hi[axis];
            let x = (E_MIN..=E_MAX).find(|&x| covers(x)).unwrap_or(E_MAX);
            (x + 127) as u8
        })
    }

    /// The bytes by definition, every byte tried: the largest q decoding to ≤ lo, moved
    /// down to the first byte of its value; the smallest decoding to ≥ hi (or 255), moved
    /// up to the last of its value.
    fn by_definition(frame: &Frame, child: &Aabb) -> ([u8; 3], [u8; 3]) {
        let s = step(frame.e);
        let (mut lo, mut hi) = ([0u8; 3], [0u8; 3]);
        for axis in 0..3 {
            let value = |q: u32| plane(frame.p[axis], s[axis], q);
            let l = (0..=Q_MAX)
                .rev()
                .find(|&q| value(q) <= child.lo[axis])
                .unwrap_or(0);
            lo[axis] = (0..=l).find(|&q| value(q) == value(l)).unwrap() as u8;
            let h = (0..=Q_MAX)
                .find(|&q| value(q) >= child.hi[axis])
                .unwrap_or(Q_MAX);
            hi[axis] = (h..=Q_MAX).rev().find(|&q| value(q) == value(h)).unwrap() as u8;
        }
        (lo, hi)
    }

    proptest! {
        /// The walks from the estimate find the bytes of the definition, on boxes from
        /// tiny (steps below the planes' f32 spacing) to huge.
        #[test]
        fn quantise_finds_the_bytes_of_the_definition(
            lo in prop::array::uniform3(-1e6f32..1e6),
            size in prop::array::uniform3(0.0f32..1.0),
            scale in -30i32..30,
            child in prop::array::uniform3((0.0f32..1.0, 0.0f32..1.0)),
        ) {
            let lo = Vec3::from(lo);
            let size = Vec3::from(size) * 2f32.powi(scale);
            let parent = Aabb { lo, hi: lo + size };
            let frame = Frame::new(&parent);
            prop_assert_eq!(frame.e, exponents_by_definition(&parent));
            let at = |k: usize, t: f32| lo[k] + size[k] * t;
            let (a, b) = (child.map(|c| c.0.min(c.1)), child.map(|c| c.0.max(c.1)));
            let child = Aabb {
                lo: Vec3::new(at(0, a[0]), at(1, a[1]), at(2, a[2])),
                hi: Vec3::new(at(0, b[0]), at(1, b[1]), at(2, b[2])),
            };
            prop_assert_eq!(frame.quantise(&child), by_definition(&frame, &child));
        }

        /// ⌈log₂ x⌉ = r: 2^(r−1) < x ≤ 2^r.
        /// The same at the ends of f32: steps near the smallest and largest exponents,
        /// frames whose top plane overflows to +∞.
        #[test]
        fn quantise_finds_the_bytes_at_the_ends_of_f32(
            (m, e, negative) in (1.0f32..2.0, -140i32..=126, any::<bool>()),
            below in 0i32..=30,
            child in prop::array::uniform3((0.0f32..1.0, 0.0f32..1.0)),
        ) {
            // A box corner of any exponent, and a size of the same order or below.
            let corner = if negative { -m } else { m } * 2f32.powi(e);
            let size = m * 2f32.powi(e + 1 - below);
            // Below f32's largest value (the box is finite); flat where the size is below
            // the corner's spacing.
            let (lo, hi) = match corner + size {
                hi if hi.is_finite() => (corner, hi),
                _ => (corner - size, corner),
            };
            let parent = Aabb { lo: Vec3::splat(lo), hi: Vec3::splat(hi) };
            let frame = Frame::new(&parent);
            prop_assert_eq!(frame.e, exponents_by_definition(&parent));
            let at = |t: f32| (lo + size * t).clamp(lo, hi);
            let child = Aabb {
                lo: Vec3::from(child.map(|c| at(c.0.min(c.1)))),
                hi: Vec3::from(child.map(|c| at(c.0.max(c.1)))),
            };
            prop_assert_eq!(frame.quantise(&child), by_definition(&frame, &child));
        }

        #[test]
        fn ceil_log2_is_the_smallest_power_above(m in 1.0f64..2.0, k in -1000i32..1000) {
            let x = m * 2f64.powi(k);
            let r = ceil_log2(x);
            prop_assert!(2f64.powi(r - 1) < x && x <= 2f64.powi(r));
        }
    }

    #[test]
    fn ceil_log2_of_powers_of_two_is_exact() {
        for k in -1000..1000 {
            assert_eq!(ceil_log2(2f64.powi(k)), k);
        }
    }
}
