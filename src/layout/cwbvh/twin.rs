//! The CPU twin of `cwbvh.wgsl`, step for step: the same group stack (a node's remaining
//! hit children pushed before descending into the one with the highest hit-mask bit), the
//! same octant order, child boxes dequantised with the same f32 arithmetic and tested with
//! the shared slab test against the same bound, a node's leaf triangles tested lowest bit
//! first right after the node, and the same tie rule, all in f32.

use glam::{Vec3, Vec3A};

use super::{CwNode, Cwbvh, COUNT_SHIFT, STACK_SIZE, TRI_BITS, WIDTH};
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, MISS, PARALLEL_INV};
use crate::layout::leaf_tri::{with_leaf_test, LeafRay};

/// Hit-mask bits of internal children.
const NODE_BITS: u32 = !((1 << TRI_BITS) - 1);
/// Hit-mask bits of triangles.
const TRI_MASK: u32 = (1 << TRI_BITS) - 1;
/// A meta byte's bit index field.
const INDEX_MASK: u32 = (1 << COUNT_SHIFT) - 1;

impl Accel for Cwbvh {
    fn bounds(&self) -> Aabb {
        self.bounds
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
        with_leaf_test!(robustness, self.walk(ray, query, robustness, stats))
    }
}

/// What the child tests of one ray share.
struct RayBox {
    origin: Vec3,
    inv: Vec3,
    origin_a: Vec3A,
    inv_a: Vec3A,
    tmin: f32,
    parallel: bool,
    widen: f32,
    /// 7 ^ octant: XORed into an internal child's slot to give its traversal rank.
    oct_inv: u32,
}

impl RayBox {
    /// The hit mask of `node`'s children whose boxes the ray enters before `prune`:
    /// internal children at bit TRI_BITS + (slot ^ oct_inv), leaf triangles at their offsets.
    #[inline(always)]
    fn child_hits(&self, node: &CwNode, prune: f32) -> u32 {
        let mut hits = 0;
        for s in 0..WIDTH {
            let m = node.child_meta[s] as u32;
            if m == 0 {
                continue;
            }
            let (lo, hi) = node.child_box(s);
            let enter = if self.parallel {
                let b = Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                };
                b.slab_hit(self.origin, self.inv, self.tmin, prune, self.widen)
            } else {
                let (o, inv) = (self.origin_a, self.inv_a);
                Aabb::slab_hit_nonparallel(lo, hi, o, inv, self.tmin, prune, self.widen)
            };
            if enter {
                let inner = (node.imask as u32 >> s) & 1;
                hits |= (m >> COUNT_SHIFT) << ((m & INDEX_MASK) ^ (self.oct_inv * inner));
            }
        }
        hits
    }
}

impl Cwbvh {
    /// The traversal, with the triangle test `TEST` (`leaf_tri::leaf_test`).
    #[inline(always)]
    fn walk<const TEST: u8>(
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
        let leaf = LeafRay::new(ray, robustness);
        let inv = ray.inv_dir();
        let octant = (ray.dir.x < 0.0) as u32
            | ((ray.dir.y < 0.0) as u32) << 1
            | ((ray.dir.z < 0.0) as u32) << 2;
        let rb = RayBox {
            origin: ray.origin,
            inv,
            origin_a: Vec3A::from(ray.origin),
            inv_a: Vec3A::from(inv),
            tmin: ray.tmin,
            parallel: inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any(),
            widen: robustness.far_widen(),
            oct_inv: (WIDTH as u32 - 1) ^ octant,
        };
        // Boxes are cut against the best t plus a few ulps (prune_bound), so a triangle at
        // exactly the best t in a later box is still tested: equal t → smaller index.
        let mut prune = prune_bound(best.t);
        let mut stack = [[0u32; 2]; STACK_SIZE];
        let mut sp = 0usize;
        // The group: [first child node, hit internal children (high byte) | imask]. At the
        // top of the loop it always holds a node: first the root, alone in the top bit.
        let mut group = [0u32, 1 << 31];
        loop {
            let bit = 31 - group[1].leading_zeros();
            group[1] &= !(1 << bit);
            if group[1] & NODE_BITS != 0 {
                stack[sp] = group;
                sp += 1;
            }
            let slot = (bit - TRI_BITS) ^ rb.oct_inv;
            let idx = group[0] + (group[1] & ((1 << slot) - 1)).count_ones();
            let node = &self.nodes[idx as usize];
            stats.nodes += 1;
            let hits = rb.child_hits(node, prune);
            group = [node.child_base, (hits & NODE_BITS) | node.imask as u32];
            let mut tri_hits = hits & TRI_MASK;
            while tri_hits != 0 {
                let b = tri_hits.trailing_zeros();
                tri_hits &= tri_hits - 1;
                let lt = std::slice::from_ref(&self.tris[(node.tri_base + b) as usize]);
                if leaf.test_leaf::<TEST>(lt, query == Query::Any, &mut best, &mut prune, stats) {
                    return best;
                }
            }
            if group[1] & NODE_BITS == 0 {
                if sp == 0 {
                    break;
                }
                sp -= 1;
                group = stack[sp];
            }
        }
        debug_assert!(best.prim == MISS || best.t >= ray.tmin);
        best
    }
}
