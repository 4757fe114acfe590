//! `threaded`: eight copies of the dfs-sign tree, one per ray-direction octant, each in the
//! depth-first pre-order that octant's rays visit in dfs-sign (at a node split on axis k, the
//! high child first when the ray's direction is negative on k). An inner node stores its
//! skip index, the node after its subtree, so traversal needs no stack: a hit inner node
//! goes on to the next node (its near child), a missed one to its skip index, a leaf to the
//! next node. A ray walks the copy of its octant (bit k set: direction negative on axis k)
//! and visits the nodes dfs-sign visits, in the same order. Eight times dfs-sign's nodes in
//! exchange for no stack: lavapipe turns every per-lane stack access into a loop over lanes.

mod twin;

use crate::accel::gpu_form::zeroed_with_room;
use rayon::prelude::*;

use crate::accel::bvh::{Bvh, Node};
use crate::mesh::Mesh;

use super::dfs_sign::{node_slot, node_wgsl, DfsNode, LEAF_TAG};
use super::validate_boxes::{check_boxes, BoxTree, Slot};
use super::{GpuArrays, LayoutKind, LeafTri};

/// Copies of the tree: one per ray-direction octant.
pub(crate) const OCTANTS: usize = 8;

/// The copy a ray with direction `dir` walks: bit k set when `dir[k] < 0` (so -0.0 counts as
/// positive, as in dfs-sign's child order). The WGSL computes the same in `threaded.wgsl`.
#[inline(always)]
pub(crate) fn octant(dir: glam::Vec3) -> usize {
    (dir.x < 0.0) as usize | ((dir.y < 0.0) as usize) << 1 | ((dir.z < 0.0) as usize) << 2
}

/// A BVH flattened in the `threaded` layout; its [`Accel`](crate::accel::Accel) is the CPU
/// twin of `threaded.wgsl`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Threaded {
    /// [`OCTANTS`] copies of one tree, each of `nodes.len() / OCTANTS` nodes. Inner: `a` =
    /// the skip index (global), `b` = split axis. Leaf: as in dfs-sign.
    pub(super) nodes: Vec<DfsNode>,
    pub(super) tris: Vec<LeafTri>,
}

impl Threaded {
    /// Bytes the layout's nodes take for a tree of `tree_nodes` nodes (for a memory check
    /// before flattening).
    pub(crate) fn node_array_bytes(tree_nodes: u64) -> u128 {
        tree_nodes as u128 * OCTANTS as u128 * std::mem::size_of::<DfsNode>() as u128
    }

    /// Flattens a built tree: the eight copies in parallel.
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> Threaded {
        let n = bvh.root.nodes() as usize;
        // The triangles and the eight copies are independent: made side by side.
        let (tris, nodes) = rayon::join(
            || LeafTri::gather(bvh, mesh),
            || {
                let mut nodes = zeroed_with_room(OCTANTS * n);
                nodes
                    .par_chunks_mut(n)
                    .enumerate()
                    .for_each(|(o, copy)| write(&bvh.root, copy, (o * n) as u32, o));
                nodes
            },
        );
        Threaded { nodes, tris }
    }

    /// A layout from raw arrays (as [`arrays`](super::GpuForm::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<Threaded, String> {
        let (nodes, tris) = super::records(arrays)?;
        let layout = Threaded { nodes, tris };
        super::GpuForm::validate(&layout)?;
        Ok(layout)
    }

    /// Nodes in one copy: copy 0's root says it (its skip index, or 1 for a leaf), as the
    /// WGSL reads it.
    fn copy_len(&self) -> usize {
        let root = &self.nodes[0];
        if root.is_leaf() {
            1
        } else {
            root.a as usize
        }
    }
}

impl super::GpuForm for Threaded {
    fn name(&self) -> &'static str {
        LayoutKind::Threaded.name()
    }

    fn node_bytes(&self) -> usize {
        std::mem::size_of::<DfsNode>()
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        format!("{}{}", node_wgsl(), include_str!("threaded.wgsl"))
    }

    fn subgroup_wgsl(&self) -> Option<String> {
        Some(format!(
            "{}{}",
            node_wgsl(),
            include_str!("threaded_subgroup.wgsl")
        ))
    }

    /// Eight copies of copy 0's root's size; in each, every subtree is whole (an inner node's
    /// skip index ends its subtree, two children partition it, a leaf is one node) and every
    /// leaf range is in range. Skip indices then only move forward, so traversal ends. Then
    /// in each copy every node's box holds the triangles below it and the leaves cover the
    /// triangle array once (`check_boxes`).
    fn validate(&self) -> Result<(), String> {
        self.check_structure()?;
        check_boxes(self)
    }
}

impl BoxTree for Threaded {
    /// The root of each copy.
    fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
        let n = self.copy_len();
        (0..OCTANTS).map(move |o| node_slot(&self.nodes, o * n))
    }

    /// An inner node's children: the next node, and the node after that one's subtree.
    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
        let first = node as usize + 1;
        let near = &self.nodes[first];
        let far = if near.is_leaf() {
            first + 1
        } else {
            near.a as usize
        };
        [first, far]
            .into_iter()
            .map(move |c| node_slot(&self.nodes, c))
    }

    fn tris(&self) -> &[LeafTri] {
        &self.tris
    }
}

impl Threaded {
    /// [`validate`](super::GpuForm::validate)'s structural checks.
    fn check_structure(&self) -> Result<(), String> {
        let total = self.nodes.len();
        if total == 0 {
            return Err("BVH has no nodes".into());
        }
        let n = self.copy_len();
        if n == 0 || n.checked_mul(OCTANTS) != Some(total) {
            return Err(format!(
                "{total} nodes are not {OCTANTS} copies of the {n} nodes copy 0's root spans"
            ));
        }
        // The copies on all threads; the first fault in copy order is named.
        let copies: Vec<Result<(), String>> = (0..OCTANTS)
            .into_par_iter()
            .map(|o| self.check_copy(o * n..o * n + n))
            .collect();
        copies.into_iter().collect()
    }

    /// [`check_structure`](Self::check_structure) of the copy at nodes `range`.
    fn check_copy(&self, range: std::ops::Range<usize>) -> Result<(), String> {
        let mut stack = vec![(range.start, range.end)];
        while let Some((i, end)) = stack.pop() {
            let node = &self.nodes[i];
            if node.is_leaf() {
                if end != i + 1 {
                    return Err(format!("leaf {i} stands where a subtree {i}..{end} should"));
                }
                let (first, count) = (node.a as usize, node.count() as usize);
                if first + count > self.tris.len() {
                    return Err(format!(
                        "leaf {i} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
                continue;
            }
            if node.a as usize != end {
                return Err(format!(
                    "inner node {i} skips to {} but its subtree ends at {end}",
                    node.a
                ));
            }
            let first = i + 1;
            let mid = match self.nodes.get(first) {
                Some(c) if first < end && c.is_leaf() => first + 1,
                Some(c) if first < end => c.a as usize,
                _ => end,
            };
            if mid <= first || mid >= end {
                return Err(format!(
                    "inner node {i}: its first child {first} ends at {mid}, outside {}..{end}",
                    first + 1
                ));
            }
            // The first child last, so that the walk reads the nodes in memory order.
            stack.push((mid, end));
            stack.push((first, mid));
        }
        Ok(())
    }
}

/// Subtrees with at least this many nodes are written in parallel.
const PARALLEL_NODES: usize = 1 << 12;

/// Writes `node`'s subtree in octant `octant`'s pre-order into `out` (exactly its size),
/// whose first element is node `index` of the whole array.
fn write(node: &Node, out: &mut [DfsNode], index: u32, octant: usize) {
    let b = node.bbox();
    let (a, tag, children) = match node {
        Node::Leaf { start, count, .. } => (*start, count << 2 | LEAF_TAG, None),
        Node::Inner { axis, children, .. } => {
            let [l, r] = &**children;
            // dfs-sign's child order: the high child first for rays negative on the axis.
            let near_far = if octant >> *axis as usize & 1 == 1 {
                (r, l)
            } else {
                (l, r)
            };
            (index + node.nodes(), *axis as u32, Some(near_far))
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
    if let Some((near, far)) = children {
        let big = rest.len() >= PARALLEL_NODES;
        let (lo, hi) = rest.split_at_mut(near.nodes() as usize);
        let far_index = index + 1 + near.nodes();
        if big {
            rayon::join(
                || write(near, lo, index + 1, octant),
                || write(far, hi, far_index, octant),
            );
        } else {
            write(near, lo, index + 1, octant);
            write(far, hi, far_index, octant);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::GpuForm;
    use crate::geometry::Triangle;
    use glam::Vec3;

    fn layout() -> Threaded {
        let tris = (0..40)
            .map(|i| {
                let p = Vec3::new((i % 7) as f32, (i / 7) as f32, (i % 3) as f32);
                Triangle::new(p, p + Vec3::X, p + Vec3::Y)
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let opts = crate::accel::bvh::BuildOptions {
            max_leaf: 2,
            ..Default::default()
        };
        Threaded::flatten(&crate::accel::bvh::build(&mesh, &opts), &mesh)
    }

    #[test]
    fn each_copy_is_a_whole_tree_in_its_octants_order() {
        let l = layout();
        l.validate().unwrap();
        let n = l.copy_len();
        assert!(n > 3 && l.nodes.len() == OCTANTS * n);
        for o in 0..OCTANTS {
            // Same boxes in every copy, reordered: a copy's root is the tree's root.
            assert_eq!(l.nodes[o * n].bbox(), l.nodes[0].bbox());
            let root = &l.nodes[o * n];
            assert_eq!(root.a as usize, o * n + n);
            // The root's near child holds the low side unless the octant is negative on
            // the root's axis.
            let near = &l.nodes[o * n + 1];
            let axis = root.axis();
            let low_first = o >> axis & 1 == 0;
            let other_copy = &l.nodes[(o ^ (1 << axis)) * n + 1];
            assert_ne!(near.bbox(), other_copy.bbox(), "octant {o}");
            let (nl, ol) = (near.lo[axis], other_copy.lo[axis]);
            assert_eq!(nl <= ol, low_first, "octant {o}");
        }
    }

    #[test]
    fn corruptions_are_refused() {
        let good = layout();
        let n = good.copy_len();
        type Corruption = Box<dyn Fn(&mut Threaded)>;
        let cases: Vec<(&str, Corruption)> = vec![
            (
                "not 8 copies",
                Box::new(|l| {
                    l.nodes.pop();
                }),
            ),
            ("skips to", Box::new(move |l| l.nodes[3 * n].a -= 1)),
            (
                "refers to triangles",
                Box::new(move |l| {
                    let leaf = (5 * n..6 * n).find(|&i| l.nodes[i].is_leaf()).unwrap();
                    l.nodes[leaf].a = l.tris.len() as u32;
                }),
            ),
            (
                "first child",
                Box::new(move |l| {
                    let inner = (2 * n + 1..3 * n).find(|&i| !l.nodes[i].is_leaf()).unwrap();
                    // The first child made inner, skipping backwards.
                    l.nodes[inner + 1].b = 0;
                    l.nodes[inner + 1].a = inner as u32;
                }),
            ),
        ];
        for (want, corrupt) in cases {
            let mut l = good.clone();
            corrupt(&mut l);
            let e = l.validate().unwrap_err();
            assert!(e.contains(want), "{want}: {e}");
        }
    }
}
