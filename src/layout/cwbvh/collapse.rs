//! The shape of the 8-wide tree, decided on lancer's binary SAH tree: its leaves are first
//! split down to one triangle each (median splits along the leaf's longest centroid axis:
//! a binary leaf may hold up to `max_leaf` triangles, a wide leaf at most 3), then the
//! SAH-cost dynamic programme of Ylitie, Karras & Laine 2017 (§4.1) decides for every
//! binary node whether it becomes a wide leaf (≤ 3 triangles), a wide internal node, or is
//! spread over its parent's slots. cost(n, i) is the cheapest way to hold n's subtree in at
//! most i slots:
//!
//! ```text
//! cost(n, 1) = min(leaf: c_prim·A(n)·tris(n) if tris(n) ≤ 3,  internal: c_node·A(n) + spread(n, 8))
//! cost(n, i) = min(cost(n, i − 1), spread(n, i))            for i = 2..=8
//! spread(n, j) = min over 0 < k < j of cost(left, k) + cost(right, j − k)
//! ```
//!
//! Every wide internal child is a strict binary descendant, so the wide tree is never
//! deeper than the split binary tree.

use crate::accel::bvh::Node;
use crate::geometry::Aabb;
use crate::layout::LeafTri;

use super::{MAX_LEAF_TRIS, WIDTH};

/// SAH cost of a node test and of a triangle test (the paper's values).
const C_NODE: f32 = 1.0;
const C_PRIM: f32 = 0.3;

/// `kids[n][1]` of a leaf.
const LEAF: u32 = u32::MAX;

/// A binary tree whose leaves hold one triangle each, children before parents.
pub(crate) struct Binary {
    boxes: Vec<Aabb>,
    /// Inner: the two children. Leaf: [position in the gathered triangles, LEAF].
    kids: Vec<[u32; 2]>,
    /// Triangles beneath.
    tris: Vec<u32>,
}

impl Binary {
    /// Splits `root`'s leaves (triangles `tris` in leaf order, at least one).
    pub fn new(root: &Node, tris: &[LeafTri]) -> Binary {
        let mut t = Binary {
            boxes: Vec::new(),
            kids: Vec::new(),
            tris: Vec::new(),
        };
        t.add(root, tris);
        t
    }

    /// The root (the last node added).
    pub fn root(&self) -> u32 {
        self.boxes.len() as u32 - 1
    }

    /// The exact box of `n`'s triangles.
    pub fn bbox(&self, n: u32) -> &Aabb {
        &self.boxes[n as usize]
    }

    fn is_leaf(&self, n: u32) -> bool {
        self.kids[n as usize][1] == LEAF
    }

    /// The gathered positions of the triangles beneath `n`, left to right.
    pub fn positions(&self, n: u32, out: &mut Vec<u32>) {
        let [a, b] = self.kids[n as usize];
        if b == LEAF {
            out.push(a);
        } else {
            self.positions(a, out);
            self.positions(b, out);
        }
    }

    fn push(&mut self, bbox: Aabb, kids: [u32; 2], tris: u32) -> u32 {
        self.boxes.push(bbox);
        self.kids.push(kids);
        self.tris.push(tris);
        self.root()
    }

    fn add(&mut self, node: &Node, tris: &[LeafTri]) -> u32 {
        match node {
            Node::Leaf { start, count, .. } => {
                let mut pos: Vec<u32> = (*start..start + count).collect();
                self.split(&mut pos, tris)
            }
            Node::Inner { children, .. } => {
                let l = self.add(&children[0], tris);
                let r = self.add(&children[1], tris);
                self.join(l, r)
            }
        }
    }

    fn join(&mut self, l: u32, r: u32) -> u32 {
        let bbox = self.bbox(l).union(*self.bbox(r));
        let n = self.tris[l as usize] + self.tris[r as usize];
        self.push(bbox, [l, r], n)
    }

    /// A binary leaf's triangles as a tree of one-triangle leaves (`pos` non-empty).
    fn split(&mut self, pos: &mut [u32], tris: &[LeafTri]) -> u32 {
        let bbox = |p: &u32| tris[*p as usize].triangle().bbox();
        if let [p] = pos {
            let b = bbox(p);
            return self.push(b, [*p, LEAF], 1);
        }
        let centres = Aabb::from_points(&pos.iter().map(|p| bbox(p).center()).collect::<Vec<_>>());
        let axis = centres.longest_axis();
        pos.sort_by(|a, b| {
            let (ca, cb) = (bbox(a).center()[axis], bbox(b).center()[axis]);
            ca.total_cmp(&cb).then(a.cmp(b))
        });
        let (lo, hi) = pos.split_at_mut(pos.len() / 2);
        let l = self.split(lo, tris);
        let r = self.split(hi, tris);
        self.join(l, r)
    }
}

/// The DP's decisions for every binary node.
pub(crate) struct Plan {
    /// cost(n, i + 1).
    cost: Vec<[f32; WIDTH]>,
    /// `[0]`: the left share k of spread(n, 8) (an internal node's children); `[i − 1]`
    /// for i ≥ 2: the k of spread(n, i) when it beats cost(n, i − 1), else 0.
    split: Vec<[u8; WIDTH]>,
    /// Whether cost(n, 1) is the leaf's.
    leaf: Vec<bool>,
}

impl Plan {
    /// Runs the DP bottom-up (children precede parents in `tree`).
    pub fn new(tree: &Binary) -> Plan {
        let len = tree.boxes.len();
        let mut plan = Plan {
            cost: Vec::with_capacity(len),
            split: Vec::with_capacity(len),
            leaf: Vec::with_capacity(len),
        };
        for n in 0..len {
            let area = tree.boxes[n].area();
            let [l, r] = tree.kids[n];
            if r == LEAF {
                plan.cost.push([C_PRIM * area; WIDTH]);
                plan.split.push([0; WIDTH]);
                plan.leaf.push(true);
                continue;
            }
            let (cl, cr) = (plan.cost[l as usize], plan.cost[r as usize]);
            let spread = |j: usize| {
                let mut best = (f32::INFINITY, 0u8);
                for k in 1..j {
                    let c = cl[k - 1] + cr[j - k - 1];
                    if c < best.0 {
                        best = (c, k as u8);
                    }
                }
                best
            };
            let mut cost = [0.0; WIDTH];
            let mut split = [0u8; WIDTH];
            let (c8, k8) = spread(WIDTH);
            let internal = C_NODE * area + c8;
            let n_tris = tree.tris[n];
            let leaf = n_tris <= MAX_LEAF_TRIS && C_PRIM * area * n_tris as f32 <= internal;
            cost[0] = if leaf {
                C_PRIM * area * n_tris as f32
            } else {
                internal
            };
            split[0] = k8;
            for i in 2..=WIDTH {
                let (c, k) = spread(i);
                if c < cost[i - 2] {
                    (cost[i - 1], split[i - 1]) = (c, k);
                } else {
                    cost[i - 1] = cost[i - 2];
                }
            }
            plan.cost.push(cost);
            plan.split.push(split);
            plan.leaf.push(leaf);
        }
        plan
    }

    /// The children of the wide internal node made from `n`: (binary node, is a wide
    /// leaf), at most [`WIDTH`]. A binary leaf (a one-triangle tree) is its own only child.
    pub fn children(&self, tree: &Binary, n: u32) -> Vec<(u32, bool)> {
        let mut out = Vec::with_capacity(WIDTH);
        if tree.is_leaf(n) {
            out.push((n, true));
        } else {
            let [l, r] = tree.kids[n as usize];
            let k = self.split[n as usize][0] as usize;
            self.collect(tree, l, k, &mut out);
            self.collect(tree, r, WIDTH - k, &mut out);
        }
        out
    }

    /// The at most `slots` subtrees that hold `n`'s subtree.
    fn collect(&self, tree: &Binary, n: u32, slots: usize, out: &mut Vec<(u32, bool)>) {
        let split = &self.split[n as usize];
        let mut i = slots;
        while i > 1 && split[i - 1] == 0 {
            i -= 1;
        }
        if i <= 1 || tree.is_leaf(n) {
            out.push((n, self.leaf[n as usize]));
            return;
        }
        let [l, r] = tree.kids[n as usize];
        let k = split[i - 1] as usize;
        self.collect(tree, l, k, out);
        self.collect(tree, r, i - k, out);
    }
}
