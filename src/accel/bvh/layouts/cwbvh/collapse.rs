//! The shape of the 8-wide tree, decided on lancer's binary SAH tree: its leaves are first
//! split down to one triangle each (median splits along the leaf's longest centroid axis:
//! a binary leaf may hold up to `max_leaf` triangles, a wide leaf at most 3), then the
//! shared SAH programme (`layouts::sah_collapse`, Ylitie, Karras & Laine 2017, §4.1) for
//! eight slots decides for every binary node whether it becomes a wide leaf (≤ 3
//! triangles), a wide internal node, or is spread over its parent's slots.

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Plan, SahCosts};
use crate::accel::bvh::Node;
use crate::accel::LeafTri;
use crate::geometry::Aabb;

use super::{MAX_LEAF_TRIS, WIDTH};

/// SAH cost of a node test and of a triangle test (the paper's values).
const COSTS: SahCosts = SahCosts {
    node: 1.0,
    tri: 0.3,
    max_leaf: MAX_LEAF_TRIS,
};

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
            Node::Leaf {
                bbox, start, count, ..
            } => {
                let mut pos: Vec<u32> = (*start..start + count).collect();
                self.split(&mut pos, tris, bbox)
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

    /// A binary leaf's triangles as a tree of one-triangle leaves (`pos` non-empty). A
    /// triangle's box is its bounds within the leaf's box `within`: all of it, unless a
    /// spatial split gave the leaf only a part of the triangle.
    fn split(&mut self, pos: &mut [u32], tris: &[LeafTri], within: &Aabb) -> u32 {
        let bbox = |p: &u32| {
            let b = tris[*p as usize].triangle().bbox();
            Aabb {
                lo: b.lo.max(within.lo),
                hi: b.hi.min(within.hi),
            }
        };
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
        let l = self.split(lo, tris, within);
        let r = self.split(hi, tris, within);
        self.join(l, r)
    }
}

impl BinaryTree for Binary {
    fn len(&self) -> usize {
        self.boxes.len()
    }

    fn area(&self, n: u32) -> f32 {
        self.boxes[n as usize].area()
    }

    fn kids(&self, n: u32) -> Option<[u32; 2]> {
        let kids = self.kids[n as usize];
        (kids[1] != LEAF).then_some(kids)
    }

    fn tris(&self, n: u32) -> u32 {
        self.tris[n as usize]
    }
}

/// The programme's decisions for the 8-wide tree of `tree`.
pub(crate) fn plan(tree: &Binary) -> Plan<WIDTH> {
    Plan::new(tree, COSTS)
}
