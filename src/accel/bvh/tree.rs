//! The tree the builders produce: boxes, split axes, leaf ranges into a triangle order.

use crate::geometry::Aabb;

/// Deepest leaf depth (root = 0). Traversal keeps one stack entry per interior ancestor,
/// so a 64-entry stack (CPU and GPU) can never overflow.
pub const MAX_DEPTH: usize = 64;

/// A built tree. Leaves refer to ranges of [`Bvh::order`].
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    /// Triangles `order[start..start + count]`.
    Leaf {
        /// Bounds of the leaf's triangles.
        bbox: Aabb,
        /// First position in [`Bvh::order`].
        start: u32,
        /// Number of triangles.
        count: u32,
    },
    /// Two subtrees, split on `axis`.
    Inner {
        /// Bounds of the subtree's triangles.
        bbox: Aabb,
        /// Split axis: 0 = x, 1 = y, 2 = z.
        axis: u8,
        /// Nodes in this subtree, itself included: where flattening puts the second child.
        nodes: u32,
        /// The low side of the split axis, then the high side.
        children: Box<[Node; 2]>,
    },
}

impl Node {
    pub(crate) fn inner(bbox: Aabb, axis: usize, children: [Node; 2]) -> Node {
        Kids::reserve().inner(bbox, axis, children)
    }

    /// The inner node over two subtrees split on `axis` (0, 1 or 2; the low side first):
    /// its box theirs joined, its count theirs and itself. How a builder of your own makes
    /// its inner nodes ([`Bvh::new`] checks the tree).
    pub fn parent(axis: u8, children: [Node; 2]) -> Node {
        let bbox = children[0].bbox().union(*children[1].bbox());
        Node::inner(bbox, axis as usize, children)
    }

    /// Nodes in this subtree, itself included.
    pub fn nodes(&self) -> u32 {
        match self {
            Node::Leaf { .. } => 1,
            Node::Inner { nodes, .. } => *nodes,
        }
    }

    /// The leaf-order positions `start..end` of this subtree's triangles: its leaves'
    /// ranges follow one another (as [`Bvh::new`] checks), so the first leaf's start and
    /// the last leaf's end.
    pub(crate) fn leaf_range(&self) -> (u32, u32) {
        let mut first = self;
        while let Node::Inner { children, .. } = first {
            first = &children[0];
        }
        let mut last = self;
        while let Node::Inner { children, .. } = last {
            last = &children[1];
        }
        match (first, last) {
            (
                Node::Leaf { start, .. },
                Node::Leaf {
                    start: s, count, ..
                },
            ) => (*start, s + count),
            _ => (0, 0),
        }
    }

    /// Bounds of the triangles in this subtree.
    pub fn bbox(&self) -> &Aabb {
        match self {
            Node::Leaf { bbox, .. } | Node::Inner { bbox, .. } => bbox,
        }
    }
}

/// A BVH over the included triangles of a mesh: `order[i]` is the original triangle index
/// at position i of leaf order (leaves appear left to right, their ranges following one
/// another).
///
/// Made by the builders ([`build`](super::build)), kept valid by [`Bvh::refit`] and
/// [`optimize`](super::optimize), or from a tree made elsewhere (your own builder's) by
/// [`Bvh::new`], which checks the shape that flattening and the statistics rely on. Its
/// fields are read through [`Bvh::root`] and [`Bvh::order`].
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    /// The root node.
    pub(crate) root: Node,
    /// Original (file-order) triangle indices in leaf order (the builders': included
    /// triangles only).
    pub(crate) order: Vec<u32>,
    /// Triangles (the top level over instances: boxes) of what it was built over: every
    /// entry of `order` lies below this.
    pub(crate) mesh_len: usize,
}

impl Bvh {
    /// The root node.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// Original (file-order) triangle indices in leaf order: a leaf holds positions
    /// `start..start + count`. A triangle split in space (the spatial-split builder's) is
    /// listed once for each leaf that holds a part of it.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Triangles of the mesh it was built over (the top level over instances: boxes): a
    /// smaller mesh is refused by [`try_flatten`] and [`epo_cost`], which read it by the
    /// tree's indices.
    ///
    /// [`try_flatten`]: super::layouts::try_flatten
    /// [`epo_cost`]: super::epo_cost
    pub fn mesh_len(&self) -> usize {
        self.mesh_len
    }

    /// Refuses a mesh smaller than the one the tree was built over (its triangles are read
    /// by the tree's indices); `to` says what the caller does with it, for the message.
    pub(crate) fn check_mesh(&self, mesh: &crate::mesh::Mesh, to: &str) -> crate::Result<()> {
        if self.mesh_len > mesh.len() {
            return Err(crate::Error::Usage(format!(
                "the BVH was built over {} triangles but the mesh given has {}: {to} the mesh \
                 it was built over",
                self.mesh_len,
                mesh.len()
            )));
        }
        Ok(())
    }

    /// The tree over none of a mesh's `mesh_len` triangles: one empty leaf.
    pub(crate) fn empty(mesh_len: usize) -> Bvh {
        Bvh {
            root: leaf(Aabb::EMPTY, 0, 0),
            order: Vec::new(),
            mesh_len,
        }
    }
}

impl Drop for Bvh {
    /// A big tree is one small allocation per inner node: the top subtrees are freed on all
    /// threads.
    fn drop(&mut self) {
        fn free(node: Node, depth: u32) {
            if let Node::Inner { children, .. } = node {
                if depth < 4 {
                    let [a, b] = *children;
                    rayon::join(|| free(a, depth + 1), || free(b, depth + 1));
                }
            }
        }
        free(
            std::mem::replace(&mut self.root, leaf(Aabb::EMPTY, 0, 0)),
            0,
        );
    }
}

/// An inner node's children's place, allocated before they are built: a builder that
/// reserves it before recursing lays the tree out in memory in the order a depth-first walk
/// reads it (parents before children, left subtrees before right), so that walks stream
/// through memory instead of chasing pointers back and forth.
pub(crate) struct Kids(Box<[Node; 2]>);

impl Kids {
    const UNSET: Node = Node::Leaf {
        bbox: Aabb::EMPTY,
        start: 0,
        count: 0,
    };

    pub fn reserve() -> Kids {
        Kids(Box::new([Kids::UNSET, Kids::UNSET]))
    }

    /// The inner node of these children, put in their reserved place.
    pub fn inner(mut self, bbox: Aabb, axis: usize, children: [Node; 2]) -> Node {
        *self.0 = children;
        let nodes = 1 + self.0[0].nodes() + self.0[1].nodes();
        Node::Inner {
            bbox,
            axis: axis as u8,
            nodes,
            children: self.0,
        }
    }
}

/// For a node whose children were not made by a split (merged or moved): the axis on which
/// their centres lie farthest apart, and whether `b` is the low side there (then it goes
/// first).
pub(crate) fn children_order(a: &Aabb, b: &Aabb) -> (usize, bool) {
    let (ca, cb) = (a.center(), b.center());
    let gap = (cb - ca).abs();
    let axis = if gap.x >= gap.y && gap.x >= gap.z {
        0
    } else if gap.y >= gap.z {
        1
    } else {
        2
    };
    (axis, cb[axis] < ca[axis])
}

pub(crate) fn leaf(bbox: Aabb, start: usize, count: usize) -> Node {
    Node::Leaf {
        bbox,
        start: start as u32,
        count: count as u32,
    }
}
