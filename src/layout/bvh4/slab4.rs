//! The slab test of four boxes at once, one box per SIMD lane. Lane k does
//! [`Aabb::slab_hit`](crate::geometry::Aabb::slab_hit)'s operations in its order on box k —
//! the far-plane widening, the parallel-axis rule, the ray bounds last — so each lane's
//! answer is slab_hit's (a unit test below compares them), and `bvh4_slab` in bvh4.wgsl is
//! the same again, lane for lane. The lane-wise min/max do not handle NaN, but no operand is
//! NaN (finite boxes, origin and reciprocal; overflow gives ±∞, never ∞−∞ or 0·∞), and of
//! non-NaN values they give the scalar result.

use glam::{BVec4A, Vec3, Vec4};

use crate::geometry::PARALLEL_INV;

/// A ray's values splatted across the lanes, once per ray.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayLanes {
    origin: [Vec4; 3],
    inv_dir: [Vec4; 3],
    /// Axes the ray is parallel to (|inv| ≥ PARALLEL_INV).
    parallel: [bool; 3],
    /// The far-plane factor (`Robustness::far_widen`).
    widen: f32,
}

impl RayLanes {
    pub fn new(origin: Vec3, inv_dir: Vec3, widen: f32) -> RayLanes {
        RayLanes {
            origin: origin.to_array().map(Vec4::splat),
            inv_dir: inv_dir.to_array().map(Vec4::splat),
            parallel: inv_dir.to_array().map(|i| i.abs() >= PARALLEL_INV),
            widen,
        }
    }
}

/// Per lane: whether [max(t_near, tmin), min(t_far, tmax)] is non-empty for the box
/// (`lo[axis]`, `hi[axis]` hold the four boxes' planes), and max(t_near, tmin), the entry
/// distance (meaningful where the box is hit).
#[inline(always)]
pub(super) fn slab_hit4(
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    ray: &RayLanes,
    tmin: f32,
    tmax: f32,
) -> (BVec4A, Vec4) {
    let mut tn = [Vec4::ZERO; 3];
    let mut tf = [Vec4::ZERO; 3];
    for a in 0..3 {
        let (o, inv) = (ray.origin[a], ray.inv_dir[a]);
        let t0 = (lo[a] - o) * inv;
        let t1 = (hi[a] - o) * inv;
        (tn[a], tf[a]) = (t0.min(t1), t0.max(t1) * ray.widen);
        // Rare (axis-aligned rays), one branch for all four boxes.
        if ray.parallel[a] {
            let inside = lo[a].cmple(o) & o.cmple(hi[a]);
            let big = Vec4::select(inside, Vec4::splat(f32::MAX), Vec4::splat(-f32::MAX));
            (tn[a], tf[a]) = (-big, big);
        }
    }
    // max/min with the ray bounds last.
    let enter = tn[0].max(tn[1]).max(tn[2]).max(Vec4::splat(tmin));
    let exit = tf[0].min(tf[1]).min(tf[2]).min(Vec4::splat(tmax));
    (enter.cmple(exit), enter)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Aabb, FAR_WIDEN};

    /// Each lane equals the scalar slab test on its box, for boxes with faces on the origin,
    /// flat boxes, and rays parallel (±0, tiny) or not to each axis.
    #[test]
    fn each_lane_is_the_scalar_slab_test() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut f = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let comps = [0.0, -0.0, 1e-31, -1e-31, 3e-30, 1.0, -0.7, 1e30];
        let (mut hits, mut parallel_hits) = (0, 0);
        for i in 0..20_000 {
            let origin = Vec3::new(f(), f(), f()) * 2.0;
            let mut dir = Vec3::new(f(), f(), f());
            for a in 0..3 {
                if (i >> a) % 3 == 0 {
                    dir[a] = comps[(i / 7 + a) % comps.len()];
                }
            }
            if dir == Vec3::ZERO {
                continue;
            }
            let inv = crate::geometry::Ray::new(origin, dir, 0.0, 1.0).inv_dir();
            let boxes: [Aabb; 4] = std::array::from_fn(|k| {
                let (a, b) = (Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()));
                let mut bx = Aabb::EMPTY.grow(a).grow(b);
                // Faces through the origin, and flat boxes.
                if (i + k) % 4 == 0 {
                    bx.lo[k % 3] = origin[k % 3];
                }
                if (i + k) % 5 == 0 {
                    bx.hi[(k + 1) % 3] = origin[(k + 1) % 3];
                }
                if (i + k) % 6 == 0 {
                    bx.hi[k % 3] = bx.lo[k % 3];
                }
                bx
            });
            let planes = |v: fn(&Aabb) -> Vec3| -> [Vec4; 3] {
                std::array::from_fn(|a| Vec4::from_array(boxes.map(|b| v(&b)[a])))
            };
            let (lo, hi) = (planes(|b| b.lo), planes(|b| b.hi));
            let (tmin, tmax) = if i % 3 == 0 {
                (-1e30, 1e30)
            } else {
                (0.0, f().abs() * 3.0)
            };
            for widen in [FAR_WIDEN, 1.0] {
                let lanes = RayLanes::new(origin, inv, widen);
                let (hit, _) = slab_hit4(lo, hi, &lanes, tmin, tmax);
                for (k, b) in boxes.iter().enumerate() {
                    let want = b.slab_hit(origin, inv, tmin, tmax, widen);
                    assert_eq!(hit.test(k), want, "box {b:?}, origin {origin}, dir {dir}");
                    hits += want as usize;
                    parallel_hits += (want && lanes.parallel.contains(&true)) as usize;
                }
            }
        }
        // Both answers occur often, for parallel rays too.
        println!("{hits} hits ({parallel_hits} of parallel rays) in 160,000 box tests");
        assert!(hits > 4_000 && hits < 150_000, "{hits} hits");
        assert!(parallel_hits > 400, "{parallel_hits} parallel hits");
    }
}
