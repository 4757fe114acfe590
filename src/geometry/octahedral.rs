//! Unit vectors in one 32-bit word: the octahedral map (Meyer et al. 2010, "On
//! floating-point normal vectors") with two 16-bit signed normalised coordinates. Shading
//! normals travel this way from the readers to both renderers: 4 bytes a corner instead of
//! 12, off by at most ~0.005° from the vector packed. The GPU decodes the same bits with
//! the same f32 operations (render.wgsl `unpack_normal`), so both devices shade with the
//! same normal.

use glam::Vec3;

/// A word no unit vector packs to (both halves −32768, which [`pack_unit`] never writes):
/// a triangle whose first corner holds it has no shading normals, and shades with its
/// geometric normal.
pub const NO_NORMAL: u32 = 0x8000_8000;

/// The scale of a 16-bit signed normalised coordinate: 1/32767, rounded to f32 once.
pub const SNORM16_SCALE: f32 = 1.0 / 32767.0;

/// `v` (any length above zero) packed; None for a zero or non-finite vector.
pub fn pack_unit(v: Vec3) -> Option<u32> {
    let (x, y) = fold(v)?;
    let q = |c: f32| ((c.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16 as u32;
    Some(q(x) | (q(y) << 16))
}

/// `v`'s point (x, y) on the octahedral map; None for a zero or non-finite vector.
fn fold(v: Vec3) -> Option<(f32, f32)> {
    let l1 = v.x.abs() + v.y.abs() + v.z.abs();
    if !(l1.is_finite() && l1 > 0.0) {
        return None;
    }
    let (x, y) = (v.x / l1, v.y / l1);
    Some(if v.z < 0.0 {
        ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y))
    } else {
        (x, y)
    })
}

/// The direction a word packs, not normalised (renderers normalise after interpolating).
pub fn unpack_unit(w: u32) -> Vec3 {
    let half = |bits: u32| (bits as u16 as i16) as f32 * SNORM16_SCALE;
    unfold(half(w & 0xffff), half(w >> 16))
}

/// The direction at (x, y) of the octahedral map, not normalised.
fn unfold(x: f32, y: f32) -> Vec3 {
    let z = 1.0 - x.abs() - y.abs();
    if z < 0.0 {
        Vec3::new((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y), z)
    } else {
        Vec3::new(x, y, z)
    }
}

/// The word of a triangle without a tangent (its [`TANGENT_PRESENT`] bit clear).
pub const NO_TANGENT: u32 = 0;
/// The bit of a packed tangent that says it is there.
pub const TANGENT_PRESENT: u32 = 1 << 31;
/// The bit of a packed tangent that says the bitangent is −(n × t) (glTF's w = −1).
pub const TANGENT_FLIPPED: u32 = 1 << 30;
/// The scale of a tangent's 15-bit signed normalised coordinates: 1/16383.
pub const SNORM15_SCALE: f32 = 1.0 / 16383.0;

/// A tangent `t` (any length above zero) and its handedness (`flipped`: the bitangent is
/// −(n × t)) in one word: the octahedral map in two 15-bit coordinates (within ~0.01°),
/// then the two bits; None for a zero or non-finite vector. WGSL `unpack_tangent` reads it.
pub fn pack_tangent(t: Vec3, flipped: bool) -> Option<u32> {
    let (x, y) = fold(t)?;
    let q = |c: f32| (((c.clamp(-1.0, 1.0) * 16383.0).round() as i32) as u32) & 0x7fff;
    let hand = if flipped { TANGENT_FLIPPED } else { 0 };
    Some(q(x) | (q(y) << 15) | TANGENT_PRESENT | hand)
}

/// The tangent a word packs (not normalised) and whether it is flipped; None for
/// [`NO_TANGENT`].
pub fn unpack_tangent(w: u32) -> Option<(Vec3, bool)> {
    if w & TANGENT_PRESENT == 0 {
        return None;
    }
    let x = (((w << 17) as i32) >> 17) as f32 * SNORM15_SCALE;
    let y = (((w << 2) as i32) >> 17) as f32 * SNORM15_SCALE;
    Some((unfold(x, y), w & TANGENT_FLIPPED != 0))
}

/// ±1 by the sign bit's absence: 1 for +0 and for positive numbers.
fn sign(x: f32) -> f32 {
    if x >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_tangents_come_back_with_their_handedness() {
        let dirs = [
            Vec3::new(0.3, -0.8, 0.2),
            Vec3::new(-0.1, 0.4, -0.9),
            Vec3::X,
            -Vec3::Z,
        ];
        for d in dirs {
            for flipped in [false, true] {
                let w = pack_tangent(d, flipped).unwrap();
                assert_ne!(w, NO_TANGENT);
                let (t, f) = unpack_tangent(w).unwrap();
                assert_eq!(f, flipped);
                let angle = t
                    .normalize()
                    .dot(d.normalize())
                    .min(1.0)
                    .acos()
                    .to_degrees();
                assert!(angle < 0.02, "{d}: {angle}°");
            }
        }
        assert_eq!(unpack_tangent(NO_TANGENT), None);
        assert_eq!(pack_tangent(Vec3::ZERO, false), None);
    }

    #[test]
    fn packed_directions_come_back_within_a_hundredth_of_a_degree() {
        let mut worst = 0.0f64;
        let mut state = 12345u32;
        let mut next = || {
            state = state.wrapping_mul(747796405).wrapping_add(2891336453);
            (state >> 8) as f32 / 16777216.0 * 2.0 - 1.0
        };
        let mut dirs: Vec<Vec3> = (0..100_000)
            .map(|_| Vec3::new(next(), next(), next()))
            .collect();
        dirs.extend([Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]);
        dirs.push(Vec3::new(1e-30, -1e-30, -1e-30));
        for d in dirs.into_iter().filter(|d| d.length() > 1e-35) {
            let w = pack_unit(d).unwrap();
            assert_ne!(w, NO_NORMAL);
            let back = unpack_unit(w).as_dvec3().normalize();
            let angle = back
                .dot(d.as_dvec3().normalize())
                .min(1.0)
                .acos()
                .to_degrees();
            worst = worst.max(angle);
        }
        assert!(worst < 0.01, "{worst}°");
        assert!(worst > 0.0);
        for bad in [Vec3::ZERO, Vec3::NAN, Vec3::new(f32::INFINITY, 0.0, 0.0)] {
            assert_eq!(pack_unit(bad), None);
        }
    }
}
