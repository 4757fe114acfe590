//! The CPU twin of `cwbvh.wgsl`, step for step: the same group stack (a node's remaining
//! hit children pushed before descending into the one with the highest hit-mask bit), the
//! same octant order, child boxes dequantised with the same f32 arithmetic and tested with
//! the shared slab test against the same bound (four slots at a time in SIMD lanes for a ray
//! with no parallel axis, equal to it lane for lane), a node's leaf triangles tested lowest bit
//! first right after the node, and the same tie rule, all in f32.

use glam::{Vec3, Vec3A, Vec4};

use super::quantise::step;
use super::{CwNode, Cwbvh, COUNT_SHIFT, STACK_SIZE, TRI_BITS, WIDTH};
use crate::accel::{Accel, Query, RayStats};
use crate::geometry::{prune_bound, Aabb, Hit, Ray, Robustness, SlabRay4, MISS, PARALLEL_INV};
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
    tmin: f32,
    widen: f32,
    /// For a ray with no parallel axis: its lanes for four boxes at a time.
    slab4: Option<SlabRay4>,
    /// 7 ^ octant: XORed into an internal child's slot to give its traversal rank.
    oct_inv: u32,
}

impl RayBox {
    /// Bit s set: slot s's box (used or not) is entered before `prune`.
    #[inline(always)]
    fn entered(&self, node: &CwNode, prune: f32) -> u32 {
        match &self.slab4 {
            // Slots 0–3 and 4–7 in SIMD lanes: per lane the dequantisation p + q · step of
            // `CwNode::child_box` and the slab test of `SlabRay4`, which equal the scalar ones.
            Some(s) => {
                let (p, step) = (Vec3A::from_array(node.p), step(node.e));
                let mut bits = 0;
                for half in 0..2 {
                    let lanes = |q: &[[u8; WIDTH]; 3], axis: usize| {
                        let b = &q[axis][4 * half..4 * half + 4];
                        let q = Vec4::new(b[0] as f32, b[1] as f32, b[2] as f32, b[3] as f32);
                        Vec4::splat(p[axis]) + q * Vec4::splat(step[axis])
                    };
                    let lo = [0, 1, 2].map(|a| lanes(&node.q_lo, a));
                    let hi = [0, 1, 2].map(|a| lanes(&node.q_hi, a));
                    let (enter, exit) = s.intervals(lo, hi, prune);
                    bits |= enter.cmple(exit).bitmask() << (4 * half);
                }
                bits
            }
            None => (0..WIDTH).fold(0, |bits, s| {
                let (lo, hi) = node.child_box(s);
                let b = Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                };
                let hit = b.slab_hit(self.origin, self.inv, self.tmin, prune, self.widen);
                bits | (hit as u32) << s
            }),
        }
    }

    /// The hit mask of `node`'s children whose boxes the ray enters before `prune`:
    /// internal children at bit TRI_BITS + (slot ^ oct_inv), leaf triangles at their offsets.
    #[inline(always)]
    fn child_hits(&self, node: &CwNode, prune: f32) -> u32 {
        let mut entered = self.entered(node, prune);
        let mut hits = 0;
        while entered != 0 {
            let s = entered.trailing_zeros() as usize;
            entered &= entered - 1;
            // An empty slot (meta 0) adds nothing.
            let m = node.child_meta[s] as u32;
            let inner = (node.imask as u32 >> s) & 1;
            hits |= (m >> COUNT_SHIFT) << ((m & INDEX_MASK) ^ (self.oct_inv * inner));
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
        let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
        let widen = robustness.far_widen();
        let rb = RayBox {
            origin: ray.origin,
            inv,
            tmin: ray.tmin,
            widen,
            slab4: (!parallel).then(|| SlabRay4::new(ray.origin, inv, ray.tmin, widen)),
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
