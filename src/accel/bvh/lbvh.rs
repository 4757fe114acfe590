//! LBVH: the linear BVH of Lauterbach et al. (2009) with the radix-tree construction of
//! Karras (2012). Primitives sorted along a 30-bit Morton curve become the leaves of a
//! binary radix tree whose every inner node is found on its own (no node waits for
//! another), then boxes are unioned bottom-up. Each step is data-parallel, so the same
//! algorithm runs as WGSL kernels (`lbvh.wgsl`, driven by `gpu::build_lbvh`); this file is
//! its CPU twin, and both make the same [`RadixTree`]: same sort, same nodes, same boxes.
//!
//! Every step is exact on both devices: the centroid is kept doubled (`lo + hi`, one
//! rounding), the Morton cell comes from one subtraction and two multiplications by powers
//! of two (no division, whose rounding WGSL leaves loose), and boxes are minima and maxima.
//! The tree then becomes lancer's tree as PLOC's does: leaves where the SAH prefers them.

use rayon::prelude::*;

use super::cluster_tree::{to_node, Clusters};
use super::prims::Prims;
use super::tree::Node;
use super::BuildOptions;
use crate::geometry::Aabb;

/// Bits per axis of the Morton code (30 in all: the code fits a WGSL `u32`).
pub const CODE_BITS: u32 = 10;

/// A child reference of the radix tree with this bit set is a leaf: the rest is its place in
/// [`RadixTree::sorted`]; without it, an inner node.
pub const LEAF_BIT: u32 = 1 << 31;

/// Most primitives the radix tree takes (its signed place arithmetic stays within an `i32`
/// on the GPU).
pub const MAX_PRIMS: usize = 1 << 29;

/// The radix tree both devices build: the primitives in Morton order and `n - 1` inner nodes
/// (node 0 is the root).
#[derive(Clone, Debug, PartialEq)]
pub struct RadixTree {
    /// Primitive positions (into the builder's input) in Morton order; equal codes in
    /// position order.
    pub sorted: Vec<u32>,
    /// Children of each inner node: an inner node's index, or [`LEAF_BIT`] | a place in
    /// `sorted`.
    pub kids: Vec<[u32; 2]>,
    /// Bounds of each inner node's primitives.
    pub boxes: Vec<Aabb>,
}

impl RadixTree {
    /// Refuses a radix tree that is not one over `n` primitives (one made in code, or a
    /// device's that went wrong), naming the first fault: `sorted` a permutation of `0..n`,
    /// `n − 1` inner nodes with their boxes, every child in range, every node but the root
    /// (inner node 0) the child of exactly one node and reached from the root. Then every
    /// walk of it ends.
    pub fn check(&self, n: usize) -> Result<(), String> {
        let inner = n.saturating_sub(1);
        if self.sorted.len() != n || self.kids.len() != inner || self.boxes.len() != inner {
            return Err(format!(
                "{} sorted places, {} inner nodes and {} boxes for {n} primitives (want {n}, \
                 {inner}, {inner})",
                self.sorted.len(),
                self.kids.len(),
                self.boxes.len()
            ));
        }
        let mut placed = vec![None; n];
        for (p, &s) in self.sorted.iter().enumerate() {
            let Some(at) = placed.get_mut(s as usize) else {
                return Err(format!("sorted place {p} holds primitive {s} of {n}"));
            };
            if let Some(q) = at.replace(p) {
                return Err(format!("sorted places {q} and {p} both hold primitive {s}"));
            }
        }
        // Parents: one for every node but the root, none for the root.
        let mut leaf_parent = vec![false; n];
        let mut inner_parent = vec![false; inner];
        for (k, pair) in self.kids.iter().enumerate() {
            for &c in pair {
                let (taken, what, of) = match c & LEAF_BIT {
                    0 => (inner_parent.get_mut(c as usize), "inner node", inner),
                    _ => (leaf_parent.get_mut((c & !LEAF_BIT) as usize), "leaf", n),
                };
                let i = c & !LEAF_BIT;
                let Some(t) = taken else {
                    return Err(format!(
                        "inner node {k} names {what} {i}, but there are {of}"
                    ));
                };
                if std::mem::replace(t, true) {
                    return Err(format!("{what} {i} is the child of two nodes"));
                }
            }
        }
        if inner_parent.first() == Some(&true) {
            return Err("the root (inner node 0) is a child".into());
        }
        // Each node has one parent and the root none, so this walk meets every node at most
        // once; a node it misses lies on a cycle.
        let mut reached = 0usize;
        let mut stack: Vec<u32> = if inner > 0 { vec![0] } else { Vec::new() };
        while let Some(k) = stack.pop() {
            reached += 1;
            stack.extend(self.kids[k as usize].iter().filter(|&&c| c & LEAF_BIT == 0));
        }
        if reached != inner {
            return Err(format!(
                "{} of its {inner} inner nodes are not reached from the root (a cycle)",
                inner - reached
            ));
        }
        Ok(())
    }
}

/// The Morton cell of a doubled centroid: `((c - lo) · s1) · s2`, truncated to
/// [`CODE_BITS`] bits per axis.
#[derive(Clone, Copy, Debug)]
pub struct Quantiser {
    /// Low corner of the doubled centroids' bounds.
    pub lo: glam::Vec3,
    /// The scale 2^k split as 2^k1 · 2^k2 (each a normal f32).
    pub s1: f32,
    /// Second factor of the scale.
    pub s2: f32,
}

impl Quantiser {
    /// The scale is the largest power of two that keeps the widest axis of `bounds` below
    /// 2^CODE_BITS cells (at least half the cells are used); a bounds box of zero or
    /// subnormal width puts every primitive in cell 0.
    pub fn new(bounds: &Aabb) -> Quantiser {
        let side = bounds.extent().max_element();
        let field = (side.to_bits() >> 23) & 0xff;
        let (s1, s2) = if field == 0 || bounds.is_empty() {
            (0.0, 0.0)
        } else {
            // side < 2^(e + 1), so side · 2^(CODE_BITS - 1 - e) < 2^CODE_BITS.
            let k = CODE_BITS as i32 - 1 - (field as i32 - 127);
            (pow2(k >> 1), pow2(k - (k >> 1)))
        };
        Quantiser {
            lo: bounds.lo,
            s1,
            s2,
        }
    }

    /// The Morton code of a doubled centroid: x in bit 0, y in bit 1, z in bit 2, …
    pub fn code(&self, c2: glam::Vec3) -> u32 {
        let cell = |a: usize| {
            let q = ((c2[a] - self.lo[a]) * self.s1) * self.s2;
            (q as u32).min((1 << CODE_BITS) - 1)
        };
        spread(cell(0)) | spread(cell(1)) << 1 | spread(cell(2)) << 2
    }
}

/// 2^k for k in the normal range.
fn pow2(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    x = (x | x << 2) & 0x0924_9249;
    x
}

/// A box's doubled centroid (`lo + hi`: one rounding, the same in WGSL).
pub fn doubled_centroid(b: &Aabb) -> glam::Vec3 {
    b.lo + b.hi
}

/// Length of the common prefix of the keys at places `i` and `j` of the sorted codes, a key
/// being the code followed by the place (so that equal codes still differ); -1 when `j` is
/// outside.
fn delta(codes: &[u32], i: i64, j: i64) -> i32 {
    if j < 0 || j >= codes.len() as i64 {
        return -1;
    }
    let (a, b) = (codes[i as usize], codes[j as usize]);
    if a != b {
        (a ^ b).leading_zeros() as i32
    } else {
        32 + ((i ^ j) as u32).leading_zeros() as i32
    }
}

/// Inner node `i`'s children (Karras 2012, fig. 4): the direction of its range, the range's
/// far end by doubling then binary search, the split where the prefix grows.
fn node_kids(codes: &[u32], i: i64) -> [u32; 2] {
    let d: i64 = if delta(codes, i, i + 1) > delta(codes, i, i - 1) {
        1
    } else {
        -1
    };
    let dmin = delta(codes, i, i - d);
    let mut lmax: i64 = 2;
    while delta(codes, i, i + lmax * d) > dmin {
        lmax *= 2;
    }
    let mut l = 0;
    let mut t = lmax / 2;
    while t >= 1 {
        if delta(codes, i, i + (l + t) * d) > dmin {
            l += t;
        }
        t /= 2;
    }
    let j = i + l * d;
    let dnode = delta(codes, i, j);
    let mut s = 0;
    let mut div = 2;
    loop {
        let t = (l + div - 1) / div;
        if delta(codes, i, i + (s + t) * d) > dnode {
            s += t;
        }
        if t == 1 {
            break;
        }
        div *= 2;
    }
    let split = i + s * d + d.min(0);
    let kid = |place: i64, end: i64| {
        if place == end {
            LEAF_BIT | place as u32
        } else {
            place as u32
        }
    };
    [kid(split, i.min(j)), kid(split + 1, i.max(j))]
}

/// The radix tree over primitive boxes (at least one), on all threads when asked.
pub fn radix_tree(boxes: &[Aabb], parallel: bool) -> RadixTree {
    let n = boxes.len();
    let c2 = |i: usize| doubled_centroid(&boxes[i]);
    let bounds = (0..n).fold(Aabb::EMPTY, |b, i| b.grow(c2(i)));
    let q = Quantiser::new(&bounds);
    let mut keys: Vec<(u32, u32)> = if parallel {
        (0..n as u32)
            .into_par_iter()
            .map(|i| (q.code(c2(i as usize)), i))
            .collect()
    } else {
        (0..n as u32).map(|i| (q.code(c2(i as usize)), i)).collect()
    };
    // A stable sort from place order: equal codes stay in place order (as on the GPU).
    radsort::sort_by_key(&mut keys, |k| k.0);
    let (codes, sorted): (Vec<u32>, Vec<u32>) = keys.into_iter().unzip();
    let inner = n.saturating_sub(1);
    let kids: Vec<[u32; 2]> = if parallel {
        (0..inner as i64)
            .into_par_iter()
            .map(|i| node_kids(&codes, i))
            .collect()
    } else {
        (0..inner as i64).map(|i| node_kids(&codes, i)).collect()
    };
    let mut node_boxes = vec![Aabb::EMPTY; inner];
    if inner > 0 {
        union_below(0, &kids, &sorted, boxes, &mut node_boxes);
    }
    RadixTree {
        sorted,
        kids,
        boxes: node_boxes,
    }
}

/// The box of inner node `i`, its descendants' boxes written on the way (depth ≤ 62: each
/// level's prefix is longer than its parent's, and keys have 62 bits).
fn union_below(
    i: usize,
    kids: &[[u32; 2]],
    sorted: &[u32],
    prims: &[Aabb],
    out: &mut [Aabb],
) -> Aabb {
    let mut b = Aabb::EMPTY;
    for k in kids[i] {
        b = b.union(if k & LEAF_BIT != 0 {
            prims[sorted[(k & !LEAF_BIT) as usize] as usize]
        } else {
            union_below(k as usize, kids, sorted, prims, out)
        });
    }
    out[i] = b;
    b
}

/// Lancer's tree from a radix tree over `prims` (None when it is deeper than the cap).
pub(crate) fn to_tree(
    tree: RadixTree,
    prims: &Prims,
    opts: &BuildOptions,
) -> Option<(Node, Vec<u32>)> {
    let n = prims.len();
    let RadixTree {
        sorted,
        kids,
        boxes,
    } = tree;
    let node = |k: u32| match k & LEAF_BIT {
        0 => n as u32 + k,
        _ => sorted[(k & !LEAF_BIT) as usize],
    };
    let mut clusters = Clusters {
        bbox: (0..n as u32).map(|i| prims.bbox(i)).collect(),
        kids: vec![[u32::MAX; 2]; n],
    };
    clusters.bbox.extend(boxes);
    clusters
        .kids
        .extend(kids.iter().map(|&[a, b]| [node(a), node(b)]));
    let root = if n == 1 { 0 } else { n as u32 };
    to_node("LBVH", &clusters, root, n, opts)
}

/// The LBVH builder (CPU).
pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> Option<(Node, Vec<u32>)> {
    if prims.len() > MAX_PRIMS {
        log::warn!("LBVH takes at most {MAX_PRIMS} primitives: built with binned SAH");
        return None;
    }
    let boxes: Vec<Aabb> = (0..prims.len() as u32).map(|i| prims.bbox(i)).collect();
    to_tree(radix_tree(&boxes, opts.parallel), prims, opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(lo: [f32; 3]) -> Aabb {
        let lo = glam::Vec3::from(lo);
        Aabb { lo, hi: lo + 1.0 }
    }

    #[test]
    fn the_widest_axis_fills_between_half_and_all_cells() {
        for side in [1.0f32, 3.0, 1023.5, 1e-20, 7e10] {
            let q = Quantiser::new(&Aabb {
                lo: glam::Vec3::ZERO,
                hi: glam::Vec3::new(side, side / 3.0, 0.0),
            });
            let top = ((side * q.s1) * q.s2) as u32;
            assert!((512..1024).contains(&top), "side {side}: top cell {top}");
        }
        let flat = Quantiser::new(&Aabb {
            lo: glam::Vec3::ONE,
            hi: glam::Vec3::ONE,
        });
        assert_eq!(flat.code(glam::Vec3::ONE), 0);
    }

    #[test]
    fn spread_interleaves_every_bit() {
        assert_eq!(spread(0x3ff), 0x0924_9249);
        assert_eq!(spread(1 << 9), 1 << 27);
    }

    /// Every place is a leaf of exactly one node, every inner node but the root a child of
    /// exactly one, and each inner node's box bounds its children's.
    #[test]
    fn the_radix_tree_is_a_tree_with_equal_codes_too() {
        // A grid with repeated boxes: many equal codes.
        let boxes: Vec<Aabb> = (0..300)
            .map(|i| unit([(i % 7) as f32, (i / 7 % 5) as f32, (i % 3) as f32]))
            .collect();
        for parallel in [false, true] {
            let t = radix_tree(&boxes, parallel);
            let n = boxes.len();
            let (mut leaves, mut inner) = (vec![0; n], vec![0; n - 1]);
            for (i, ks) in t.kids.iter().enumerate() {
                for &k in ks {
                    let b = if k & LEAF_BIT != 0 {
                        leaves[(k & !LEAF_BIT) as usize] += 1;
                        boxes[t.sorted[(k & !LEAF_BIT) as usize] as usize]
                    } else {
                        inner[k as usize] += 1;
                        t.boxes[k as usize]
                    };
                    assert_eq!(t.boxes[i].union(b), t.boxes[i]);
                }
            }
            assert!(leaves.iter().all(|&c| c == 1));
            assert_eq!(inner[0], 0);
            assert!(inner[1..].iter().all(|&c| c == 1));
            assert_eq!(t, radix_tree(&boxes, !parallel));
        }
    }

    #[test]
    fn a_tree_that_is_no_radix_tree_is_refused_and_every_walk_of_a_checked_one_ends() {
        let boxes: Vec<Aabb> = (0..9).map(|i| unit([i as f32 * 2.0, 0.0, 0.0])).collect();
        for n in [1, 2, 9] {
            radix_tree(&boxes[..n], false).check(n).unwrap();
        }
        let good = radix_tree(&boxes, false);
        let refused = |f: &dyn Fn(&mut RadixTree), want: &str| {
            let mut t = good.clone();
            f(&mut t);
            let e = t.check(9).unwrap_err();
            assert!(e.contains(want), "{want}: {e}");
        };
        refused(
            &|t| t.sorted[3] = t.sorted[4],
            "places 3 and 4 both hold primitive",
        );
        refused(&|t| t.sorted[0] = 9, "place 0 holds primitive 9 of 9");
        refused(
            &|t| t.kids[2][0] = 40,
            "names inner node 40, but there are 8",
        );
        refused(
            &|t| t.kids[2][0] = LEAF_BIT | 9,
            "names leaf 9, but there are 9",
        );
        refused(&|t| t.kids.truncate(7), "7 inner nodes");
        refused(
            &|t| {
                t.boxes.pop();
            },
            "7 boxes",
        );
        // Node 0 its own child: a walk from the root would never end.
        refused(
            &|t| t.kids[0] = [0, t.kids[0][1]],
            "the root (inner node 0) is a child",
        );
        // Inner node 1 its own child, cut off from the root: every node but the root has
        // one parent, and the walk from the root misses it (a walk into it never ends).
        let cycle = RadixTree {
            sorted: vec![0, 1, 2],
            kids: vec![[LEAF_BIT, LEAF_BIT | 1], [1, LEAF_BIT | 2]],
            boxes: vec![unit([0.0; 3]); 2],
        };
        let e = cycle.check(3).unwrap_err();
        assert!(e.contains("1 of its 2 inner nodes are not reached"), "{e}");
        // The builder from a radix tree refuses it (its walk would not end) and ids beyond
        // the mesh.
        use crate::accel::bvh::build_from_radix_tree;
        use crate::geometry::Triangle;
        let tris = (0..3).map(|i| {
            let p = glam::Vec3::new(i as f32, 0.0, 0.0);
            Triangle::new(p, p + glam::Vec3::X, p + glam::Vec3::Y)
        });
        let mesh = crate::mesh::Mesh::from_triangles(tris.collect());
        let opts = Default::default();
        let e = build_from_radix_tree(&mesh, &[0, 1, 2], cycle, &opts).unwrap_err();
        assert!(e.to_string().contains("not reached from the root"), "{e}");
        let e = build_from_radix_tree(&mesh, &[0, 1, 7], good, &opts).unwrap_err();
        assert!(e.to_string().contains("id 7 of a mesh of 3"), "{e}");
    }
}
