//! The SAH collapse: which binary nodes become 4-wide nodes and which leaves, decided by
//! the dynamic programme of Ylitie, Karras & Laine 2017 (§4.1, as `cwbvh`'s collapse) for
//! four slots. A leaf is a binary subtree of at most `MAX_LEAF_TRIS` triangles (its leaves'
//! ranges are contiguous in leaf order, so it is one range); cost(n, i) is the cheapest way
//! to hold n's subtree in at most i slots:
//!
//! ```text
//! cost(n, 1) = min(leaf: C_TRI·A(n)·tris(n) if tris(n) ≤ MAX_LEAF_TRIS,  inner: C_NODE·A(n) + spread(n, 4))
//! cost(n, i) = min(cost(n, i − 1), spread(n, i))            for i = 2..=4
//! spread(n, j) = min over 0 < k < j of cost(left, k) + cost(right, j − k)
//! ```
//!
//! Every 4-wide child is a strict binary descendant, so the 4-wide tree is never deeper
//! than the binary one; `emit` gives up (and the greedy collapse is used) where it would be
//! deeper than the stack holds.

use crate::accel::bvh::Node;

use super::{Bvh4Node, INNER, WIDTH};

/// SAH cost of a 4-wide node's visit and of a triangle test.
pub(super) const C_NODE: f32 = 1.0;
pub(super) const C_TRI: f32 = 0.3;

/// Most triangles a leaf made of several binary leaves holds (a binary leaf is kept
/// whatever its size).
pub(super) const MAX_LEAF_TRIS: u32 = 4;

/// How a node's subtree is held in `i` slots.
#[derive(Clone, Copy, Debug, Default)]
enum Choice {
    /// One slot: a leaf.
    #[default]
    Leaf,
    /// One slot: a 4-wide node.
    Inner,
    /// As in i − 1 slots.
    Fewer,
    /// k slots for the left child, i − k for the right.
    Spread(u8),
}

/// The binary tree in arrays, children before parents, with the programme's tables.
struct Plan<'a> {
    nodes: Vec<&'a Node>,
    kids: Vec<Option<[u32; 2]>>,
    tris: Vec<u32>,
    /// cost[n][i − 1], choice[n][i − 1] for i = 1..=WIDTH.
    cost: Vec<[f32; WIDTH]>,
    choice: Vec<[Choice; WIDTH]>,
    /// spread(n, WIDTH)'s split for an inner node.
    inner_split: Vec<u8>,
}

impl<'a> Plan<'a> {
    fn add(&mut self, node: &'a Node) -> u32 {
        let kids = match node {
            Node::Leaf { .. } => None,
            Node::Inner { children, .. } => Some([self.add(&children[0]), self.add(&children[1])]),
        };
        let tris = match (node, kids) {
            (Node::Leaf { count, .. }, _) => *count,
            (_, Some([l, r])) => self.tris[l as usize] + self.tris[r as usize],
            _ => 0,
        };
        let area = node.bbox().area();
        let mut cost = [f32::INFINITY; WIDTH];
        let mut choice = [Choice::default(); WIDTH];
        let mut inner_split = 0;
        match kids {
            None => {
                cost = [C_TRI * area * tris as f32; WIDTH];
                choice = [Choice::Leaf, Choice::Fewer, Choice::Fewer, Choice::Fewer];
            }
            Some([l, r]) => {
                let (cl, cr) = (self.cost[l as usize], self.cost[r as usize]);
                let spread = |j: usize| -> (f32, u8) {
                    (1..j)
                        .map(|k| (cl[k - 1] + cr[j - k - 1], k as u8))
                        .fold((f32::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
                };
                let (s, k) = spread(WIDTH);
                inner_split = k;
                let inner = C_NODE * area + s;
                let leaf = match tris <= MAX_LEAF_TRIS {
                    true => C_TRI * area * tris as f32,
                    false => f32::INFINITY,
                };
                (cost[0], choice[0]) = match leaf <= inner {
                    true => (leaf, Choice::Leaf),
                    false => (inner, Choice::Inner),
                };
                for i in 2..=WIDTH {
                    let (s, k) = spread(i);
                    (cost[i - 1], choice[i - 1]) = match s < cost[i - 2] {
                        true => (s, Choice::Spread(k)),
                        false => (cost[i - 2], Choice::Fewer),
                    };
                }
            }
        }
        self.nodes.push(node);
        self.kids.push(kids);
        self.tris.push(tris);
        self.cost.push(cost);
        self.choice.push(choice);
        self.inner_split.push(inner_split);
        self.nodes.len() as u32 - 1
    }

    /// The slots holding n's subtree in at most i slots: (node, as a leaf).
    fn slots(&self, n: u32, i: usize, out: &mut Vec<(u32, bool)>) {
        match self.choice[n as usize][i - 1] {
            Choice::Leaf => out.push((n, true)),
            Choice::Inner => out.push((n, false)),
            Choice::Fewer => self.slots(n, i - 1, out),
            Choice::Spread(k) => self.spread(n, i, k as usize, out),
        }
    }

    fn spread(&self, n: u32, i: usize, k: usize, out: &mut Vec<(u32, bool)>) {
        let Some([l, r]) = self.kids[n as usize] else {
            return;
        };
        self.slots(l, k, out);
        self.slots(r, i - k, out);
    }

    /// Appends the 4-wide node of inner node n at depth d (and its subtree) to `out` in
    /// pre-order; None when a node would lie deeper than `max_depth`.
    fn emit(&self, n: u32, d: usize, max_depth: usize, out: &mut Vec<Bvh4Node>) -> Option<u32> {
        if d > max_depth {
            return None;
        }
        let index = out.len();
        out.push(bytemuck::Zeroable::zeroed());
        let mut slots = Vec::with_capacity(WIDTH);
        self.spread(n, WIDTH, self.inner_split[n as usize] as usize, &mut slots);
        let mut rec: Bvh4Node = bytemuck::Zeroable::zeroed();
        for (k, &(c, leaf)) in slots.iter().enumerate() {
            let node = self.nodes[c as usize];
            rec.set_bbox(k, node.bbox());
            (rec.child[k], rec.kind[k]) = match leaf {
                true => (first(node), self.tris[c as usize]),
                false => (self.emit(c, d + 1, max_depth, out)?, INNER),
            };
        }
        out[index] = rec;
        Some(index as u32)
    }
}

/// The first leaf-order position of `node`'s triangles.
fn first(node: &Node) -> u32 {
    match node {
        Node::Leaf { start, .. } => *start,
        Node::Inner { children, .. } => first(&children[0]),
    }
}

/// The 4-wide nodes of `root`'s tree by the SAH collapse, in depth-first pre-order (the
/// root at 0); None when `root` is a leaf or the tree would be deeper than `max_depth`.
pub(super) fn collapse(root: &Node, max_depth: usize) -> Option<Vec<Bvh4Node>> {
    if matches!(root, Node::Leaf { .. }) {
        return None;
    }
    let mut plan = Plan {
        nodes: Vec::new(),
        kids: Vec::new(),
        tris: Vec::new(),
        cost: Vec::new(),
        choice: Vec::new(),
        inner_split: Vec::new(),
    };
    let r = plan.add(root);
    let mut out = Vec::new();
    plan.emit(r, 0, max_depth, &mut out)?;
    Some(out)
}
