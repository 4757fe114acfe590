//! The CPU twin of `bvh2_wide_node.wgsl`, step for step: the root box tested once from the
//! header, both child boxes of a record tested with the shared slab test, the hit children
//! visited nearest first (equal entries → the first child), only the far one pushed, leaf
//! ranges tested in order with the shared triangle test and tie rule, all in f32.

use glam::{Vec3, Vec3A};

use super::{is_leaf, Bvh2WideNode, ChildRef, COUNT_SHIFT};
use crate::accel::bvh::MAX_DEPTH;
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{
    intersect_triangle_bounded, prune_bound, Aabb, Hit, Ray, Robustness, TriHit, TriangleTest,
    WatertightRay, MISS, PARALLEL_INV,
};

impl Accel for Bvh2WideNode {
    fn bounds(&self) -> Aabb {
        match self.nodes.first() {
            Some(head) if !self.tris.is_empty() => head.box0(),
            _ => Aabb::EMPTY,
        }
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

/// Where the ray enters a box it hits: the largest near-plane distance, at least tmin
/// (WGSL `bvh2_wide_entry`). Only orders the two children of a record, never decides a
/// hit. Its operands are never NaN (finite box and origin, finite non-zero reciprocal), so
/// the lane-wise min/max give the WGSL result exactly.
#[inline(always)]
fn entry(lo: [f32; 3], hi: [f32; 3], origin: Vec3A, inv: Vec3A, tmin: f32) -> f32 {
    let t0 = (Vec3A::from_array(lo) - origin) * inv;
    let t1 = (Vec3A::from_array(hi) - origin) * inv;
    let e = t0.min(t1).max_element();
    if e > tmin {
        e
    } else {
        tmin
    }
}

impl Bvh2WideNode {
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
        let Some(head) = self.nodes.first() else {
            return best;
        };
        if !ray.is_valid() {
            return best;
        }
        let test = if MT {
            TriangleTest::MollerTrumbore
        } else {
            TriangleTest::Watertight
        };
        let widen = robustness.far_widen();
        let reject_near = robustness.rejects_near_hits();
        let inv = ray.inv_dir();
        let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
        let (origin_a, inv_a) = (Vec3A::from(ray.origin), Vec3A::from(inv));
        // The shared slab test: the scalar one (parallel-axis rule) for a ray parallel to
        // an axis, else its SIMD form, which equals it on such rays.
        let box_hit = |lo: [f32; 3], hi: [f32; 3], tmax: f32| {
            if parallel {
                let b = Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                };
                b.slab_hit(ray.origin, inv, ray.tmin, tmax, widen)
            } else {
                Aabb::slab_hit_nonparallel(
                    Vec3A::from_array(lo),
                    Vec3A::from_array(hi),
                    origin_a,
                    inv_a,
                    ray.tmin,
                    tmax,
                    widen,
                )
            }
        };
        let wr = WatertightRay::new(ray.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        // The root box, once, from the header.
        stats.nodes += 1;
        if !box_hit(head.lo0, head.hi0, prune) {
            return best;
        }
        let mut stack: [ChildRef; MAX_DEPTH] = [(0, 0); MAX_DEPTH];
        let mut sp = 0usize;
        let mut cur = head.child0();
        loop {
            if is_leaf(cur) {
                let first = cur.0 as usize;
                let count = (cur.1 >> COUNT_SHIFT) as usize;
                for lt in &self.tris[first..first + count] {
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
            } else {
                let node = &self.nodes[cur.0 as usize];
                stats.nodes += 1;
                let hit0 = box_hit(node.lo0, node.hi0, prune);
                let hit1 = box_hit(node.lo1, node.hi1, prune);
                if hit0 && hit1 {
                    let e0 = entry(node.lo0, node.hi0, origin_a, inv_a, ray.tmin);
                    let e1 = entry(node.lo1, node.hi1, origin_a, inv_a, ray.tmin);
                    let (near, far) = if e1 < e0 {
                        (node.child1(), node.child0())
                    } else {
                        (node.child0(), node.child1())
                    };
                    stack[sp] = far;
                    sp += 1;
                    cur = near;
                    continue;
                }
                if hit0 {
                    cur = node.child0();
                    continue;
                }
                if hit1 {
                    cur = node.child1();
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            cur = stack[sp];
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        best
    }
}
