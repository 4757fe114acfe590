//! The shape of the 8-wide tree, decided on lancer's binary SAH tree: its leaves are first
//! split down to one triangle each (median splits along the leaf's longest centroid axis:
//! a binary leaf may hold up to `max_leaf` triangles, a wide leaf at most 3), then the
//! shared SAH programme (`layouts::sah_collapse`, Ylitie, Karras & Laine 2017, §4.1) for
//! eight slots decides for every binary node whether it becomes a wide leaf (≤ 3
//! triangles), a wide internal node, or is spread over its parent's slots. The
//! one-triangle leaves are not stored (their box, count and decision follow from the
//! triangle), which halves the memory of the programme's tree.

use glam::Vec3;

use crate::accel::bvh::layouts::sah_collapse::{BinaryTree, Decision, Entry, Plan, SahCosts};
use crate::accel::bvh::Node;
use crate::geometry::Aabb;
use crate::geometry::Triangle;
use crate::util::zeroed_on_all_threads;

use super::{MAX_LEAF_TRIS, WIDTH};

/// SAH cost of a node test and of a triangle test (the paper's values).
const COSTS: SahCosts = SahCosts {
    node: 1.0,
    tri: 0.3,
    max_leaf: MAX_LEAF_TRIS,
};

/// Tag of a one-triangle leaf's id: `LEAF | its leaf-order position`; untagged ids are
/// inner nodes. References number fewer than 2³¹ (mesh sizes are checked far below).
const LEAF: u32 = 1 << 31;

/// A built tree's triangles in leaf order, read where they lie in the mesh.
pub(crate) struct LeafOrder<'a> {
    /// Original triangle index by leaf-order position ([`Bvh::order`](crate::accel::bvh::Bvh::order)).
    pub order: &'a [u32],
    /// The mesh's triangles.
    pub triangles: &'a [Triangle],
}

impl LeafOrder<'_> {
    /// The triangle at leaf-order position `p`.
    pub fn triangle(&self, p: u32) -> &Triangle {
        &self.triangles[self.order[p as usize] as usize]
    }
}

/// A binary tree whose leaves hold one triangle each. Its inner nodes are stored, children
/// before parents; a node's id is its index, or `LEAF | position` for a leaf.
pub(crate) struct Binary<'a> {
    boxes: Vec<Aabb>,
    /// The two children's ids.
    kids: Vec<[u32; 2]>,
    /// Triangles beneath.
    tris: Vec<u32>,
    /// The leaves whose box is not their triangle's whole box (a spatial split gave their
    /// binary leaf a part of the triangle), by position, in position order.
    clipped: Vec<(u32, Aabb)>,
    root: u32,
    leaves: &'a LeafOrder<'a>,
}

/// Subtrees of at least this many triangles are made on two threads, and written on several.
const PARALLEL_TRIS: u32 = 16384;

/// A subtree's share of the arrays: its inner nodes' slots, children before parents, the
/// subtree's root last; `base` is the index of its first slot. `clipped` collects the
/// subtree's clipped leaves.
struct Share<'s, const W: usize> {
    base: u32,
    boxes: &'s mut [Aabb],
    kids: &'s mut [[u32; 2]],
    tris: &'s mut [u32],
    decisions: &'s mut [Decision<W>],
    clipped: Vec<(u32, Aabb)>,
}

impl<'s, const W: usize> Share<'s, W> {
    /// The first `at` slots and the rest before the last (the subtree root's own).
    fn split(self, at: usize) -> (Share<'s, W>, Share<'s, W>, Share<'s, W>) {
        let last = self.boxes.len() - 1;
        let (b, b_own) = self.boxes.split_at_mut(last);
        let (k, k_own) = self.kids.split_at_mut(last);
        let (t, t_own) = self.tris.split_at_mut(last);
        let (e, e_own) = self.decisions.split_at_mut(last);
        let (b0, b1) = b.split_at_mut(at);
        let (k0, k1) = k.split_at_mut(at);
        let (t0, t1) = t.split_at_mut(at);
        let (e0, e1) = e.split_at_mut(at);
        let base = self.base;
        (
            Share {
                base,
                boxes: b0,
                kids: k0,
                tris: t0,
                decisions: e0,
                clipped: Vec::new(),
            },
            Share {
                base: base + at as u32,
                boxes: b1,
                kids: k1,
                tris: t1,
                decisions: e1,
                clipped: Vec::new(),
            },
            Share {
                base: base + last as u32,
                boxes: b_own,
                kids: k_own,
                tris: t_own,
                decisions: e_own,
                clipped: self.clipped,
            },
        )
    }

    /// Puts an inner node and its programme entry in local slot `i`; returns its id.
    fn put(&mut self, i: usize, bbox: Aabb, kids: [u32; 2], tris: u32, entry: Entry<W>) -> Made<W> {
        self.boxes[i] = bbox;
        self.kids[i] = kids;
        self.tris[i] = tris;
        self.decisions[i] = entry.decision();
        (self.base + i as u32, bbox, entry)
    }

    /// Triangles beneath the node `id` of this share.
    fn tris_of(&self, id: u32) -> u32 {
        if id & LEAF != 0 {
            1
        } else {
            self.tris[(id - self.base) as usize]
        }
    }
}

/// A subtree's root as made: its id, box and programme entry.
type Made<const W: usize> = (u32, Aabb, Entry<W>);

impl<'a> Binary<'a> {
    /// Splits `root`'s leaves (triangles `tris` in leaf order, at least one), and runs the
    /// SAH programme for the wide tree on it, the big subtrees on all threads.
    pub fn new(root: &Node, tris: &'a LeafOrder<'a>) -> (Binary<'a>, Plan<WIDTH>) {
        let (start, end) = root.leaf_range();
        debug_assert!(end < LEAF, "references beyond the leaf tag");
        // T triangles, T − 1 inner nodes.
        let len = (end - start) as usize - 1;
        // Every slot is written below, each subtree's on its thread.
        let mut t = Binary {
            boxes: zeroed_on_all_threads(len),
            kids: zeroed_on_all_threads(len),
            tris: zeroed_on_all_threads(len),
            clipped: Vec::new(),
            root: 0,
            leaves: tris,
        };
        let mut decisions: Vec<Decision<WIDTH>> = zeroed_on_all_threads(len);
        let share = Share {
            base: 0,
            boxes: &mut t.boxes,
            kids: &mut t.kids,
            tris: &mut t.tris,
            decisions: &mut decisions,
            clipped: Vec::new(),
        };
        let ((root, ..), clipped) = fill(root, (start, end), share, tris);
        t.root = root;
        t.clipped = clipped;
        t.clipped.sort_unstable_by_key(|&(p, _)| p);
        (t, Plan::from_decisions(decisions))
    }

    /// The root: the last inner node, or the only leaf.
    pub fn root(&self) -> u32 {
        self.root
    }

    /// Triangles beneath node n.
    pub fn tris(&self, n: u32) -> u32 {
        if n & LEAF != 0 {
            1
        } else {
            self.tris[n as usize]
        }
    }

    /// The exact box of `n`'s triangles.
    pub fn bbox(&self, n: u32) -> Aabb {
        if n & LEAF == 0 {
            return self.boxes[n as usize];
        }
        let p = n & !LEAF;
        match self.clipped.binary_search_by_key(&p, |&(q, _)| q) {
            Ok(i) => self.clipped[i].1,
            Err(_) => self.leaves.triangle(p).bbox(),
        }
    }

    /// Writes the leaf-order positions of the triangles beneath `n`, left to right, at the
    /// start of `out` (room for them all); returns how many.
    pub fn positions(&self, n: u32, out: &mut [u32]) -> u32 {
        match self.kids(n) {
            None => {
                out[0] = n & !LEAF;
                1
            }
            Some([a, b]) => {
                let k = self.positions(a, out);
                k + self.positions(b, &mut out[k as usize..])
            }
        }
    }
}

/// Fills `share` with `node`'s subtree (leaf-order positions `range`): the two halves of a
/// big subtree on two threads, a small one in order. Returns the subtree's root and its
/// clipped leaves.
fn fill<'s>(
    node: &Node,
    range: (u32, u32),
    share: Share<'s, WIDTH>,
    tris: &LeafOrder,
) -> (Made<WIDTH>, Vec<(u32, Aabb)>) {
    match node {
        Node::Inner { children, .. } if range.1 - range.0 >= PARALLEL_TRIS => {
            let mid = children[0].leaf_range().1;
            let (left, right, mut own) = share.split((mid - range.0) as usize - 1);
            let ((l, mut clipped), (r, more)) = rayon::join(
                || fill(&children[0], (range.0, mid), left, tris),
                || fill(&children[1], (mid, range.1), right, tris),
            );
            clipped.extend(more);
            clipped.append(&mut own.clipped);
            (own.join(0, l, r, range.1 - range.0), clipped)
        }
        _ => {
            let mut share = share;
            let mut cursor = 0;
            let root = add(node, &mut share, &mut cursor, tris, &mut Vec::new());
            debug_assert_eq!(cursor, share.boxes.len());
            (root, share.clipped)
        }
    }
}

impl Share<'_, WIDTH> {
    /// Puts the parent of `l` and `r` (of `tris` triangles) in local slot `i`.
    fn join(&mut self, i: usize, l: Made<WIDTH>, r: Made<WIDTH>, tris: u32) -> Made<WIDTH> {
        let bbox = l.1.union(r.1);
        let entry = Entry::new(bbox.area(), tris, Some([&l.2, &r.2]), COSTS);
        self.put(i, bbox, [l.0, r.0], tris, entry)
    }

    /// A one-triangle leaf: nothing stored but a clipped box.
    fn leaf(&mut self, r: &Ref) -> Made<WIDTH> {
        if r.clipped {
            self.clipped.push((r.p, r.bbox));
        }
        (
            LEAF | r.p,
            r.bbox,
            Entry::new(r.bbox.area(), 1, None, COSTS),
        )
    }
}

/// Adds `node`'s subtree at the share's `cursor`, in post-order; returns its root.
fn add(
    node: &Node,
    share: &mut Share<'_, WIDTH>,
    cursor: &mut usize,
    tris: &LeafOrder,
    refs: &mut Vec<Ref>,
) -> Made<WIDTH> {
    match node {
        Node::Leaf {
            bbox, start, count, ..
        } => {
            // A triangle's box is its bounds within the leaf's box: all of it, unless a
            // spatial split gave the leaf only a part of the triangle (then it is kept).
            let at = |p: u32| {
                // Bounds of −0 made +0 (as the builders' references make them, so that a
                // leaf's bound of +0 does not read as a clip of the triangle's −0).
                let plus_zero = |b: Aabb| Aabb {
                    lo: b.lo + Vec3::ZERO,
                    hi: b.hi + Vec3::ZERO,
                };
                let whole = plus_zero(tris.triangle(p).bbox());
                let within = plus_zero(Aabb {
                    lo: whole.lo.max(bbox.lo),
                    hi: whole.hi.min(bbox.hi),
                });
                let same = |a: Vec3, b: Vec3| (0..3).all(|k| a[k].to_bits() == b[k].to_bits());
                Ref {
                    p,
                    bbox: within,
                    clipped: !(same(within.lo, whole.lo) && same(within.hi, whole.hi)),
                }
            };
            // One buffer for every leaf of the subtree (a leaf is made for every few
            // triangles).
            refs.clear();
            refs.extend((*start..start + count).map(at));
            split(refs, share, cursor)
        }
        Node::Inner { children, .. } => {
            let l = add(&children[0], share, cursor, tris, refs);
            let r = add(&children[1], share, cursor, tris, refs);
            next(share, cursor, l, r)
        }
    }
}

/// Joins `l` and `r` at the cursor.
fn next(
    share: &mut Share<'_, WIDTH>,
    cursor: &mut usize,
    l: Made<WIDTH>,
    r: Made<WIDTH>,
) -> Made<WIDTH> {
    let n = share.tris_of(l.0) + share.tris_of(r.0);
    let i = *cursor;
    *cursor += 1;
    share.join(i, l, r, n)
}

/// A triangle of a binary leaf: its leaf-order position, its box within the leaf, and
/// whether that is less than the triangle's whole box.
#[derive(Clone, Copy)]
struct Ref {
    p: u32,
    bbox: Aabb,
    clipped: bool,
}

/// A binary leaf's triangles (at least one) as a tree of one-triangle leaves: median
/// splits on the longest axis of the box centres.
fn split(refs: &mut [Ref], share: &mut Share<'_, WIDTH>, cursor: &mut usize) -> Made<WIDTH> {
    if let [r] = refs {
        return share.leaf(r);
    }
    let centres = refs
        .iter()
        .fold(Aabb::EMPTY, |b, r| b.grow(r.bbox.center()));
    let axis = centres.longest_axis();
    refs.sort_by(|a, b| {
        let (ca, cb) = (a.bbox.center()[axis], b.bbox.center()[axis]);
        ca.total_cmp(&cb).then(a.p.cmp(&b.p))
    });
    let (lo, hi) = refs.split_at_mut(refs.len() / 2);
    let l = split(lo, share, cursor);
    let r = split(hi, share, cursor);
    next(share, cursor, l, r)
}

impl BinaryTree for Binary<'_> {
    type Id = u32;

    fn kids(&self, n: u32) -> Option<[u32; 2]> {
        (n & LEAF == 0).then(|| self.kids[n as usize])
    }

    /// Inner nodes by their number; a leaf (its position with the `LEAF` bit) lies past
    /// every plan's and count's index.
    fn index(&self, n: u32) -> usize {
        n as usize
    }

    fn big(&self, n: u32) -> bool {
        self.tris(n) >= PARALLEL_TRIS
    }
}
