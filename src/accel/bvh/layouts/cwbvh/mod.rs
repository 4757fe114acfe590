//! `cwbvh`: the compressed 8-wide BVH of Ylitie, Karras & Laine 2017 ("Efficient incoherent
//! ray traversal on GPUs through compressed wide BVHs"). An 80-byte node holds a frame
//! (origin, three power-of-two steps) and up to 8 children: each child's box in 8 bits per
//! plane against that frame ([`quantise`]), and a meta byte saying whether it is an
//! internal node (stored contiguously from `child_base`, in slot order) or a leaf of 1–3
//! triangles (a unary count and an offset from `tri_base`). Children sit in slots by ray
//! octant ([`slots`]), so a ray visits them roughly near to far by taking the highest bit
//! of a hit mask; traversal keeps a stack of node groups (a base index and a hit mask), at
//! most one per level.
//!
//! The tree is collapsed from lancer's binary SAH tree by the paper's SAH-cost dynamic
//! programme ([`collapse`]); binary leaves of more than 3 triangles are first split into
//! one-triangle leaves (the DP then regroups them into wide leaves of ≤ 3). Triangles are
//! stored in the layout's own order, each once, `prim` keeping the original index.
//!
//! WGSL: `cwbvh_node.wgsl` (node, child test, group stack) under `cwbvh.wgsl` (one ray an
//! invocation, the twin's walk) or `cwbvh_subgroup.wgsl` (the subgroup's lanes walk the
//! union of their walks: the same closest hits).

mod collapse;
mod quantise;
mod slots;
mod twin;

pub(crate) use twin::Walk as CwbvhWalk;

use crate::accel::gpu_form::{capacity_for, zeroed_on_all_threads_with_room};
use std::borrow::Cow;

use glam::Vec3A;

use crate::accel::bvh::{Bvh, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::mesh::Mesh;
use crate::util::zeroed_on_all_threads;

use super::validate_boxes::{check_boxes, node_zero, At, BoxTree, Child, Slot};
use super::{GpuArrays, LayoutKind, LeafTri};

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Plan};
use collapse::{Binary, LeafOrder};
use quantise::{dequantise, step, Frame};

/// Children per node.
pub(crate) const WIDTH: usize = 8;
/// Most triangles in one leaf child (three unary count bits in the meta byte).
pub(crate) const MAX_LEAF_TRIS: u32 = 3;
/// Hit-mask bits below this are triangles (at most 24 per node, offsets from `tri_base`),
/// the 8 above are internal children in traversal order (WGSL `CWBVH_TRI_BITS`).
pub(crate) const TRI_BITS: u32 = 24;
/// A meta byte: the unary triangle count (1 for an internal child) above this shift, the
/// hit-mask bit index below (WGSL `CWBVH_COUNT_SHIFT`).
pub(crate) const COUNT_SHIFT: u32 = 5;
/// Node groups the traversal stack holds: one per level, so every node must be at depth
/// ≤ this (checked by `validate`; the kernel's stack is sized to the tree's own depth,
/// `spill_size`). The wide tree is never deeper than the binary one, whose depth the
/// builders cap at MAX_DEPTH.
pub(crate) const STACK_SIZE: usize = MAX_DEPTH;
/// Stack groups the kernel keeps in variables (WGSL `CWBVH_STACK_REGISTERS`, its
/// `group_top0`–`group_top3`); deeper ones go to its spill array (`Cwbvh::spill_size`).
const STACK_REGISTERS: usize = 4;
/// Bytes of one node record.
pub(crate) const NODE_BYTES: usize = std::mem::size_of::<CwNode>();

/// One node, 80 bytes (WGSL `CwbvhNode`; `e` and `imask` are its `e_imask` word, the byte
/// arrays its `child_meta`, `q_lo`, `q_hi` words, little-endian).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct CwNode {
    /// Frame origin: the low corner of the node's box.
    pub p: [f32; 3],
    /// Biased f32 exponents of the per-axis steps (step = bits `e << 23`).
    pub e: [u8; 3],
    /// Bit s set: slot s is an internal child.
    pub imask: u8,
    /// Index of the first internal child (the others follow, in slot order).
    pub child_base: u32,
    /// Index of the first triangle of the leaf children.
    pub tri_base: u32,
    /// Per slot: 0 empty; internal `1 << 5 | (24 + slot)`; leaf `(2^count − 1) << 5 | offset`.
    pub child_meta: [u8; WIDTH],
    /// Per axis, per slot: the child's low planes as bytes.
    pub q_lo: [[u8; WIDTH]; 3],
    /// Per axis, per slot: the child's high planes as bytes.
    pub q_hi: [[u8; WIDTH]; 3],
}

impl CwNode {
    /// The meta byte of an internal child in `slot`.
    fn inner_meta(slot: usize) -> u8 {
        (1 << COUNT_SHIFT | (TRI_BITS + slot as u32)) as u8
    }

    /// The dequantised box of slot `s`, as the traversal computes it.
    #[inline(always)]
    fn child_box(&self, s: usize) -> (Vec3A, Vec3A) {
        let p = Vec3A::from_array(self.p);
        let step = step(self.e);
        let q = |b: &[[u8; WIDTH]; 3]| Vec3A::new(b[0][s] as f32, b[1][s] as f32, b[2][s] as f32);
        (
            dequantise(p, step, q(&self.q_lo)),
            dequantise(p, step, q(&self.q_hi)),
        )
    }
}

/// What a node's slot holds (for inspection: [`Cwbvh::children`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CwChild {
    /// An internal node, by index.
    Node(u32),
    /// A leaf: triangles `first..first + count` of the layout's triangle array.
    Tris {
        /// First triangle.
        first: u32,
        /// Number of triangles (1..=3).
        count: u32,
    },
}

/// A BVH flattened in the `cwbvh` layout; its [`Accel`](crate::accel::Accel) is the CPU
/// twin of `cwbvh.wgsl`.
#[derive(Clone, Debug, PartialEq)]
pub struct Cwbvh {
    nodes: Vec<CwNode>,
    tris: Vec<LeafTri>,
    bounds: Aabb,
    /// Depth of the deepest node (the root's is 0): the most groups the traversal stack
    /// ever holds, which sizes the kernel's spill array (`wgsl`).
    deepest: usize,
}

impl Cwbvh {
    /// Collapses a built tree into 8-wide compressed nodes.
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> Cwbvh {
        Cwbvh::collapse(Cow::Borrowed(bvh), &bvh.order, mesh)
    }

    /// [`Cwbvh::flatten`], consuming the tree: its nodes are freed as soon as the collapse
    /// holds the tree's shape, before the wide nodes are written (a lower peak of memory).
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten_owned(mut bvh: Bvh, mesh: &Mesh) -> Cwbvh {
        let order = std::mem::take(&mut bvh.order);
        Cwbvh::collapse(Cow::Owned(bvh), &order, mesh)
    }

    /// Collapses `bvh`'s tree (its triangles in `order`), dropping it once it is read.
    fn collapse(bvh: Cow<'_, Bvh>, order: &[u32], mesh: &Mesh) -> Cwbvh {
        let leaves = LeafOrder {
            order,
            triangles: &mesh.triangles,
        };
        if order.is_empty() {
            // One node without children: every ray loads it and ends.
            let empty = CwNode {
                e: [127; 3],
                ..bytemuck::Zeroable::zeroed()
            };
            return Cwbvh {
                nodes: vec![empty],
                tris: Vec::new(),
                bounds: Aabb::EMPTY,
                deepest: 0,
            };
        }
        let (tree, plan) = Binary::new(&bvh.root, &leaves);
        drop(bvh);
        let w = Writer {
            tree: &tree,
            plan: &plan,
        };
        let root = tree.root();
        let mut nodes = zeroed_on_all_threads_with_room(plan.nodes(&tree, root) as usize);
        // The writer places leaf-order positions; the triangles are then read for them on all
        // threads (each written once, not zeroed first).
        let mut places: Vec<u32> = zeroed_on_all_threads(order.len());
        let (first, rest) = nodes.split_at_mut(1);
        let deepest = w.write(root, 0, &mut first[0], (1, rest), (0, &mut places));
        // The collapse's arrays are freed before the triangle array is made: the allocator
        // may give their pages to it (a lower peak, fewer pages faulted in).
        let bounds = tree.bbox(root);
        drop((tree, plan));
        let tris = {
            use rayon::prelude::*;
            let tri = |&p: &u32| LeafTri::new(leaves.triangle(p).v, leaves.order[p as usize]);
            let mut tris = Vec::with_capacity(capacity_for::<LeafTri>(places.len()));
            tris.par_extend(places.par_iter().map(tri));
            tris
        };
        Cwbvh {
            nodes,
            tris,
            bounds,
            deepest,
        }
    }

    /// A layout from raw arrays (as [`arrays`](super::GpuForm::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<Cwbvh, String> {
        let (nodes, tris) = super::records::<CwNode>(arrays)?;
        let bounds = (tris.iter()).fold(Aabb::EMPTY, |b, t| b.union(t.triangle().bbox()));
        let mut layout = Cwbvh {
            nodes,
            tris,
            bounds,
            deepest: 0,
        };
        layout.deepest = layout.checked_depth()?;
        Ok(layout)
    }

    /// Number of node records.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The layout's triangles, in its own order.
    pub fn leaf_tris(&self) -> &[LeafTri] {
        &self.tris
    }

    /// Node `i`'s occupied slots: (slot, its box as the traversal dequantises it, what it
    /// holds). Panics if `i` is not below [`node_count`](Self::node_count).
    pub fn children(&self, i: usize) -> Vec<(usize, Aabb, CwChild)> {
        self.occupied(i).collect()
    }

    /// [`children`](Self::children) as an iterator.
    fn occupied(&self, i: usize) -> impl Iterator<Item = (usize, Aabb, CwChild)> + '_ {
        let n = &self.nodes[i];
        let mut next_inner = n.child_base;
        (0..WIDTH).filter_map(move |s| {
            let m = n.child_meta[s] as u32;
            let child = if n.imask >> s & 1 == 1 {
                next_inner += 1;
                CwChild::Node(next_inner - 1)
            } else if m != 0 {
                CwChild::Tris {
                    first: n.tri_base + (m & ((1 << COUNT_SHIFT) - 1)),
                    count: (m >> COUNT_SHIFT).count_ones(),
                }
            } else {
                return None;
            };
            let (lo, hi) = n.child_box(s);
            let bbox = Aabb {
                lo: lo.into(),
                hi: hi.into(),
            };
            Some((s, bbox, child))
        })
    }
}

impl BoxTree for Cwbvh {
    /// Node 0, whose children the traversal tests first.
    fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
        node_zero()
    }

    /// The occupied slots with their dequantised boxes.
    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
        self.occupied(node as usize).map(move |(s, bbox, c)| Slot {
            bbox: Some(bbox),
            child: match c {
                CwChild::Node(i) => Child::Node(i),
                CwChild::Tris { first, count } => Child::Tris { first, count },
            },
            at: At::Slot {
                node,
                slot: s as u32,
            },
        })
    }

    fn tris(&self) -> &[LeafTri] {
        &self.tris
    }
}

/// Writes wide nodes depth first; each node's internal children are contiguous, followed
/// by the first child's descendants, then the second's, and so on; each node's leaf
/// triangles' places come before its children's. The big subtrees are written on all
/// threads, into the parts of the arrays their sizes (the programme's counts) give them.
struct Writer<'a> {
    tree: &'a Binary<'a>,
    plan: &'a Plan<WIDTH>,
}

/// A part of an output array, and the index of its first element in the whole.
type Part<'p, T> = (u32, &'p mut [T]);

impl Writer<'_> {
    /// Writes the wide node made from binary node `n` into `slot` at `depth`, its
    /// descendants into `nodes`, and into `places` the leaf-order positions of its subtree's
    /// triangles where the layout's triangles go; returns the depth of the deepest node
    /// written.
    fn write(
        &self,
        n: u32,
        depth: usize,
        slot: &mut CwNode,
        nodes: Part<'_, CwNode>,
        places: Part<'_, u32>,
    ) -> usize {
        let children = self.plan.children(self.tree, n);
        // Held in place, not allocated: a wide node is written for every few triangles.
        let mut boxes = [Aabb::EMPTY; WIDTH];
        for (b, &(c, _)) in boxes.iter_mut().zip(children.iter()) {
            *b = self.tree.bbox(c);
        }
        let boxes = &boxes[..children.len()];
        let bbox = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
        let frame = Frame::new(&bbox);
        let mut node = CwNode {
            p: frame.p.into(),
            e: frame.e,
            imask: 0,
            child_base: nodes.0,
            tri_base: places.0,
            child_meta: [0; WIDTH],
            q_lo: [[0; WIDTH]; 3],
            q_hi: [[0; WIDTH]; 3],
        };
        let mut inner = [0u32; WIDTH];
        let mut inner_len = 0;
        let mut offset = 0u32;
        for (s, c) in slots::assign(&bbox, boxes).into_iter().enumerate() {
            let Some(c) = c else { continue };
            let (b, leaf) = children[c];
            let (lo, hi) = frame.quantise(&boxes[c]);
            for axis in 0..3 {
                node.q_lo[axis][s] = lo[axis];
                node.q_hi[axis][s] = hi[axis];
            }
            if leaf {
                let count = self.tree.positions(b, &mut places.1[offset as usize..]);
                node.child_meta[s] = (((1 << count) - 1) << COUNT_SHIFT | offset) as u8;
                offset += count;
            } else {
                node.imask |= 1 << s;
                node.child_meta[s] = CwNode::inner_meta(s);
                inner[inner_len] = b;
                inner_len += 1;
            }
        }
        *slot = node;
        // The parts of the children: their records, then each one's descendants and
        // triangles in turn.
        let (records, mut rest) = nodes.1.split_at_mut(inner_len);
        let mut rest_base = nodes.0 + inner_len as u32;
        let (_, mut places_rest) = places.1.split_at_mut(offset as usize);
        let mut places_base = places.0 + offset;
        let mut jobs = Vec::with_capacity(inner_len);
        for (&c, record) in inner[..inner_len].iter().zip(records) {
            let below = self.plan.nodes(self.tree, c) as usize - 1;
            let (mine, more) = std::mem::take(&mut rest).split_at_mut(below);
            let (my_places, more_places) =
                std::mem::take(&mut places_rest).split_at_mut(self.tree.tris(c) as usize);
            jobs.push((c, record, (rest_base, mine), (places_base, my_places)));
            rest_base += below as u32;
            places_base += self.tree.tris(c);
            (rest, places_rest) = (more, more_places);
        }
        let go =
            |(c, record, nodes, places): (u32, &mut CwNode, Part<'_, CwNode>, Part<'_, u32>)| {
                self.write(c, depth + 1, record, nodes, places)
            };
        // Big subtrees (`BinaryTree::big`) are written on several threads.
        let deepest = if self.tree.big(n) {
            use rayon::prelude::*;
            jobs.into_par_iter().map(go).max()
        } else {
            jobs.into_iter().map(go).max()
        };
        deepest.unwrap_or(depth).max(depth)
    }
}

impl super::GpuForm for Cwbvh {
    fn name(&self) -> &'static str {
        LayoutKind::Cwbvh.name()
    }

    fn node_bytes(&self) -> usize {
        NODE_BYTES
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    /// `CWBVH_SPILL_SIZE` is sized to this tree's deepest node (see `spill_size`).
    fn stack_depth(&self) -> usize {
        self.deepest
    }

    fn wgsl(&self) -> String {
        format!("{}{}", self.node_wgsl(), include_str!("cwbvh.wgsl"))
    }

    fn subgroup_wgsl(&self) -> Option<String> {
        Some(format!(
            "{}{}",
            self.node_wgsl(),
            include_str!("cwbvh_subgroup.wgsl")
        ))
    }

    /// Every node reached once from the root, children after their parent, depth ≤ the
    /// group stack; meta bytes well formed (internal slots match `imask`, leaves of 1–3
    /// triangles within the node's 24 triangle bits, within the triangle array); steps
    /// normal; no child box inverted. Then every slot's dequantised box holds the triangles
    /// below it and the leaves cover the triangle array once (`check_boxes`).
    fn validate(&self) -> Result<(), String> {
        self.checked_depth().map(|_| ())
    }
}

impl Cwbvh {
    /// The WGSL both traversals share (`cwbvh_node.wgsl`: node, child test, group stack),
    /// with its constants from this module and this tree's spill array size.
    fn node_wgsl(&self) -> String {
        format!(
            "const CWBVH_TRI_BITS: u32 = {TRI_BITS}u;\n\
             const CWBVH_COUNT_SHIFT: u32 = {COUNT_SHIFT}u;\n\
             const CWBVH_WIDTH: u32 = {WIDTH}u;\n\
             const CWBVH_NODE_WORDS: u32 = {}u;\n\
             const CWBVH_STACK_REGISTERS: u32 = {STACK_REGISTERS}u;\n\
             const CWBVH_SPILL_SIZE: u32 = {}u;\n{}",
            NODE_BYTES / 16,
            self.spill_size(),
            include_str!("cwbvh_node.wgsl")
        )
    }

    /// The kernel's spill array (WGSL `CWBVH_SPILL_SIZE`): the stack groups past the
    /// `STACK_REGISTERS` it keeps in variables. A stack of `deepest` groups spills at most
    /// `deepest` − `STACK_REGISTERS` (at least one entry: WGSL has no empty arrays). Sized to this tree rather than to
    /// `STACK_SIZE`, because every invocation zero-fills its private arrays (WGSL's rule):
    /// on this project's machine (Mesa 25 lavapipe, bunny primary rays) filling the
    /// 64-entry array took ~7% of the kernel's profile, and the sized array (two entries on
    /// the bunny) gave ~1.06x primary and ~1.04x shadow rays/s (six paired runs).
    fn spill_size(&self) -> usize {
        self.deepest.max(STACK_REGISTERS + 1) - STACK_REGISTERS
    }

    /// [`validate`](super::GpuForm::validate)'s checks, the structural ones first; returns
    /// the depth of the deepest node. Each node's own fields are checked on all threads (the
    /// first fault by index is named); then, in index order (children come after their
    /// parents, checked first), that every node is reached once from the root and no deeper
    /// than the stack holds.
    fn checked_depth(&self) -> Result<usize, String> {
        use rayon::prelude::*;
        if self.nodes.is_empty() {
            return Err("BVH has no nodes".into());
        }
        let bad = (0..self.nodes.len())
            .into_par_iter()
            .find_first(|&i| self.check_node(i).is_err());
        if let Some(i) = bad {
            self.check_node(i)?;
        }
        // A node's depth (at most STACK_SIZE, below u8::MAX), or none yet.
        const UNREACHED: u8 = u8::MAX;
        const _: () = assert!(STACK_SIZE < UNREACHED as usize);
        let mut depth = vec![UNREACHED; self.nodes.len()];
        depth[0] = 0;
        let mut deepest = 0;
        for (i, n) in self.nodes.iter().enumerate() {
            let d = depth[i];
            if d == UNREACHED {
                return Err(format!("node {i} is unreachable"));
            }
            let d = d as usize;
            deepest = deepest.max(d);
            let base = n.child_base as usize;
            let inner = n.imask.count_ones() as usize;
            for (c, dc) in depth.iter_mut().enumerate().skip(base).take(inner) {
                if *dc != UNREACHED {
                    return Err(format!("node {c} is reached twice"));
                }
                if d + 1 > STACK_SIZE {
                    return Err(format!(
                        "node {c} is at depth {} > the {STACK_SIZE}-group stack",
                        d + 1
                    ));
                }
                *dc = (d + 1) as u8;
            }
        }
        check_boxes(self)?;
        Ok(deepest)
    }

    /// [`checked_depth`](Self::checked_depth)'s checks of node `i`'s own fields: step
    /// exponents, meta bytes (internal slots match `imask`, leaves of 1–3 triangles in
    /// range), boxes not inverted, children after it and in range.
    fn check_node(&self, i: usize) -> Result<(), String> {
        let n = &self.nodes[i];
        if n.e.iter().any(|&e| e == 0 || e == 255) {
            return Err(format!("node {i} has a step exponent outside 1..=254"));
        }
        for s in 0..WIDTH {
            let m = n.child_meta[s] as u32;
            if n.imask >> s & 1 == 1 {
                if m != CwNode::inner_meta(s) as u32 {
                    return Err(format!("node {i} slot {s}: internal with meta {m:#04x}"));
                }
            } else if m != 0 {
                let unary = m >> COUNT_SHIFT;
                let count = unary.count_ones();
                let first = m & ((1 << COUNT_SHIFT) - 1);
                if unary != (1 << count) - 1 || first + count > TRI_BITS {
                    return Err(format!("node {i} slot {s}: bad leaf meta {m:#04x}"));
                }
                let start = n.tri_base as usize + first as usize;
                let end = start + count as usize;
                if end > self.tris.len() {
                    return Err(format!(
                        "node {i} slot {s} refers to triangles {start}..{end} of {}",
                        self.tris.len()
                    ));
                }
            }
            if m != 0 && (0..3).any(|a| n.q_lo[a][s] > n.q_hi[a][s]) {
                return Err(format!("node {i} slot {s}: inverted box"));
            }
        }
        let inner = n.imask.count_ones() as usize;
        let base = n.child_base as usize;
        if inner > 0 && (base <= i || base + inner > self.nodes.len()) {
            return Err(format!(
                "node {i} has children {base}..{} outside {}..{}",
                base + inner,
                i + 1,
                self.nodes.len()
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::accel::GpuForm;
    use crate::gpu::shaders;

    #[test]
    fn the_wgsl_node_matches_the_rust_node() {
        // A 10×10×5 lattice of small tilted triangles.
        let tris = (0..500)
            .map(|i| {
                let c = glam::Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32);
                crate::geometry::Triangle::new(
                    c,
                    c + glam::Vec3::new(0.7, 0.0, 0.2),
                    c + glam::Vec3::new(0.0, 0.6, 0.3),
                )
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let layout = Cwbvh::flatten(&crate::accel::bvh::build(&mesh, &Default::default()), &mesh);
        let src = shaders::trace_source(&layout, &crate::gpu::BufferParts::WHOLE);
        let fields = [
            ("p", offset_of!(CwNode, p)),
            ("e_imask", offset_of!(CwNode, e)),
            ("child_base", offset_of!(CwNode, child_base)),
            ("tri_base", offset_of!(CwNode, tri_base)),
            ("child_meta", offset_of!(CwNode, child_meta)),
            ("q_lo", offset_of!(CwNode, q_lo)),
            ("q_hi", offset_of!(CwNode, q_hi)),
        ];
        shaders::check_struct(&src, "CwbvhNode", size_of::<CwNode>(), &fields).unwrap();
        // e and imask share the word e_imask: e in bytes 0..3, imask in byte 3.
        assert_eq!(offset_of!(CwNode, imask), offset_of!(CwNode, e) + 3);
        assert_eq!(NODE_BYTES, 80);
        assert!(layout.node_count() > 10);
        assert_eq!(layout.triangles(), 500);
        layout.validate().unwrap();
    }
}
