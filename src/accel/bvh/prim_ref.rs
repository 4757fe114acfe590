//! The builders' primitive reference: a triangle's box in SIMD lanes with its index in the
//! spare lanes, 32 bytes, so that builders stream references through memory instead of
//! gathering boxes by index.

use glam::{Vec3, Vec3A, Vec4};

use crate::geometry::Aabb;

/// A box in SIMD lanes. Operands are never NaN (the mesh excludes non-finite triangles), so
/// the lane-wise min/max are exact.
#[derive(Clone, Copy)]
pub(crate) struct BoxA {
    pub lo: Vec3A,
    pub hi: Vec3A,
}

impl BoxA {
    pub const EMPTY: BoxA = BoxA {
        lo: Vec3A::splat(f32::MAX),
        hi: Vec3A::splat(-f32::MAX),
    };

    #[inline(always)]
    pub fn union(self, o: BoxA) -> BoxA {
        BoxA {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    #[inline(always)]
    pub fn grow(self, p: Vec3A) -> BoxA {
        BoxA {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    pub fn aabb(self) -> Aabb {
        Aabb {
            lo: Vec3::from(self.lo),
            hi: Vec3::from(self.hi),
        }
    }
}

impl From<Aabb> for BoxA {
    fn from(b: Aabb) -> BoxA {
        BoxA {
            lo: b.lo.into(),
            hi: b.hi.into(),
        }
    }
}

/// A primitive reference: its box, with the primitive's index in the spare `w` lanes as two
/// 16-bit halves stored as small whole floats (raw index bits would be denormals, which the
/// lane-wise arithmetic on `w` would make very slow).
#[derive(Clone, Copy)]
pub(crate) struct Ref {
    lo: Vec4,
    hi: Vec4,
}

impl Ref {
    pub fn new(b: &Aabb, id: u32) -> Ref {
        Ref {
            lo: b.lo.extend((id & 0xffff) as f32),
            hi: b.hi.extend((id >> 16) as f32),
        }
    }

    pub fn id(&self) -> u32 {
        self.lo.w as u32 | (self.hi.w as u32) << 16
    }

    #[inline(always)]
    pub fn bbox(&self) -> BoxA {
        BoxA {
            lo: Vec3A::from_vec4(self.lo),
            hi: Vec3A::from_vec4(self.hi),
        }
    }

    /// Same value as [`Aabb::center`].
    #[inline(always)]
    pub fn centroid(&self) -> Vec3A {
        (Vec3A::from_vec4(self.lo) + Vec3A::from_vec4(self.hi)) * 0.5
    }
}

pub(crate) fn bounds(refs: &[Ref]) -> (BoxA, BoxA) {
    refs.iter().fold((BoxA::EMPTY, BoxA::EMPTY), |(b, c), r| {
        (b.union(r.bbox()), c.grow(r.centroid()))
    })
}

/// Surface area, with the operations of the binned builder's lane-wise area.
#[inline(always)]
pub(crate) fn box_area(b: BoxA) -> f32 {
    let e = b.hi - b.lo;
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}
