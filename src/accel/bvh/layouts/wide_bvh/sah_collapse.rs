//! The wide layouts' collapse: the shared SAH programme (`layouts::sah_collapse`) for W slots on
//! lancer's binary tree as built, where a wide leaf is a binary subtree of at most
//! `MAX_LEAF_TRIS` triangles (its leaves' ranges are contiguous in leaf order, so it is one
//! range) or a binary leaf of any size. `collapse` gives up (and the greedy collapse is used)
//! where the tree would be deeper than the stack holds.

use std::sync::atomic::{AtomicU32, Ordering};

use rayon::prelude::*;

use crate::accel::bvh::layouts::sah_collapse::{
    zeroed_counts, BinaryTree, Decision, Entry, Plan, SahCosts,
};
use crate::accel::bvh::Node;
use crate::geometry::Aabb;
use crate::util::zeroed_on_all_threads;

use super::{WideNode, INNER};

/// SAH cost of a wide node's visit and of a triangle test.
pub(super) const C_NODE: f32 = 1.0;
pub(super) const C_TRI: f32 = 0.3;

/// Most triangles a leaf made of several binary leaves holds.
pub(super) const MAX_LEAF_TRIS: u32 = 4;

/// The binary tree in arrays, children before parents (post-order, the root last): what
/// the wide nodes are written from, read in place of the tree's boxed nodes.
struct Arena {
    boxes: Vec<Aabb>,
    /// The first leaf-order position of the node's triangles.
    first: Vec<u32>,
    /// The two children's indices; `NO_KIDS` for a leaf (an inner node's two differ).
    kids: Vec<[u32; 2]>,
    tris: Vec<u32>,
}

/// The `kids` of a leaf.
const NO_KIDS: [u32; 2] = [0, 0];

/// One node's entries in the arena (and its decision in the plan).
struct Own<'s, const W: usize> {
    bbox: &'s mut Aabb,
    first: &'s mut u32,
    kids: &'s mut [u32; 2],
    tris: &'s mut u32,
    decision: &'s mut Decision<W>,
}

/// A subtree's share of the arena and of the plan: its nodes' slots, children before
/// parents, the subtree's root last.
struct Share<'s, const W: usize> {
    boxes: &'s mut [Aabb],
    first: &'s mut [u32],
    kids: &'s mut [[u32; 2]],
    tris: &'s mut [u32],
    decisions: &'s mut [Decision<W>],
}

impl<'s, const W: usize> Share<'s, W> {
    /// The first `at` slots, the rest before the last, and the last slot's entries.
    fn split(self, at: usize) -> (Self, Self, Own<'s, W>) {
        let last = self.boxes.len() - 1;
        let (b, b_own) = self.boxes.split_at_mut(last);
        let (f, f_own) = self.first.split_at_mut(last);
        let (k, k_own) = self.kids.split_at_mut(last);
        let (t, t_own) = self.tris.split_at_mut(last);
        let (e, e_own) = self.decisions.split_at_mut(last);
        let (b0, b1) = b.split_at_mut(at);
        let (f0, f1) = f.split_at_mut(at);
        let (k0, k1) = k.split_at_mut(at);
        let (t0, t1) = t.split_at_mut(at);
        let (e0, e1) = e.split_at_mut(at);
        (
            Share {
                boxes: b0,
                first: f0,
                kids: k0,
                tris: t0,
                decisions: e0,
            },
            Share {
                boxes: b1,
                first: f1,
                kids: k1,
                tris: t1,
                decisions: e1,
            },
            Own {
                bbox: &mut b_own[0],
                first: &mut f_own[0],
                kids: &mut k_own[0],
                tris: &mut t_own[0],
                decision: &mut e_own[0],
            },
        )
    }
}

/// Subtrees of at least this many nodes fill their two halves on two threads.
const PARALLEL_NODES: u32 = 8192;

/// Fills `share` with `node`'s subtree in post-order, its first slot at index `base`, and
/// the programme's decisions bottom-up (each subtree on its own thread where big); returns
/// the entry of `node`, which its parent's is made from.
fn fill<const W: usize>(node: &Node, base: u32, share: Share<'_, W>, costs: SahCosts) -> Entry<W> {
    let bbox = *node.bbox();
    let area = bbox.area();
    let Node::Inner { children, .. } = node else {
        let (start, count) = match node {
            Node::Leaf { start, count, .. } => (*start, *count),
            Node::Inner { .. } => (0, 0),
        };
        let entry = Entry::new(area, count, None, costs);
        share.boxes[0] = bbox;
        share.first[0] = start;
        share.kids[0] = NO_KIDS;
        share.tris[0] = count;
        share.decisions[0] = entry.decision();
        return entry;
    };
    let nl = children[0].nodes();
    let (left, right, own) = share.split(nl as usize);
    let (l, r) = (nl as usize - 1, right.boxes.len() - 1);
    let go = |c: &Node, b: u32, s: Share<'_, W>| fill(c, b, s, costs);
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
    *own.bbox = bbox;
    *own.first = left.first[0];
    *own.kids = [base + l as u32, base + nl + r as u32];
    *own.tris = tris;
    *own.decision = entry.decision();
    entry
}

fn reborrow<'t, const W: usize>(s: &'t mut Share<'_, W>) -> Share<'t, W> {
    Share {
        boxes: s.boxes,
        first: s.first,
        kids: s.kids,
        tris: s.tris,
        decisions: s.decisions,
    }
}

impl BinaryTree for Arena {
    fn kids(&self, n: u32) -> Option<[u32; 2]> {
        let kids = self.kids[n as usize];
        (kids != NO_KIDS).then_some(kids)
    }

    fn tris(&self, n: u32) -> u32 {
        self.tris[n as usize]
    }
}

/// Subtrees of at least this many triangles are written on several threads.
const PARALLEL_TRIS: u32 = 16384;

/// Writes the wide node of inner node `n` at depth `d` into `out[0]` and its subtree after
/// it, in pre-order (`out` is exactly that subtree's part; `index`, the position of
/// `out[0]` in the whole); None when a node would lie deeper than `max_depth`. The big
/// subtrees' parts are written on all threads.
#[allow(clippy::too_many_arguments)] // the tree, its plan and counts, and where to write
fn emit<const W: usize>(
    arena: &Arena,
    plan: &Plan<W>,
    counts: &[AtomicU32],
    n: u32,
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
    for (k, &(c, leaf)) in plan.children(arena, n).iter().enumerate() {
        own.set_bbox(k, &arena.boxes[c as usize]);
        (own.child[k], own.kind[k]) = match leaf {
            true => (arena.first[c as usize], arena.tris[c as usize]),
            false => {
                let size = counts[c as usize].load(Ordering::Relaxed);
                let (part, more) = std::mem::take(&mut rest).split_at_mut(size as usize);
                jobs.push((c, next, part));
                rest = more;
                next += size;
                (next - size, INNER)
            }
        };
    }
    let go = |(c, i, part): (u32, u32, &mut [WideNode<W>])| {
        emit(arena, plan, counts, c, d + 1, max_depth, i, part)
    };
    if arena.tris[n as usize] >= PARALLEL_TRIS {
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
    // Zeroed on all threads (`fill` writes every slot, each subtree's on its thread).
    let mut arena = Arena {
        boxes: zeroed_on_all_threads(len),
        first: zeroed_on_all_threads(len),
        kids: zeroed_on_all_threads(len),
        tris: zeroed_on_all_threads(len),
    };
    let mut decisions: Vec<Decision<W>> = zeroed_on_all_threads(len);
    let share = Share {
        boxes: &mut arena.boxes,
        first: &mut arena.first,
        kids: &mut arena.kids,
        tris: &mut arena.tris,
        decisions: &mut decisions,
    };
    fill(root, 0, share, costs);
    let plan = Plan::<W>::from_decisions(decisions);
    let r = len as u32 - 1;
    let counts = zeroed_counts(len);
    let mut out = zeroed_on_all_threads(plan.count(&arena, r, &counts) as usize);
    emit(&arena, &plan, &counts, r, 0, max_depth, 0, &mut out)?;
    Some(out)
}
