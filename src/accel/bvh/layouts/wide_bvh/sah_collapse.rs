//! The wide layouts' collapse: the shared SAH programme (`layouts::sah_collapse`) for W slots on
//! lancer's binary tree as built, where a wide leaf is a binary subtree of at most
//! `MAX_LEAF_TRIS` triangles (its leaves' ranges are contiguous in leaf order, so it is one
//! range) or a binary leaf of any size. `collapse` gives up (and the greedy collapse is used)
//! where the tree would be deeper than the stack holds.

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Plan, SahCosts};
use crate::accel::bvh::Node;

use super::{WideNode, INNER};

/// SAH cost of a wide node's visit and of a triangle test.
pub(super) const C_NODE: f32 = 1.0;
pub(super) const C_TRI: f32 = 0.3;

/// Most triangles a leaf made of several binary leaves holds.
pub(super) const MAX_LEAF_TRIS: u32 = 4;

/// The binary tree in arrays, children before parents.
struct Arena<'a> {
    nodes: Vec<&'a Node>,
    kids: Vec<Option<[u32; 2]>>,
    tris: Vec<u32>,
}

impl<'a> Arena<'a> {
    fn add(&mut self, node: &'a Node) -> u32 {
        let (kids, tris) = match node {
            Node::Leaf { count, .. } => (None, *count),
            Node::Inner { children, .. } => {
                let (l, r) = (self.add(&children[0]), self.add(&children[1]));
                (Some([l, r]), self.tris[l as usize] + self.tris[r as usize])
            }
        };
        self.nodes.push(node);
        self.kids.push(kids);
        self.tris.push(tris);
        self.nodes.len() as u32 - 1
    }
}

impl BinaryTree for Arena<'_> {
    fn len(&self) -> usize {
        self.nodes.len()
    }

    fn area(&self, n: u32) -> f32 {
        self.nodes[n as usize].bbox().area()
    }

    fn kids(&self, n: u32) -> Option<[u32; 2]> {
        self.kids[n as usize]
    }

    fn tris(&self, n: u32) -> u32 {
        self.tris[n as usize]
    }
}

/// Appends the wide node of inner node n at depth d (and its subtree) to `out` in
/// pre-order; None when a node would lie deeper than `max_depth`.
fn emit<const W: usize>(
    arena: &Arena,
    plan: &Plan<W>,
    n: u32,
    d: usize,
    max_depth: usize,
    out: &mut Vec<WideNode<W>>,
) -> Option<u32>
where
    WideNode<W>: bytemuck::Pod,
{
    if d > max_depth {
        return None;
    }
    let index = out.len();
    out.push(bytemuck::Zeroable::zeroed());
    let mut rec: WideNode<W> = bytemuck::Zeroable::zeroed();
    for (k, (c, leaf)) in plan.children(arena, n).into_iter().enumerate() {
        let node = arena.nodes[c as usize];
        rec.set_bbox(k, node.bbox());
        (rec.child[k], rec.kind[k]) = match leaf {
            true => (first(node), arena.tris[c as usize]),
            false => (emit(arena, plan, c, d + 1, max_depth, out)?, INNER),
        };
    }
    out[index] = rec;
    Some(index as u32)
}

/// The first leaf-order position of `node`'s triangles.
fn first(node: &Node) -> u32 {
    match node {
        Node::Leaf { start, .. } => *start,
        Node::Inner { children, .. } => first(&children[0]),
    }
}

/// The W-wide nodes of `root`'s tree by the SAH collapse, in depth-first pre-order (the
/// root at 0); None when `root` is a leaf or the tree would be deeper than `max_depth`.
pub(super) fn collapse<const W: usize>(root: &Node, max_depth: usize) -> Option<Vec<WideNode<W>>>
where
    WideNode<W>: bytemuck::Pod,
{
    if matches!(root, Node::Leaf { .. }) {
        return None;
    }
    let mut arena = Arena {
        nodes: Vec::new(),
        kids: Vec::new(),
        tris: Vec::new(),
    };
    let r = arena.add(root);
    let costs = SahCosts {
        node: C_NODE,
        tri: C_TRI,
        max_leaf: MAX_LEAF_TRIS,
    };
    let plan = Plan::<W>::new(&arena, costs);
    let mut out = Vec::new();
    emit(&arena, &plan, r, 0, max_depth, &mut out)?;
    Some(out)
}
