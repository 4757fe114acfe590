//! The CPU twin of `bvh4.wgsl`, step for step: the same four-box slab test (slab4.rs), the
//! same child order (entry distance, then slot), the same stack of (node and slot, entry)
//! entries popped only while their entry is within the prune bound, the same triangle
//! tests in the same operation order and the same tie rule, all in f32.

use glam::Vec4;

use super::slab4::{slab_hit4, RayLanes};
use super::{Bvh4, Bvh4Node, INNER, STACK_SIZE, WIDTH};
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{
    intersect_triangle_bounded, prune_bound, Aabb, Hit, Ray, Robustness, TriHit, TriangleTest,
    WatertightRay, MISS,
};

/// A pushed child: its node and slot (`node << 2 | slot`), and the entry distance its box
/// was entered at (WGSL `Bvh4Entry`). 8 bytes, not the child and kind themselves (12): a
/// popped entry reads them again from the node, and the kernels' stack stays small.
#[derive(Clone, Copy, Debug)]
struct Entry {
    slot: u32,
    enter: f32,
}

impl Accel for Bvh4 {
    fn bounds(&self) -> Aabb {
        let root = &self.nodes[0];
        (0..WIDTH)
            .filter(|&k| root.kind[k] != 0)
            .fold(Aabb::EMPTY, |b, k| b.union(root.bbox(k)))
    }

    #[inline]
    fn intersect(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        // One specialised loop per triangle test (the choice is not re-made per triangle).
        match robustness.triangle_test {
            TriangleTest::Watertight => self.walk::<false>(ray, query, robustness, stats),
            TriangleTest::MollerTrumbore => self.walk::<true>(ray, query, robustness, stats),
        }
    }
}

/// The order hit children are visited in: `rank[k]` = how many children of the bit set
/// `hit` come before slot k by (entry distance, slot). Slots not hit get no rank.
#[inline(always)]
fn ranks(hit: u32, enter: [f32; WIDTH]) -> [u32; WIDTH] {
    let mut rank = [0u32; WIDTH];
    for j in 0..WIDTH {
        if hit >> j & 1 != 0 {
            for (k, r) in rank.iter_mut().enumerate() {
                *r += (enter[j] < enter[k] || (enter[j] == enter[k] && j < k)) as u32;
            }
        }
    }
    rank
}

impl Bvh4 {
    /// The traversal, with Möller–Trumbore when `MT`, else the watertight test.
    #[inline(always)]
    fn walk<const MT: bool>(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        if !ray.is_valid() {
            return best;
        }
        let test = if MT {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        let reject_near = robustness.rejects_near_hits();
        let lanes = RayLanes::new(ray.origin, ray.inv_dir(), robustness.far_widen());
        let wr = WatertightRay::new(ray.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        let mut stack = [Entry {
            slot: 0,
            enter: 0.0,
        }; STACK_SIZE];
        let mut sp = 0usize;
        let (mut child, mut kind) = (0u32, INNER);
        'walk: loop {
            let mut descended = false;
            if kind == INNER {
                let index = child;
                let node: &Bvh4Node = &self.nodes[index as usize];
                stats.nodes += 1;
                let plane = |p: [f32; WIDTH]| Vec4::from_array(p);
                let lo = [plane(node.lo_x), plane(node.lo_y), plane(node.lo_z)];
                let hi = [plane(node.hi_x), plane(node.hi_y), plane(node.hi_z)];
                let (hit4, enter4) = slab_hit4(lo, hi, &lanes, ray.tmin, prune);
                let used = (0..WIDTH).fold(0, |m, k| m | ((node.kind[k] != 0) as u32) << k);
                let hit = hit4.bitmask() & used;
                if hit != 0 {
                    descended = true;
                    let n = hit.count_ones();
                    if n == 1 {
                        let k = hit.trailing_zeros() as usize;
                        (child, kind) = (node.child[k], node.kind[k]);
                    } else {
                        // The nearest is visited next; the others pushed farthest first.
                        let enter = enter4.to_array();
                        let rank = ranks(hit, enter);
                        for k in 0..WIDTH {
                            if hit >> k & 1 == 0 {
                                continue;
                            }
                            if rank[k] == 0 {
                                (child, kind) = (node.child[k], node.kind[k]);
                            } else {
                                stack[sp + (n - 1 - rank[k]) as usize] = Entry {
                                    slot: index << 2 | k as u32,
                                    enter: enter[k],
                                };
                            }
                        }
                        sp += (n - 1) as usize;
                    }
                }
            } else {
                let first = child as usize;
                for lt in &self.tris[first..first + kind as usize] {
                    stats.tris += 1;
                    let tri = lt.triangle();
                    let h = intersect_triangle_bounded(test, &tri, ray, &wr, ray.tmin, best.t);
                    if let Some(h) = h {
                        let TriHit { t, u, v, .. } = h;
                        if !Hit::beats(t, lt.prim, best.t, best.prim) {
                            continue;
                        }
                        if reject_near && h.maybe_behind_origin() {
                            continue;
                        }
                        best = Hit {
                            t,
                            prim: lt.prim,
                            u,
                            v,
                        };
                        prune = h.prune();
                        if query == Query::Any {
                            return best;
                        }
                    }
                }
            }
            if !descended {
                // The nearest entry whose box is still entered before the prune bound (the
                // slab test again with the new bound: only its tmax changed).
                loop {
                    if sp == 0 {
                        break 'walk;
                    }
                    sp -= 1;
                    let e = stack[sp];
                    if e.enter <= prune {
                        let (node, k) = (&self.nodes[(e.slot >> 2) as usize], e.slot as usize & 3);
                        (child, kind) = (node.child[k], node.kind[k]);
                        break;
                    }
                }
            }
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_order_by_entry_then_slot() {
        let r = ranks(0b1011, [2.0, 1.0, 0.0, 1.0]);
        assert_eq!((r[0], r[1], r[3]), (2, 0, 1));
        let r = ranks(0b1111, [-0.0, 0.0, 0.0, -1.0]);
        assert_eq!(r, [1, 2, 3, 0]);
    }
}
