//! Random numbers and sampling shared, operation for operation, with shaders/render.wgsl:
//! integer hashing only, no transcendental functions (their GPU implementations differ),
//! so CPU and GPU draw the same numbers and the same directions.

use glam::Vec3;

use crate::geometry::dot;

/// PCG hash (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering").
#[inline]
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Per-(seed, pixel, sample) random stream.
pub struct Rng(u32);

impl Rng {
    /// The stream of sample `sample` of pixel `pixel` (row-major index) under `seed`.
    pub fn new(seed: u32, pixel: u32, sample: u32) -> Rng {
        Rng(pcg(seed ^ pcg(pixel ^ pcg(sample))))
    }

    /// Next value: the PCG hash of the previous one.
    pub fn next_u32(&mut self) -> u32 {
        self.0 = pcg(self.0);
        self.0
    }

    /// Uniform in [0, 1), 24 bits.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// Orthonormal basis around unit n (Duff et al. 2017, "Building an Orthonormal Basis,
/// Revisited").
#[inline]
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Cosine-weighted direction about unit n: a point of the unit disk by rejection (at most
/// 16 tries, then the centre) lifted onto the hemisphere.
pub fn cosine_direction(n: Vec3, rng: &mut Rng) -> Vec3 {
    let (mut x, mut y) = (0.0f32, 0.0f32);
    for _ in 0..16 {
        let a = 2.0 * rng.next_f32() - 1.0;
        let b = 2.0 * rng.next_f32() - 1.0;
        if a * a + b * b <= 1.0 {
            (x, y) = (a, b);
            break;
        }
    }
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    let (t, b) = basis(n);
    t * x + b * y + n * z
}

/// The relative error bound γ(7) of a point interpolated from a triangle's vertices by
/// barycentric weights (pbrt-v4 §6.8.5): per component, |p − p_exact| ≤ POINT_ERROR ·
/// (|b0·v0| + |b1·v1| + |b2·v2|).
pub const POINT_ERROR: f32 = crate::geometry::gamma(7.0);

/// The error bound of the point `v0·b0 + v1·b1 + v2·b2`, per component (see
/// [`POINT_ERROR`]). WGSL `point_error` is the same.
#[inline]
pub fn point_error(v: &[Vec3; 3], b0: f32, b1: f32, b2: f32) -> Vec3 {
    ((v[0] * b0).abs() + (v[1] * b1).abs() + (v[2] * b2).abs()) * POINT_ERROR
}

/// pbrt-v4's ray-origin offset (§6.8.6): moves p along n (facing the side the ray leaves
/// to) by the projection of its error bound `err` onto n, then one more float outwards per
/// component, so the new origin lies strictly on that side of the exact surface, wherever p
/// lies in the scene: no self-intersection, and no scene-size epsilon.
pub fn offset_origin(p: Vec3, err: Vec3, n: Vec3) -> Vec3 {
    let d = dot(n.abs(), err);
    let off = n * d;
    let po = p + off;
    let away = |x: f32, o: f32| {
        if o > 0.0 {
            x.next_up()
        } else if o < 0.0 {
            x.next_down()
        } else {
            x
        }
    };
    Vec3::new(away(po.x, off.x), away(po.y, off.y), away(po.z, off.z))
}
