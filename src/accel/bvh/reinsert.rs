//! Reinsertion optimisation (Bittner, Hapala & Havran 2013, "Fast insertion-based
//! optimization of bounding volume hierarchies"): a post-pass on any builder's tree. Each
//! round takes the nodes whose boxes are largest, and for each one removes it (its sibling
//! takes its parent's place), searches the whole tree by branch and bound for the position
//! where putting it back costs least, and moves it there when that lowers the SAH.
//!
//! Leaves move whole, so their boxes and triangle counts never change: the SAH changes only
//! by the inner nodes' areas (each weighs 2·T_cube), which is all the search weighs. Moves
//! that would put a leaf deeper than `max_depth` are not made.
//!
//! The searches run in batches on all threads (as Meister & Bittner 2022 do), each reading
//! the tree as it is before its batch, with the node taken out in thought only; the moves
//! are then made one at a time in candidate order, each only if, with the tree as it is by
//! then, it lowers the SAH exactly. So the result does not depend on the number of threads,
//! and the SAH never rises.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use super::tree::{children_order, leaf, Kids, Node};
use super::{BuildOptions, Bvh};
use crate::geometry::Aabb;

const NONE: u32 = u32::MAX;

/// Rounds of reinsertion; each takes the largest [`SHARE`] of the nodes.
pub const ROUNDS: usize = 3;
/// The share of nodes a round reinserts (the largest boxes first).
pub const SHARE: f64 = 1.0;
/// Candidates whose positions are searched at once, on all threads (Meister & Bittner 2022
/// search many in parallel too); the moves are then made one by one.
const BATCH: usize = 256;

/// The tree in arrays with parent links.
struct Arena {
    bbox: Vec<Aabb>,
    parent: Vec<u32>,
    /// Children of an inner node; `[NONE; 2]` for a leaf.
    kids: Vec<[u32; 2]>,
    /// A leaf's range in the old leaf order.
    range: Vec<(u32, u32)>,
    /// Levels below the node (0 for a leaf).
    height: Vec<u32>,
    root: u32,
}

impl Arena {
    fn of(root: &Node) -> Arena {
        let mut a = Arena {
            bbox: Vec::new(),
            parent: Vec::new(),
            kids: Vec::new(),
            range: Vec::new(),
            height: Vec::new(),
            root: 0,
        };
        a.root = a.add(root, NONE);
        a
    }

    fn add(&mut self, node: &Node, parent: u32) -> u32 {
        let i = self.bbox.len() as u32;
        self.bbox.push(*node.bbox());
        self.parent.push(parent);
        self.kids.push([NONE; 2]);
        self.range.push((0, 0));
        self.height.push(0);
        match node {
            Node::Leaf { start, count, .. } => self.range[i as usize] = (*start, *count),
            Node::Inner { children, .. } => {
                let l = self.add(&children[0], i);
                let r = self.add(&children[1], i);
                self.kids[i as usize] = [l, r];
                self.height[i as usize] = 1 + self.height[l as usize].max(self.height[r as usize]);
            }
        }
        i
    }

    fn is_leaf(&self, n: u32) -> bool {
        self.kids[n as usize][0] == NONE
    }

    fn area(&self, n: u32) -> f32 {
        self.bbox[n as usize].area()
    }

    /// Whether every node is reached exactly once from the root, no deeper than `max_depth`.
    fn is_tree_within(&self, max_depth: u32) -> bool {
        let mut seen = vec![false; self.bbox.len()];
        let mut stack = vec![(self.root, 0u32)];
        while let Some((n, depth)) = stack.pop() {
            if depth > max_depth || std::mem::replace(&mut seen[n as usize], true) {
                return false;
            }
            if !self.is_leaf(n) {
                stack.extend(self.kids[n as usize].map(|c| (c, depth + 1)));
            }
        }
        seen.iter().all(|&s| s)
    }

    /// Recomputes boxes and heights from `n` up to the root.
    fn refit_from(&mut self, mut n: u32) {
        while n != NONE {
            let [l, r] = self.kids[n as usize];
            if l != NONE {
                self.bbox[n as usize] = self.bbox[l as usize].union(self.bbox[r as usize]);
                self.height[n as usize] = 1 + self.height[l as usize].max(self.height[r as usize]);
            }
            n = self.parent[n as usize];
        }
    }

    /// Σ of the areas of the inner nodes above `n` (its ancestors).
    fn ancestors_area(&self, mut n: u32) -> f64 {
        let mut sum = 0.0;
        while self.parent[n as usize] != NONE {
            n = self.parent[n as usize];
            sum += self.area(n) as f64;
        }
        sum
    }

    /// Takes `n` (not the root, nor a child of the root) out: its sibling takes its parent's
    /// place. Returns the freed parent node and the sibling.
    fn remove(&mut self, n: u32) -> (u32, u32) {
        let p = self.parent[n as usize];
        let [a, b] = self.kids[p as usize];
        let s = if a == n { b } else { a };
        let g = self.parent[p as usize];
        let slot = (self.kids[g as usize][1] == p) as usize;
        self.kids[g as usize][slot] = s;
        self.parent[s as usize] = g;
        self.refit_from(g);
        (p, s)
    }

    /// Puts `n` back as the sibling of `x`, under the free node `p` (which takes `x`'s place,
    /// the root's too).
    fn insert(&mut self, n: u32, x: u32, p: u32) {
        let g = self.parent[x as usize];
        if g == NONE {
            self.root = p;
        } else {
            let slot = (self.kids[g as usize][1] == x) as usize;
            self.kids[g as usize][slot] = p;
        }
        self.parent[p as usize] = g;
        self.kids[p as usize] = [x, n];
        self.parent[x as usize] = p;
        self.parent[n as usize] = p;
        self.refit_from(p);
    }

    /// The node whose sibling `n` costs least to become once `n` is taken out, by branch and
    /// bound: putting `n` beside `x` adds a node of area A(x ∪ n) and grows every ancestor
    /// of x to hold n. The tree is read as it would be without `n` — its parent spliced out,
    /// the parent's ancestors shrunk to what remains — without changing it, so that many
    /// searches can run at once. Only positions where every leaf stays within `max_depth`.
    fn propose(&self, n: u32, max_depth: u32) -> u32 {
        let p = self.parent[n as usize];
        let [a, b] = self.kids[p as usize];
        let s = if a == n { b } else { a };
        // The ancestors of p with their boxes once n is gone, the root first: the path's
        // node at depth d is shrunk[d].
        let mut shrunk: Vec<(u32, Aabb)> = Vec::new();
        let (mut below, mut cur) = (p, self.bbox[s as usize]);
        while self.parent[below as usize] != NONE {
            let up = self.parent[below as usize];
            let [l, r] = self.kids[up as usize];
            let other = if l == below { r } else { l };
            cur = cur.union(self.bbox[other as usize]);
            shrunk.push((up, cur));
            below = up;
        }
        shrunk.reverse();
        let on_path = |k: u32, depth: u32| shrunk.get(depth as usize).filter(|e| e.0 == k);
        let bbox = |k: u32, depth: u32| match on_path(k, depth) {
            Some(e) => e.1,
            None => self.bbox[k as usize],
        };
        let nb = self.bbox[n as usize];
        let an = nb.area() as f64;
        let mut best = (NONE, f64::INFINITY);
        let mut heap = BinaryHeap::new();
        heap.push(Candidate {
            induced: 0.0,
            node: self.root,
            depth: 0,
        });
        while let Some(Candidate {
            induced,
            node,
            depth,
        }) = heap.pop()
        {
            // Any position in this subtree adds at least A(n) beyond what is induced here.
            if induced + an >= best.1 {
                break;
            }
            let node_box = bbox(node, depth);
            let cost = induced + node_box.union(nb).area() as f64;
            // n and x both go one level below x's place (heights on the path may be stale
            // by one: the check is then stricter, never looser).
            let below = self.height[n as usize].max(self.height[node as usize]);
            if depth + 1 + below <= max_depth
                && (cost < best.1 || (cost == best.1 && node < best.0))
            {
                best = (node, cost);
            }
            if !self.is_leaf(node) {
                let induced = cost - node_box.area() as f64;
                for c in self.kids[node as usize] {
                    // The parent is spliced out: its place is the sibling's.
                    let c = if c == p { s } else { c };
                    heap.push(Candidate {
                        induced,
                        node: c,
                        depth: depth + 1,
                    });
                }
            }
        }
        best.0
    }

    /// The inner area putting `n` (taken out, its freed parent `p`) beside `x` adds, as
    /// [`Self::propose`] counts it; None where `x` is not in the tree any more (a move since
    /// the proposal put it in n's subtree: its way up passes n or p) or the move would pass
    /// the depth cap.
    fn added_beside(&self, n: u32, p: u32, x: u32, max_depth: u32) -> Option<f64> {
        let nb = self.bbox[n as usize];
        let mut added = self.bbox[x as usize].union(nb).area() as f64;
        let (mut a, mut depth) = (x, 0);
        while self.parent[a as usize] != NONE {
            if a == n || a == p {
                return None;
            }
            a = self.parent[a as usize];
            let box_a = self.bbox[a as usize];
            added += (box_a.union(nb).area() - box_a.area()) as f64;
            depth += 1;
        }
        let below = self.height[n as usize].max(self.height[x as usize]);
        (a == self.root && depth + 1 + below <= max_depth).then_some(added)
    }

    /// Moves `n` beside `x` if that lowers the SAH, as the tree now is; else leaves it where
    /// it was. Whether it moved.
    fn try_move(&mut self, n: u32, x: u32, max_depth: u32) -> bool {
        let p = self.parent[n as usize];
        if p == NONE || self.parent[p as usize] == NONE || x == NONE {
            return false; // an earlier move made it a child of the root
        }
        // Inner area before: the parent and every ancestor above it.
        let before = self.area(p) as f64 + self.ancestors_area(p);
        let was_first = self.kids[p as usize][0] == n;
        let (p, s) = self.remove(n);
        // After removal, the sibling's ancestors hold what the parent's did less n.
        let after_removal = self.ancestors_area(s);
        let added = (x != s && x != p)
            .then(|| self.added_beside(n, p, x, max_depth))
            .flatten();
        match added {
            Some(added) if after_removal + added < before - 1e-6 * before.abs() => {
                self.insert(n, x, p);
                true
            }
            _ => {
                self.insert(n, s, p);
                if was_first {
                    self.kids[p as usize] = [n, s];
                }
                false
            }
        }
    }

    /// The tree as nodes, its leaves in depth-first order, and the leaf order they refer to;
    /// each inner node's axis and child order set by its children's centres (the low side
    /// first on the axis where they lie farthest apart).
    fn into_tree(self, order: &[u32]) -> (Node, Vec<u32>) {
        let mut out = Vec::with_capacity(order.len());
        let root = self.emit(self.root, order, &mut out);
        (root, out)
    }

    fn emit(&self, n: u32, order: &[u32], out: &mut Vec<u32>) -> Node {
        let bbox = self.bbox[n as usize];
        if self.is_leaf(n) {
            let (start, count) = self.range[n as usize];
            let at = out.len();
            out.extend_from_slice(&order[start as usize..(start + count) as usize]);
            return leaf(bbox, at, count as usize);
        }
        let [a, b] = self.kids[n as usize];
        let (axis, swap) = children_order(&self.bbox[a as usize], &self.bbox[b as usize]);
        let (first, second) = if swap { (b, a) } else { (a, b) };
        let kids = Kids::reserve();
        let l = self.emit(first, order, out);
        let r = self.emit(second, order, out);
        kids.inner(bbox, axis, [l, r])
    }
}

/// A search position: its node, the area its ancestors grow by to hold the node being
/// placed, and its depth. The heap pops the smallest induced area first (then the lowest
/// node index: deterministic).
struct Candidate {
    induced: f64,
    node: u32,
    depth: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        // Reversed: BinaryHeap pops the greatest.
        (o.induced.total_cmp(&self.induced)).then(o.node.cmp(&self.node))
    }
}

/// Optimises `bvh` in place by up to three rounds of reinsertion. The SAH never rises; the
/// leaves and their triangles are the same (in a new leaf order).
pub fn optimize(bvh: &mut Bvh, opts: &BuildOptions) {
    if matches!(bvh.root, Node::Leaf { .. }) {
        return;
    }
    let max_depth = opts.max_depth.min(super::MAX_DEPTH) as u32;
    let mut arena = Arena::of(&bvh.root);
    let len = arena.bbox.len();
    for _ in 0..ROUNDS {
        // The largest boxes first, ties by index; the root and its children stay.
        let mut candidates: Vec<u32> = (0..len as u32)
            .filter(|&n| {
                let p = arena.parent[n as usize];
                p != NONE && arena.parent[p as usize] != NONE
            })
            .collect();
        candidates.sort_by(|&a, &b| arena.area(b).total_cmp(&arena.area(a)).then(a.cmp(&b)));
        candidates.truncate(((len as f64 * SHARE).ceil() as usize).max(1));
        let mut moved = 0;
        for batch in candidates.chunks(BATCH) {
            // Where each candidate would go, searched on all threads in the tree as it is
            // before the batch; then the moves made one by one, each checked exactly.
            let proposals: Vec<u32> = if opts.parallel {
                batch
                    .par_iter()
                    .map(|&n| arena.propose(n, max_depth))
                    .collect()
            } else {
                batch.iter().map(|&n| arena.propose(n, max_depth)).collect()
            };
            for (&n, &x) in batch.iter().zip(&proposals) {
                moved += arena.try_move(n, x, max_depth) as usize;
            }
        }
        log::debug!("reinsertion: {moved} nodes moved");
        if moved == 0 {
            break;
        }
    }
    // A safety net before the recursive conversion: the moves keep the arena a tree within
    // the depth cap; were that ever broken, the built tree is kept rather than recursing
    // into a cycle.
    if !arena.is_tree_within(max_depth) {
        log::error!("reinsertion broke the tree (a bug): the tree is kept as built");
        return;
    }
    let (root, order) = arena.into_tree(&bvh.order);
    bvh.root = root;
    bvh.order = order;
}
