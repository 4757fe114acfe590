//! The greedy collapse (Wald, Benthin & Boulos 2008, "Getting rid of packets"; tinybvh's
//! `ConvertBVH4`), used where the SAH collapse's tree would be too deep for the stack: a
//! node starts with its binary node's two children and, while it has fewer than four, the
//! inner child with the largest surface area is replaced by its two children. A 4-wide node
//! costs one visit whatever its number of children, so pulling up child C removes C's own
//! visit, taken with probability area(C)/area(root): the largest area is the greedy SAH
//! choice. One rule comes first, for the stack: a node at 4-wide depth d comes from a binary
//! node at depth b ≥ 2d (an inner child one binary level down that would break this is
//! pulled up before the greedy choice), so no node lies deeper than `MAX_WIDE_DEPTH`.

use crate::accel::bvh::Node;

use super::{Bvh4Node, INNER, WIDTH};

/// The 4-wide nodes of `root`'s tree, in depth-first pre-order (the root at 0).
pub(super) fn collapse(root: &Node) -> Vec<Bvh4Node> {
    // About one 4-wide node per three binary inner nodes.
    let mut nodes = Vec::with_capacity(root.nodes() as usize / 6 + 1);
    emit(root, 0, 0, &mut nodes);
    nodes
}

/// The binary nodes that become the children of `node`'s 4-wide node, left to right, each
/// with its binary depth; `node` is at binary depth `b` and becomes a 4-wide node at depth
/// `d` ≤ b / 2. First an inner child that would break d ≤ b / 2 one level down is replaced
/// by its two children (at most both children are, which makes four); then, while there
/// are fewer than four, the inner child of largest area (the first among equals). A leaf
/// (the root of a tiny tree) is its own single child.
fn slots(node: &Node, d: usize, b: usize) -> Vec<(&Node, usize)> {
    let Node::Inner { children, .. } = node else {
        return vec![(node, b)];
    };
    let mut slots: Vec<(&Node, usize)> = children.iter().map(|c| (c, b + 1)).collect();
    let mut k = 0;
    while k < slots.len() {
        match slots[k] {
            (Node::Inner { children, .. }, bc) if d + 1 > bc / 2 => {
                slots.splice(k..=k, children.iter().map(|c| (c, bc + 1)));
            }
            _ => k += 1,
        }
    }
    while slots.len() < WIDTH {
        let mut pick: Option<(usize, f32)> = None;
        for (k, (c, _)) in slots.iter().enumerate() {
            if matches!(c, Node::Inner { .. }) {
                let a = c.bbox().area();
                if pick.is_none_or(|(_, best)| a > best) {
                    pick = Some((k, a));
                }
            }
        }
        let Some((k, _)) = pick else { break };
        if let (Node::Inner { children, .. }, bc) = slots[k] {
            slots.splice(k..=k, children.iter().map(|c| (c, bc + 1)));
        }
    }
    slots
}

/// Appends the 4-wide subtree of `node` (at binary depth `b`, 4-wide depth `d`) to `out`
/// in pre-order; returns its index.
fn emit(node: &Node, d: usize, b: usize, out: &mut Vec<Bvh4Node>) -> u32 {
    let index = out.len();
    out.push(bytemuck::Zeroable::zeroed());
    let mut rec: Bvh4Node = bytemuck::Zeroable::zeroed();
    for (k, (c, bc)) in slots(node, d, b).into_iter().enumerate() {
        match c {
            Node::Leaf { bbox, start, count } => {
                // An empty leaf (the root of an empty tree) is an unused slot.
                if *count > 0 {
                    rec.set_bbox(k, bbox);
                    (rec.child[k], rec.kind[k]) = (*start, *count);
                }
            }
            Node::Inner { bbox, .. } => {
                rec.set_bbox(k, bbox);
                (rec.child[k], rec.kind[k]) = (emit(c, d + 1, bc, out), INNER);
            }
        }
    }
    out[index] = rec;
    index as u32
}
