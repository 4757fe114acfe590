//! The wide layouts' collapse: the shared SAH programme (`layouts::sah_collapse`) for W slots on
//! lancer's binary tree as built, where a wide leaf is a binary subtree of at most
//! `MAX_LEAF_TRIS` triangles (its leaves' ranges are contiguous in leaf order, so it is one
//! range) or a binary leaf of any size. `collapse` gives up (and the greedy collapse is used)
//! where the tree would be deeper than the stack holds.

use crate::accel::gpu_form::zeroed_on_all_threads_with_room;

use rayon::prelude::*;

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Decision, Entry, Plan, SahCosts};
use crate::accel::bvh::Node;
use crate::util::zeroed_on_all_threads;

use super::{WideNode, INNER};

/// SAH cost of a wide node's visit and of a triangle test.
pub(super) const C_NODE: f32 = 1.0;
pub(super) const C_TRI: f32 = 0.3;

/// Most triangles a leaf made of several binary leaves holds.
pub(super) const MAX_LEAF_TRIS: u32 = 4;

/// The built tree as the programme reads it: a node is named by itself and its place in
/// the tree's pre-order (its first child is the next place, its second child's follows the
/// first child's subtree: `Node::nodes`), where its decision is kept. The boxes and leaf
/// ranges are read from the nodes themselves: no copy of the tree is made.
struct Binary<'t>(std::marker::PhantomData<&'t Node>);

/// A node of the tree and its place in pre-order.
#[derive(Clone, Copy)]
struct At<'t> {
    node: &'t Node,
    index: u32,
}

/// Subtrees of at least this many binary nodes are decided and written on
/// several threads.
pub(super) const PARALLEL_NODES: u32 = 8192;

impl<'t> BinaryTree for Binary<'t> {
    type Id = At<'t>;

    fn kids(&self, n: At<'t>) -> Option<[At<'t>; 2]> {
        let Node::Inner { children, .. } = n.node else {
            return None;
        };
        let [l, r] = &**children;
        Some([
            At {
                node: l,
                index: n.index + 1,
            },
            At {
                node: r,
                index: n.index + 1 + l.nodes(),
            },
        ])
    }

    fn index(&self, n: At<'t>) -> usize {
        n.index as usize
    }

    fn big(&self, n: At<'t>) -> bool {
        n.node.nodes() >= PARALLEL_NODES
    }
}

/// Decides `node`'s subtree bottom-up, each big subtree's halves on two threads, into
/// `decisions` (that subtree's places in pre-order: the node, then its first child's
/// subtree, then its second's); returns the node's entry, which its parent's is made from,
/// and its triangle count.
fn fill<const W: usize>(
    node: &Node,
    decisions: &mut [Decision<W>],
    costs: SahCosts,
) -> (Entry<W>, u32) {
    let area = node.bbox().area();
    let (own, rest) = decisions.split_at_mut(1);
    let (entry, tris) = match node {
        Node::Leaf { count, .. } => (Entry::new(area, *count, None, costs), *count),
        Node::Inner {
            children, nodes, ..
        } => {
            let (left, right) = rest.split_at_mut(children[0].nodes() as usize);
            let go = |c: &Node, d: &mut [Decision<W>]| fill(c, d, costs);
            let ((le, lt), (re, rt)) = if *nodes >= PARALLEL_NODES {
                rayon::join(|| go(&children[0], left), || go(&children[1], right))
            } else {
                (go(&children[0], left), go(&children[1], right))
            };
            let tris = lt + rt;
            (Entry::new(area, tris, Some([&le, &re]), costs), tris)
        }
    };
    own[0] = entry.decision();
    (entry, tris)
}

/// Writes the wide node of inner node `n` at depth `d` into `out[0]` and its subtree after
/// it, in pre-order (`out` is exactly that subtree's part; `index`, the position of
/// `out[0]` in the whole); None when a node would lie deeper than `max_depth`. The big
/// subtrees' parts are written on all threads.
fn emit<const W: usize>(
    tree: &Binary<'_>,
    plan: &Plan<W>,
    n: At<'_>,
    d: usize,
    max_depth: usize,
    index: u32,
    out: &mut [WideNode<W>],
) -> Option<()>
where
    WideNode<W>: bytemuck::Pod,
{
    if d > max_depth {
        return None;
    }
    let (own, mut rest) = out.split_first_mut()?;
    let mut next = index + 1;
    let mut jobs = Vec::with_capacity(W);
    for (k, &(c, leaf)) in plan.children(tree, n).iter().enumerate() {
        own.set_bbox(k, c.node.bbox());
        (own.child[k], own.kind[k]) = match leaf {
            // A wide leaf: one range of leaf order (at most `MAX_LEAF_TRIS` triangles, or
            // a binary leaf).
            true => {
                let (start, end) = c.node.leaf_range();
                (start, end - start)
            }
            false => {
                let size = plan.nodes(tree, c);
                let (part, more) = std::mem::take(&mut rest).split_at_mut(size as usize);
                jobs.push((c, next, part));
                rest = more;
                next += size;
                (next - size, INNER)
            }
        };
    }
    let go = |(c, i, part): (At<'_>, u32, &mut [WideNode<W>])| {
        emit(tree, plan, c, d + 1, max_depth, i, part)
    };
    if tree.big(n) {
        jobs.into_par_iter().map(go).collect()
    } else {
        jobs.into_iter().map(go).collect()
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
    // Zeroed on all threads (`fill` writes every place, each subtree's on its thread).
    let mut decisions: Vec<Decision<W>> = zeroed_on_all_threads(len);
    fill(root, &mut decisions, costs);
    let plan = Plan::<W>::from_decisions(decisions);
    let tree = Binary(std::marker::PhantomData);
    let r = At {
        node: root,
        index: 0,
    };
    let mut out = zeroed_on_all_threads_with_room(plan.nodes(&tree, r) as usize);
    emit(&tree, &plan, r, 0, max_depth, 0, &mut out)?;
    Some(out)
}
