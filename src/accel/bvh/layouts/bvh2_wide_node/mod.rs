//! `bvh2-wide-node` (Aila & Laine 2009, "Understanding the efficiency of ray traversal on
//! GPUs"): the binary tree's inner nodes as 64-byte records, each holding both children's
//! boxes and references, so one node visit is one 64-byte load and tests both child boxes.
//! Traversal visits the hit children nearest first (by entry distance; equal entries → the
//! first child) and pushes only the far one. Leaves have no records of their own: a child
//! reference is either an inner record's index or a range of the shared [`LeafTri`] array.
//!
//! Record 0 is a header holding the root's box and reference (its second slot is zero), so
//! the root box is tested once, before the loop. Inner records follow in depth-first
//! pre-order: a record's first inner child, if any, comes right after it.
//!
//! Size: a tree with L leaves has L − 1 inner records plus the header, i.e. L × 64 bytes of
//! nodes (`dfs-sign` stores 2L − 1 nodes of 32 bytes: 32 bytes less), plus 48 bytes per
//! triangle: 70.7 bytes per triangle on the bunny (default build, ~2.8 triangles a leaf),
//! as for `dfs-sign`.
//!
//! Stack bound: only a record whose both children are hit pushes, one entry (the far
//! child), and the entries on the stack are children of distinct ancestors of the current
//! reference, all shallower than it. A record at depth d (the root's record has d = 0)
//! thus writes stack slot ≤ d. The builders keep every leaf at depth ≤ `MAX_DEPTH`, so
//! every record (an inner node) is at d ≤ `MAX_DEPTH` − 1, and the kernel's `STACK_SIZE`
//! = `MAX_DEPTH` entries suffice; [`validate`](super::GpuForm::validate) checks this depth
//! on the flattened array. An entry is a whole reference (two `u32`: a leaf's range needs
//! both), so the stack is 512 bytes, twice `dfs-sign`'s.

mod twin;

use crate::accel::bvh::{Bvh, Node, MAX_DEPTH};
use crate::accel::gpu_form::zeroed_with_room;
use crate::geometry::Aabb;
use crate::mesh::Mesh;

use super::validate_boxes::{check_boxes, At, BoxTree, Child, Slot};
use super::{GpuArrays, LayoutKind, LeafTri};

/// A child reference whose `b` has this bit set is a leaf: `a` = first triangle,
/// `b >> COUNT_SHIFT` = count. Otherwise `a` is the child's record index and `b` = 0
/// (generated into the WGSL as `BVH2_WIDE_LEAF_TAG`).
pub(crate) const LEAF_TAG: u32 = 1;

/// Where a leaf reference's triangle count starts in `b` (WGSL `BVH2_WIDE_COUNT_SHIFT`).
pub(crate) const COUNT_SHIFT: u32 = 1;

/// Bytes of one node record (WGSL `Bvh2WideNodeRecord`, loaded as
/// `BVH2_WIDE_RECORD_WORDS` 16-byte words).
pub(crate) const NODE_BYTES: usize = std::mem::size_of::<WideNode>();

/// One record, 64 bytes: child 0's box and reference (`a0`, `b0`), then child 1's. Child 0
/// is the low side of the split axis. (WGSL `Bvh2WideNodeRecord` in bvh2_wide_node.wgsl.)
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct WideNode {
    pub lo0: [f32; 3],
    pub a0: u32,
    pub hi0: [f32; 3],
    pub b0: u32,
    pub lo1: [f32; 3],
    pub a1: u32,
    pub hi1: [f32; 3],
    pub b1: u32,
}

/// A child reference: `(a, b)` of one slot of a [`WideNode`].
pub(crate) type ChildRef = (u32, u32);

/// Whether a child reference is a leaf.
#[inline(always)]
pub(crate) fn is_leaf(c: ChildRef) -> bool {
    c.1 & LEAF_TAG == LEAF_TAG
}

impl WideNode {
    pub fn child0(&self) -> ChildRef {
        (self.a0, self.b0)
    }
    pub fn child1(&self) -> ChildRef {
        (self.a1, self.b1)
    }
    pub fn box0(&self) -> Aabb {
        Aabb {
            lo: self.lo0.into(),
            hi: self.hi0.into(),
        }
    }
    pub fn box1(&self) -> Aabb {
        Aabb {
            lo: self.lo1.into(),
            hi: self.hi1.into(),
        }
    }
}

/// Slot `slot` of record `record`, holding `bbox` and the reference `c` (for [`BoxTree`]).
fn slot(record: usize, slot: u32, bbox: Aabb, c: ChildRef) -> Slot {
    Slot {
        bbox: Some(bbox),
        child: match is_leaf(c) {
            true => Child::Tris {
                first: c.0,
                count: c.1 >> COUNT_SHIFT,
            },
            false => Child::Node(c.0),
        },
        at: At::Slot {
            node: record as u32,
            slot,
        },
    }
}

/// A BVH flattened in the `bvh2-wide-node` layout; its [`Accel`](crate::accel::Accel) is
/// the CPU twin of `bvh2_wide_node.wgsl`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh2WideNode {
    /// The header (record 0), then the inner records in pre-order.
    nodes: Vec<WideNode>,
    tris: Vec<LeafTri>,
}

impl Bvh2WideNode {
    /// Flattens a built tree (in parallel for big trees).
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> Bvh2WideNode {
        // The triangles and the nodes are independent: gathered and written side by side.
        let (tris, nodes) = rayon::join(|| LeafTri::gather(bvh, mesh), || records(&bvh.root));
        Bvh2WideNode { nodes, tris }
    }

    /// A layout from raw arrays (as [`arrays`](super::GpuForm::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<Bvh2WideNode, String> {
        let (nodes, tris) = super::records(arrays)?;
        let layout = Bvh2WideNode { nodes, tris };
        super::GpuForm::validate(&layout)?;
        Ok(layout)
    }
}

/// The records of the tree under `root`: the header (record 0: the root's box and
/// reference), then the inner records in pre-order.
fn records(root: &Node) -> Vec<WideNode> {
    let mut nodes: Vec<WideNode> = zeroed_with_room(1 + inner_records(root) as usize);
    if let Some((head, rest)) = nodes.split_first_mut() {
        let (a0, b0) = child_ref(root, 1);
        let b = root.bbox();
        *head = WideNode {
            lo0: b.lo.into(),
            a0,
            hi0: b.hi.into(),
            b0,
            ..bytemuck::Zeroable::zeroed()
        };
        write(root, rest, 1);
    }
    nodes
}

/// Inner records of `node`'s subtree (a full binary tree: inner nodes = (nodes − 1) / 2).
fn inner_records(node: &Node) -> u32 {
    (node.nodes() - 1) / 2
}

/// How a parent refers to `node`, whose record (if inner) is `index`.
fn child_ref(node: &Node, index: u32) -> ChildRef {
    match node {
        Node::Leaf { start, count, .. } => (*start, count << COUNT_SHIFT | LEAF_TAG),
        Node::Inner { .. } => (index, 0),
    }
}

/// Subtrees with at least this many records are written, and checked, in parallel.
const PARALLEL_RECORDS: usize = 1 << 11;

/// Writes the records of `node`'s subtree in pre-order into `out` (exactly its inner
/// records), whose first element is record `index` of the whole array.
fn write(node: &Node, out: &mut [WideNode], index: u32) {
    let Node::Inner { children, .. } = node else {
        return;
    };
    let [l, r] = &**children;
    let left = inner_records(l);
    let (li, ri) = (index + 1, index + 1 + left);
    let ((a0, b0), (a1, b1)) = (child_ref(l, li), child_ref(r, ri));
    // An inner node has its own record, so `out` is never empty.
    let Some((head, rest)) = out.split_first_mut() else {
        return;
    };
    let (bl, br) = (l.bbox(), r.bbox());
    *head = WideNode {
        lo0: bl.lo.into(),
        a0,
        hi0: bl.hi.into(),
        b0,
        lo1: br.lo.into(),
        a1,
        hi1: br.hi.into(),
        b1,
    };
    let big = rest.len() >= PARALLEL_RECORDS;
    let (lo, hi) = rest.split_at_mut(left as usize);
    if big {
        rayon::join(|| write(l, lo, li), || write(r, hi, ri));
    } else {
        write(l, lo, li);
        write(r, hi, ri);
    }
}

impl super::GpuForm for Bvh2WideNode {
    fn name(&self) -> &'static str {
        LayoutKind::Bvh2WideNode.name()
    }

    fn node_bytes(&self) -> usize {
        NODE_BYTES
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        format!(
            "const BVH2_WIDE_LEAF_TAG: u32 = {LEAF_TAG}u;\n\
             const BVH2_WIDE_COUNT_SHIFT: u32 = {COUNT_SHIFT}u;\n\
             const BVH2_WIDE_RECORD_WORDS: u32 = {}u;\n{}",
            NODE_BYTES / 16,
            include_str!("bvh2_wide_node.wgsl")
        )
    }

    /// A header; inner references strictly forward and within their parent's pre-order
    /// range (so the records form one tree, each reached once: no cycle can hang the
    /// kernel); leaf ranges within the triangles; every record at depth < `MAX_DEPTH` (the
    /// stack bound, see the module doc); every record reachable. Then every slot's box holds
    /// the triangles below it and the leaves cover the triangle array once (`check_boxes`).
    fn validate(&self) -> Result<(), String> {
        self.check_structure()?;
        check_boxes(self)
    }
}

impl BoxTree for Bvh2WideNode {
    /// The header's first slot.
    fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
        let head = &self.nodes[0];
        std::iter::once(slot(0, 0, head.box0(), head.child0()))
    }

    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
        let (i, n) = (node as usize, &self.nodes[node as usize]);
        [
            slot(i, 0, n.box0(), n.child0()),
            slot(i, 1, n.box1(), n.child1()),
        ]
        .into_iter()
    }

    fn tris(&self) -> &[LeafTri] {
        &self.tris
    }
}

impl Bvh2WideNode {
    /// [`validate`](super::GpuForm::validate)'s structural checks.
    fn check_structure(&self) -> Result<(), String> {
        let Some(head) = self.nodes.first() else {
            return Err("no header record".into());
        };
        let len = self.nodes.len();
        let seen = 1 + self.check_subtree((head.child0(), 0, len, 0))?;
        if seen != len {
            return Err(format!("{} of {len} records are unreachable", len - seen));
        }
        Ok(())
    }

    /// The structural checks below one reference: (the reference, its depth (the root's is
    /// 0), the end of its pre-order range, the record holding it). Returns the inner
    /// records reached. Depth first in memory order; a big subtree's two halves on two
    /// threads, the first's fault named before the second's (the order of the walk on one
    /// thread).
    fn check_subtree(&self, top: (ChildRef, usize, usize, usize)) -> Result<usize, String> {
        let mut stack = vec![top];
        let mut seen = 0usize;
        while let Some((c, depth, end, parent)) = stack.pop() {
            if is_leaf(c) {
                let (first, count) = (c.0 as usize, (c.1 >> COUNT_SHIFT) as usize);
                if first + count > self.tris.len() {
                    return Err(format!(
                        "record {parent} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
                continue;
            }
            let i = c.0 as usize;
            if i <= parent || i >= end {
                return Err(format!(
                    "record {parent} refers to record {i} outside {}..{end}",
                    parent + 1
                ));
            }
            if depth >= MAX_DEPTH {
                return Err(format!(
                    "record {i} is at depth {depth}: its children would be deeper than the \
                     {MAX_DEPTH}-entry stack allows"
                ));
            }
            seen += 1;
            let n = &self.nodes[i];
            let (c0, c1) = (n.child0(), n.child1());
            // The first inner child's range ends where the second's begins.
            let mid = if is_leaf(c1) { end } else { c1.0 as usize };
            let (first, second) = ((c0, depth + 1, mid.min(end), i), (c1, depth + 1, end, i));
            if end - i >= PARALLEL_RECORDS {
                let (a, b) =
                    rayon::join(|| self.check_subtree(first), || self.check_subtree(second));
                seen += a? + b?;
                continue;
            }
            // The first child last, so that the walk reads the records in memory order.
            stack.push(second);
            stack.push(first);
        }
        Ok(seen)
    }
}

#[cfg(test)]
mod tests {
    use std::mem::offset_of;

    use super::*;
    use crate::accel::GpuForm;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;

    fn soup(n: usize) -> Mesh {
        // A deterministic scatter of small triangles: enough for a tree several levels deep.
        let tris = (0..n)
            .map(|i| {
                let f = i as f32;
                let c = glam::Vec3::new((f * 0.37).sin(), (f * 0.91).cos(), (f * 0.53).sin());
                Triangle::new(c, c + glam::Vec3::X * 0.05, c + glam::Vec3::Y * 0.05)
            })
            .collect();
        Mesh::from_triangles(tris)
    }

    #[test]
    fn the_wgsl_record_matches_the_rust_record() {
        let mesh = soup(1);
        let layout =
            Bvh2WideNode::flatten(&crate::accel::bvh::build(&mesh, &Default::default()), &mesh);
        let src = shaders::trace_source(&layout, &crate::gpu::BufferParts::WHOLE);
        let fields = [
            ("lo0", offset_of!(WideNode, lo0)),
            ("a0", offset_of!(WideNode, a0)),
            ("hi0", offset_of!(WideNode, hi0)),
            ("b0", offset_of!(WideNode, b0)),
            ("lo1", offset_of!(WideNode, lo1)),
            ("a1", offset_of!(WideNode, a1)),
            ("hi1", offset_of!(WideNode, hi1)),
            ("b1", offset_of!(WideNode, b1)),
        ];
        shaders::check_struct(&src, "Bvh2WideNodeRecord", NODE_BYTES, &fields).unwrap();
        assert_eq!(NODE_BYTES, 64);
        assert!(layout.validate().is_ok());
    }

    #[test]
    fn a_real_tree_flattens_into_a_valid_array_and_corruptions_are_refused() {
        let mesh = soup(3000);
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let layout = Bvh2WideNode::flatten(&bvh, &mesh);
        layout.validate().unwrap();
        // One record per inner node, plus the header.
        assert_eq!(layout.nodes.len() as u32, 1 + (bvh.root.nodes() - 1) / 2);
        assert!(layout.nodes.len() > 100);
        assert_eq!(layout.tris.len(), 3000);
        // A record with an inner child (the root's first record is 1).
        let n = layout.nodes.len();
        let with_inner = (1..n)
            .find(|&i| !is_leaf(layout.nodes[i].child0()))
            .unwrap();
        let with_leaf = (1..n).find(|&i| is_leaf(layout.nodes[i].child1())).unwrap();
        let corrupt = |what: &str, want: &str, f: &dyn Fn(&mut Bvh2WideNode)| {
            let mut bad = layout.clone();
            f(&mut bad);
            let e = bad.validate().expect_err(what);
            assert!(e.contains(want), "{what}: {e}");
        };
        corrupt("no header", "header", &|l| l.nodes.clear());
        corrupt("root out of range", "outside", &|l| {
            l.nodes[0].a0 = n as u32
        });
        corrupt("a cycle", "outside", &|l| {
            l.nodes[with_inner].a0 = with_inner as u32;
        });
        corrupt("a back edge", "outside", &|l| l.nodes[with_inner].a0 = 1);
        corrupt("child past its range", "outside", &|l| {
            l.nodes[with_inner].a0 = n as u32 - 1;
        });
        corrupt("leaf past the triangles", "triangles", &|l| {
            l.nodes[with_leaf].a1 = 2999;
            l.nodes[with_leaf].b1 = 2 << COUNT_SHIFT | LEAF_TAG;
        });
        corrupt("an unreachable record", "unreachable", &|l| {
            l.nodes.push(l.nodes[1]);
        });
        corrupt("an inner child turned leaf", "unreachable", &|l| {
            l.nodes[with_inner].b0 = LEAF_TAG;
        });
    }
}
