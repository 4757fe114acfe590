//! The wide layouts' collapse: the shared SAH programme (`layouts::sah_collapse`) for W slots on
//! lancer's binary tree as built, where a wide leaf is a binary subtree of at most
//! `MAX_LEAF_TRIS` triangles (its leaves' ranges are contiguous in leaf order, so it is one
//! range) or a binary leaf of any size. `collapse` gives up (and the greedy collapse is used)
//! where the tree would be deeper than the stack holds.

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Decision, Entry, Plan, SahCosts};
use crate::accel::bvh::Node;

use super::{WideNode, INNER};

/// SAH cost of a wide node's visit and of a triangle test.
pub(super) const C_NODE: f32 = 1.0;
pub(super) const C_TRI: f32 = 0.3;

/// Most triangles a leaf made of several binary leaves holds.
pub(super) const MAX_LEAF_TRIS: u32 = 4;

/// The binary tree in arrays, children before parents (post-order, the root last).
struct Arena<'a> {
    nodes: Vec<&'a Node>,
    kids: Vec<Option<[u32; 2]>>,
    tris: Vec<u32>,
}

/// A subtree's share of the arena and of the plan: its nodes' slots, children before
/// parents, the subtree's root last.
struct Share<'s, 'a, const W: usize> {
    nodes: &'s mut [&'a Node],
    kids: &'s mut [Option<[u32; 2]>],
    tris: &'s mut [u32],
    decisions: &'s mut [Decision<W>],
}

impl<'s, 'a, const W: usize> Share<'s, 'a, W> {
    /// The first `at` slots, the rest before the last, and the last slot's parts.
    #[allow(clippy::type_complexity)] // four parallel arrays, split alike
    fn split(
        self,
        at: usize,
    ) -> (
        Self,
        Self,
        (
            &'s mut &'a Node,
            &'s mut Option<[u32; 2]>,
            &'s mut u32,
            &'s mut Decision<W>,
        ),
    ) {
        let last = self.nodes.len() - 1;
        let (n, n_own) = self.nodes.split_at_mut(last);
        let (k, k_own) = self.kids.split_at_mut(last);
        let (t, t_own) = self.tris.split_at_mut(last);
        let (e, e_own) = self.decisions.split_at_mut(last);
        let (n0, n1) = n.split_at_mut(at);
        let (k0, k1) = k.split_at_mut(at);
        let (t0, t1) = t.split_at_mut(at);
        let (e0, e1) = e.split_at_mut(at);
        (
            Share {
                nodes: n0,
                kids: k0,
                tris: t0,
                decisions: e0,
            },
            Share {
                nodes: n1,
                kids: k1,
                tris: t1,
                decisions: e1,
            },
            (&mut n_own[0], &mut k_own[0], &mut t_own[0], &mut e_own[0]),
        )
    }
}

/// Subtrees of at least this many nodes fill their two halves on two threads.
const PARALLEL_NODES: u32 = 8192;

/// Fills `share` with `node`'s subtree in post-order, its first slot at index `base`, and
/// the programme's decisions bottom-up (each subtree on its own thread where big); returns
/// the entry of `node`, which its parent's is made from.
fn fill<'a, const W: usize>(
    node: &'a Node,
    base: u32,
    share: Share<'_, 'a, W>,
    costs: SahCosts,
) -> Entry<W> {
    let area = node.bbox().area();
    let Node::Inner { children, .. } = node else {
        let count = match node {
            Node::Leaf { count, .. } => *count,
            Node::Inner { .. } => 0,
        };
        let entry = Entry::new(area, count, None, costs);
        share.nodes[0] = node;
        share.kids[0] = None;
        share.tris[0] = count;
        share.decisions[0] = entry.decision();
        return entry;
    };
    let nl = children[0].nodes();
    let (left, right, own) = share.split(nl as usize);
    let (l, r) = (nl as usize - 1, right.nodes.len() - 1);
    let go = |c: &'a Node, b: u32, s: Share<'_, 'a, W>| fill(c, b, s, costs);
    let ((left, le), (right, re)) = if node.nodes() >= PARALLEL_NODES {
        rayon::join(
            || {
                let mut s = left;
                let e = go(&children[0], base, reborrow(&mut s));
                (s, e)
            },
            || {
                let mut s = right;
                let e = go(&children[1], base + nl, reborrow(&mut s));
                (s, e)
            },
        )
    } else {
        let (mut a, mut b) = (left, right);
        let ea = go(&children[0], base, reborrow(&mut a));
        let eb = go(&children[1], base + nl, reborrow(&mut b));
        ((a, ea), (b, eb))
    };
    let tris = left.tris[l] + right.tris[r];
    let entry = Entry::new(area, tris, Some([&le, &re]), costs);
    *own.0 = node;
    *own.1 = Some([base + l as u32, base + nl + r as u32]);
    *own.2 = tris;
    *own.3 = entry.decision();
    entry
}

fn reborrow<'t, 'a, const W: usize>(s: &'t mut Share<'_, 'a, W>) -> Share<'t, 'a, W> {
    Share {
        nodes: s.nodes,
        kids: s.kids,
        tris: s.tris,
        decisions: s.decisions,
    }
}

impl BinaryTree for Arena<'_> {
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
    let costs = SahCosts {
        node: C_NODE,
        tri: C_TRI,
        max_leaf: MAX_LEAF_TRIS,
    };
    let len = root.nodes() as usize;
    let mut arena = Arena {
        nodes: vec![root; len],
        kids: vec![None; len],
        tris: vec![0; len],
    };
    let mut decisions = vec![Decision::NONE; len];
    let share = Share {
        nodes: &mut arena.nodes,
        kids: &mut arena.kids,
        tris: &mut arena.tris,
        decisions: &mut decisions,
    };
    fill(root, 0, share, costs);
    let plan = Plan::<W>::from_decisions(decisions);
    let r = len as u32 - 1;
    let mut out = Vec::new();
    emit(&arena, &plan, r, 0, max_depth, &mut out)?;
    Some(out)
}
