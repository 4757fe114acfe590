//! Vector operations written out, so that the CPU does what the WGSL does, operation for
//! operation (glam's may fuse or reorder).

use glam::Vec3;

/// a · b, summed x, y, z in order.
#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// a × b.
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// v / |v| (a division, not a reciprocal square root: exact on both sides).
#[inline]
pub fn normalize(v: Vec3) -> Vec3 {
    let l = dot(v, v).sqrt();
    Vec3::new(v.x / l, v.y / l, v.z / l)
}
