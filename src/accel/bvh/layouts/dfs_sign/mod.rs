//! `dfs-sign`: 32-byte nodes in depth-first pre-order. An inner node's first child is at
//! i + 1 and holds the low side of the split axis; the second child's index and the split
//! axis are stored, and traversal visits first the child on the side the ray's direction
//! comes from on that axis. A leaf holds (first, count) into the triangle array.

mod node_ray;
mod twin;

use crate::accel::bvh::{Bvh, Node, MAX_DEPTH};
use crate::accel::gpu_form::zeroed_with_room;
use crate::geometry::Aabb;
use crate::mesh::Mesh;

use super::validate_boxes::{check_boxes, At, BoxTree, Child, Slot};
use super::{GpuArrays, LayoutKind, LeafTri};

pub(crate) use node_ray::DfsNodeRay;

/// Low two bits of `DfsNode::b` equal to this mark a leaf; otherwise they are the axis
/// (generated into the WGSL prelude as `DFS_LEAF_TAG`).
pub(crate) const LEAF_TAG: u32 = 3;

/// One node, 32 bytes (WGSL `DfsNode` in dfs_node.wgsl), shared by dfs-sign, dfs-distance
/// and threaded. Inner: `a` = second child index (threaded: the skip index, the node after
/// the subtree), `b` = split axis (0..=2).
/// Leaf: `a` = first triangle, `b` = count << 2 | LEAF_TAG.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct DfsNode {
    pub lo: [f32; 3],
    pub a: u32,
    pub hi: [f32; 3],
    pub b: u32,
}

impl DfsNode {
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == LEAF_TAG
    }
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }
    pub fn count(&self) -> u32 {
        self.b >> 2
    }
    pub fn bbox(&self) -> Aabb {
        Aabb {
            lo: self.lo.into(),
            hi: self.hi.into(),
        }
    }
}

/// Node `i` of `nodes` as the slot its parent enters it through: its own box, and its
/// triangles (a leaf) or itself (an inner node). For [`BoxTree`] (dfs-sign, threaded).
pub(crate) fn node_slot(nodes: &[DfsNode], i: usize) -> Slot {
    let n = &nodes[i];
    Slot {
        bbox: Some(n.bbox()),
        child: match n.is_leaf() {
            true => Child::Tris {
                first: n.a,
                count: n.count(),
            },
            false => Child::Node(i as u32),
        },
        at: At::Node(i as u32),
    }
}

/// The WGSL node struct and loader, with the leaf tag generated from [`LEAF_TAG`].
pub(crate) fn node_wgsl() -> String {
    format!(
        "const DFS_LEAF_TAG: u32 = {LEAF_TAG}u;\n{}",
        include_str!("dfs_node.wgsl")
    )
}

/// A BVH flattened in the `dfs-sign` layout; its [`Accel`](crate::accel::Accel) is the
/// CPU twin of `dfs_sign.wgsl`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DfsSign {
    pub(super) nodes: Vec<DfsNode>,
    pub(super) tris: Vec<LeafTri>,
}

impl DfsSign {
    /// Flattens a built tree (in parallel for big trees).
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> DfsSign {
        // The triangles and the nodes are independent: gathered and written side by side.
        let (tris, nodes) = rayon::join(|| LeafTri::gather(bvh, mesh), || dfs_nodes(bvh));
        DfsSign { nodes, tris }
    }

    /// The binary tree these arrays hold (the inverse of [`DfsSign::flatten`]): for the
    /// statistics of a layout flattened elsewhere (on the GPU: `gpu::lbvh_dfs_sign`), over a
    /// mesh of `mesh_len` triangles ([`Bvh::mesh_len`]; taken to end at the last triangle it
    /// holds where that is more).
    pub fn tree(&self, mesh_len: usize) -> Bvh {
        fn node(nodes: &[DfsNode], i: usize) -> Node {
            let n = &nodes[i];
            if n.is_leaf() {
                crate::accel::bvh::tree::leaf(n.bbox(), n.a as usize, n.count() as usize)
            } else {
                let children = [node(nodes, i + 1), node(nodes, n.a as usize)];
                Node::inner(n.bbox(), n.axis(), children)
            }
        }
        let order: Vec<u32> = self.tris.iter().map(|t| t.prim).collect();
        Bvh {
            root: node(&self.nodes, 0),
            mesh_len: (order.iter().max()).map_or(mesh_len, |&m| mesh_len.max(m as usize + 1)),
            order,
        }
    }

    /// A layout from raw arrays (as [`arrays`](super::GpuForm::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<DfsSign, String> {
        let (nodes, tris) = super::records(arrays)?;
        let layout = DfsSign { nodes, tris };
        super::GpuForm::validate(&layout)?;
        Ok(layout)
    }
}

impl super::GpuForm for DfsSign {
    fn name(&self) -> &'static str {
        LayoutKind::DfsSign.name()
    }

    fn node_bytes(&self) -> usize {
        std::mem::size_of::<DfsNode>()
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        format!("{}{}", node_wgsl(), include_str!("dfs_sign.wgsl"))
    }

    fn subgroup_wgsl(&self) -> Option<String> {
        Some(format!(
            "{}{}",
            node_wgsl(),
            include_str!("dfs_sign_subgroup.wgsl")
        ))
    }

    /// Child indices in range and forward, leaf ranges in range, depth ≤ MAX_DEPTH, every
    /// node reachable; then every node's box holds the triangles below it and the leaves
    /// cover the triangle array once (`check_boxes`).
    fn validate(&self) -> Result<(), String> {
        self.check_structure()?;
        check_boxes(self)
    }
}

impl BoxTree for DfsSign {
    fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
        std::iter::once(node_slot(&self.nodes, 0))
    }

    /// An inner node's children: the next node and its second child.
    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
        let i = node as usize;
        [i + 1, self.nodes[i].a as usize]
            .into_iter()
            .map(move |c| node_slot(&self.nodes, c))
    }

    fn tris(&self) -> &[LeafTri] {
        &self.tris
    }
}

impl DfsSign {
    /// [`validate`](super::GpuForm::validate)'s structural checks.
    fn check_structure(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("BVH has no nodes".into());
        }
        let seen = self.check_subtree(0, 0, self.nodes.len())?;
        if seen != self.nodes.len() {
            return Err(format!(
                "{} of {} nodes are unreachable",
                self.nodes.len() - seen,
                self.nodes.len()
            ));
        }
        Ok(())
    }

    /// The structural checks of the subtree at node `root` (at `depth`), which must end
    /// before node `end`; returns its number of nodes. Depth first in memory order; a big
    /// subtree's two halves on two threads, the first's fault named before the second's (the
    /// order of the walk on one thread).
    fn check_subtree(&self, root: usize, depth: usize, end: usize) -> Result<usize, String> {
        let mut stack = vec![(root, depth, end)];
        let mut seen = 0usize;
        while let Some((i, depth, end)) = stack.pop() {
            seen += 1;
            if depth > MAX_DEPTH {
                return Err(format!("node {i} is at depth {depth} > {MAX_DEPTH}"));
            }
            let n = &self.nodes[i];
            if n.is_leaf() {
                let (first, count) = (n.a as usize, n.count() as usize);
                if first + count > self.tris.len() {
                    return Err(format!(
                        "leaf {i} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
                continue;
            }
            let second = n.a as usize;
            if i + 1 >= second || second >= end {
                return Err(format!(
                    "inner node {i} has second child {second} outside {}..{end}",
                    i + 2
                ));
            }
            if end - i >= PARALLEL_NODES {
                let (first, next) = rayon::join(
                    || self.check_subtree(i + 1, depth + 1, second),
                    || self.check_subtree(second, depth + 1, end),
                );
                seen += first? + next?;
                continue;
            }
            // The first child last, so that the walk reads the nodes in memory order.
            stack.push((second, depth + 1, end));
            stack.push((i + 1, depth + 1, second));
        }
        Ok(seen)
    }
}

/// Subtrees with at least this many nodes are written, and checked, in parallel.
const PARALLEL_NODES: usize = 1 << 12;

/// The tree's nodes in depth-first pre-order (leaves hold positions in `bvh.order`): the
/// nodes of dfs-sign, and of the top level over instances.
pub(crate) fn dfs_nodes(bvh: &Bvh) -> Vec<DfsNode> {
    // Every subtree knows its size, so each writes its own part of the array; the big
    // ones on all threads (most of the time here is first touches of fresh pages).
    // With room past the end for a device to read them in place.
    let mut nodes = zeroed_with_room(bvh.root.nodes() as usize);
    write(&bvh.root, &mut nodes, 0);
    nodes
}

/// Writes `node`'s subtree in pre-order into `out` (exactly its size), whose first element
/// is node `index` of the whole array.
fn write(node: &Node, out: &mut [DfsNode], index: u32) {
    let b = node.bbox();
    let (a, tag, children) = match node {
        Node::Leaf { start, count, .. } => (*start, count << 2 | LEAF_TAG, None),
        Node::Inner { axis, children, .. } => {
            let second = index + 1 + children[0].nodes();
            (second, *axis as u32, Some(children))
        }
    };
    // Every subtree has at least its own node, so `out` is never empty.
    let Some((head, rest)) = out.split_first_mut() else {
        return;
    };
    *head = DfsNode {
        lo: b.lo.into(),
        a,
        hi: b.hi.into(),
        b: tag,
    };
    if let Some([l, r]) = children.map(|c| &**c) {
        let big = rest.len() >= PARALLEL_NODES;
        let (lo, hi) = rest.split_at_mut(l.nodes() as usize);
        if big {
            rayon::join(|| write(l, lo, index + 1), || write(r, hi, a));
        } else {
            write(l, lo, index + 1);
            write(r, hi, a);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::accel::GpuForm;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;

    #[test]
    fn the_wgsl_node_matches_the_rust_node() {
        let mesh = Mesh::from_triangles(vec![Triangle::new(
            glam::Vec3::ZERO,
            glam::Vec3::X,
            glam::Vec3::Y,
        )]);
        let layout = DfsSign::flatten(&crate::accel::bvh::build(&mesh, &Default::default()), &mesh);
        let src = shaders::trace_source(&layout, &crate::gpu::BufferParts::WHOLE);
        let fields = [
            ("lo", offset_of!(DfsNode, lo)),
            ("a", offset_of!(DfsNode, a)),
            ("hi", offset_of!(DfsNode, hi)),
            ("b", offset_of!(DfsNode, b)),
        ];
        shaders::check_struct(&src, "DfsNode", size_of::<DfsNode>(), &fields).unwrap();
        assert_eq!(size_of::<DfsNode>(), 32);
        assert!(layout.validate().is_ok());
    }
}
