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
    /// The reference of box `b` of primitive `id`, a bound of −0 made +0 (adding +0 leaves
    /// every other value as it is). SSE's lane-wise min and max return one of two equal
    /// operands by its position, so with both zeros about, a union's zero would depend on
    /// the order the boxes are joined in: two bin sets, chunks on several threads, or a
    /// builder's own order. Without −0 every union has the same bits whatever the order.
    /// (A centroid of subnormal bounds can still round to −0; bins and sorts by value are
    /// unaffected.)
    pub fn new(b: &Aabb, id: u32) -> Ref {
        Ref {
            lo: (b.lo + Vec3::ZERO).extend((id & 0xffff) as f32),
            hi: (b.hi + Vec3::ZERO).extend((id >> 16) as f32),
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn bits(b: BoxA) -> [u32; 6] {
        let (lo, hi) = (b.lo.to_array(), b.hi.to_array());
        [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
    }

    proptest! {
        /// References hold no −0, so their boxes' union has the same bits in any order
        /// (here: in order, reversed, and as two alternating sets joined), while the boxes
        /// as given, −0 and +0 both among them, need not.
        #[test]
        fn unions_of_references_do_not_depend_on_the_order(
            coords in prop::collection::vec(prop::array::uniform6(0u8..4), 1..40),
        ) {
            // 0: −0, 1: +0, 2: −1, 3: 1.
            let value = |c: u8| [-0.0f32, 0.0, -1.0, 1.0][c as usize];
            let refs: Vec<Ref> = coords
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let (a, b) = (
                        Vec3::new(value(c[0]), value(c[1]), value(c[2])),
                        Vec3::new(value(c[3]), value(c[4]), value(c[5])),
                    );
                    Ref::new(&Aabb { lo: a.min(b), hi: a.max(b) }, i as u32)
                })
                .collect();
            for r in &refs {
                let b = r.bbox();
                prop_assert!(bits(b).iter().all(|&x| x != (-0.0f32).to_bits()));
            }
            let fold = |it: &mut dyn Iterator<Item = &Ref>| {
                it.fold(BoxA::EMPTY, |b, r| b.union(r.bbox()))
            };
            let forward = fold(&mut refs.iter());
            let backward = fold(&mut refs.iter().rev());
            let sets = fold(&mut refs.iter().step_by(2)).union(fold(&mut refs.iter().skip(1).step_by(2)));
            prop_assert_eq!(bits(forward), bits(backward));
            prop_assert_eq!(bits(forward), bits(sets));
        }
    }

    /// Without the +0 in `Ref::new`, the order shows: −0 then +0 keeps +0, and the reverse
    /// keeps −0 (so the test above can fail). SSE's min and max; other targets may order
    /// the zeros.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn raw_unions_of_signed_zeros_depend_on_the_order() {
        let (neg, pos) = (
            BoxA::from(Aabb {
                lo: Vec3::splat(-0.0),
                hi: Vec3::ONE,
            }),
            BoxA::from(Aabb {
                lo: Vec3::ZERO,
                hi: Vec3::ONE,
            }),
        );
        let a = BoxA::EMPTY.union(neg).union(pos);
        let b = BoxA::EMPTY.union(pos).union(neg);
        assert_ne!(bits(a), bits(b));
    }
}
