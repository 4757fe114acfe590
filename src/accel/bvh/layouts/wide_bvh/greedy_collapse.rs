//! The greedy collapse (Wald, Benthin & Boulos 2008, "Getting rid of packets"; tinybvh's
//! `ConvertBVH4`), used where the SAH collapse's tree would be too deep for the stack: a
//! node starts with its binary node's two children and, while it has fewer than W, the
//! inner child with the largest surface area is replaced by its two children. A wide node
//! costs one visit whatever its number of children, so pulling up child C removes C's own
//! visit, taken with probability area(C)/area(root): the largest area is the greedy SAH
//! choice. One rule comes first, for the stack: a node at wide depth d comes from a binary
//! node at depth b ≥ d·log2(W) (an inner child that would break this is pulled up before
//! the greedy choice), so no node lies deeper than `max_wide_depth(W)`.

use crate::accel::bvh::Node;

use super::{levels_per_node, WideNode, INNER};

/// The W-wide nodes of `root`'s tree, in depth-first pre-order (the root at 0).
pub(super) fn collapse<const W: usize>(root: &Node) -> Vec<WideNode<W>>
where
    WideNode<W>: bytemuck::Pod,
{
    // About one W-wide node per W − 1 binary inner nodes.
    let mut nodes = Vec::with_capacity(root.nodes() as usize / (2 * (W - 1)) + 1);
    emit(root, 0, 0, &mut nodes);
    nodes
}

/// The binary nodes that become the children of `node`'s W-wide node, left to right, each
/// with its binary depth; `node` is at binary depth `b` and becomes a wide node at depth
/// `d` ≤ b / L, L = log2(W). First every inner child that would break d + 1 ≤ b' / L one
/// level down is replaced by its two children, and so on (they come from at most L levels
/// below `node`: at most W of them); then, while there are fewer than W, the inner child
/// of largest area (the first among equals). A leaf (the root of a tiny tree) is its own
/// single child.
fn slots<const W: usize>(node: &Node, d: usize, b: usize) -> Vec<(&Node, usize)> {
    let l = levels_per_node(W);
    let Node::Inner { children, .. } = node else {
        return vec![(node, b)];
    };
    let mut slots: Vec<(&Node, usize)> = children.iter().map(|c| (c, b + 1)).collect();
    let mut k = 0;
    while k < slots.len() {
        match slots[k] {
            (Node::Inner { children, .. }, bc) if d + 1 > bc / l => {
                slots.splice(k..=k, children.iter().map(|c| (c, bc + 1)));
            }
            _ => k += 1,
        }
    }
    while slots.len() < W {
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

/// Appends the W-wide subtree of `node` (at binary depth `b`, wide depth `d`) to `out`
/// in pre-order; returns its index.
fn emit<const W: usize>(node: &Node, d: usize, b: usize, out: &mut Vec<WideNode<W>>) -> u32
where
    WideNode<W>: bytemuck::Pod,
{
    let index = out.len();
    out.push(bytemuck::Zeroable::zeroed());
    let mut rec: WideNode<W> = bytemuck::Zeroable::zeroed();
    for (k, (c, bc)) in slots::<W>(node, d, b).into_iter().enumerate() {
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
