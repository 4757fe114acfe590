//! The BIH build with the global heuristic of Wächter & Keller 2006: every node carries a
//! candidate box, a cell of the global grid-like subdivision of the scene's box (not the
//! box of its triangles). The candidate is split in the middle of its longest axis and the
//! triangles are classified by their box centres; when one half would be empty, no split
//! is made and the candidate shrinks to the half that keeps the triangles, as in the paper.
//! Otherwise the node gets the clip planes of its children's actual extents (the left
//! child's maximum, the right child's minimum) and each child recurses on its half.
//!
//! Empty space: when the last empty half before a split held no part of any triangle
//! either, a one-sided node above the split cuts off the space beyond the triangles (the
//! encoding of Sunflow's BIH, the implementation most BIHs follow) — unless an ancestor's
//! plane already does. Without it, a ray crossing a node's box beside its triangles would
//! test them all: on the bunny the BIH then tests 12× the BVH's triangles per ray.
//!
//! A node of at most `max_leaf` triangles, or at the depth cap, is a leaf. Where a split
//! would leave a child too deep to reach such leaves under the cap, or the centres cannot
//! be separated by halving (identical, or within an ulp), the node is split at the object
//! median of the centres on their longest axis instead; so no input deepens the tree past
//! the traversal's stack and, when the cap allows it (it does for every mesh under 2⁶⁰
//! triangles), no leaf holds more than `max_leaf` triangles.
//!
//! Halving is done on the centres' bounds, not on the triangles: a candidate half that
//! holds no centre is recognised in O(1), and the O(n) partition runs once per node.

use glam::Vec3;
use rayon::prelude::*;

use super::node::BihNode;
use crate::accel::LeafTri;
use crate::geometry::Aabb;
use crate::mesh::Mesh;

/// Nodes with at least this many triangles build their two subtrees in parallel.
const PARALLEL_MIN: usize = 8192;

/// Halvings of a candidate box tried before a node is split at the median (f32 allows
/// fewer than 300 per axis before the halves stop shrinking; this only bounds the loop).
const MAX_HALVINGS: usize = 1024;

/// A triangle while building: its box and original index.
#[derive(Clone, Copy, Debug)]
pub(super) struct Prim {
    lo: Vec3,
    hi: Vec3,
    index: u32,
}

impl Prim {
    /// The box centre on axis `k` (the classification key; the centres' bounds use it too).
    #[inline(always)]
    fn centre(&self, k: usize) -> f32 {
        0.5 * (self.lo[k] + self.hi[k])
    }
}

/// Bounds of the prims' boxes and of their centres.
fn bounds(prims: &[Prim]) -> (Aabb, Aabb) {
    let (mut b, mut c) = (Aabb::EMPTY, Aabb::EMPTY);
    for p in prims {
        b.lo = b.lo.min(p.lo);
        b.hi = b.hi.max(p.hi);
        let centre = Vec3::new(p.centre(0), p.centre(1), p.centre(2));
        c = c.grow(centre);
    }
    (b, c)
}

/// Levels below a node of `n` triangles needed to reach leaves of `max_leaf` by halving.
fn levels_needed(n: usize, max_leaf: usize) -> usize {
    let leaves = n.div_ceil(max_leaf);
    leaves.next_power_of_two().trailing_zeros() as usize
}

/// The longest axis of a box (the first of equals).
fn longest_axis(b: &Aabb) -> usize {
    let e = b.extent();
    if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    }
}

/// A node being built: its triangles' boxes (`objects`), the bounds of their centres, its
/// candidate box, and `clip`, the region its ancestors' planes (and the root box) already
/// confine a ray to.
#[derive(Clone, Copy, Debug)]
struct Cell {
    objects: Aabb,
    centres: Aabb,
    candidate: Aabb,
    clip: Aabb,
}

/// Empty space a one-sided node cuts off: on `axis`, everything beyond `plane` on the side
/// away from the triangles (`keep_left`: they end at `plane`; else they start there).
#[derive(Clone, Copy, Debug)]
struct Cut {
    axis: usize,
    plane: f32,
    keep_left: bool,
}

impl Cut {
    /// The region a ray is confined to below the cut.
    fn clip(&self, mut region: Aabb) -> Aabb {
        if self.keep_left {
            region.hi[self.axis] = self.plane;
        } else {
            region.lo[self.axis] = self.plane;
        }
        region
    }
}

/// How a node splits: an empty-space cut first (or none), the axis, the left child's size,
/// and the children's cells.
struct Split {
    cut: Option<Cut>,
    axis: usize,
    left_len: usize,
    left: Cell,
    right: Cell,
    median: bool,
}

/// The built arrays and their shape.
pub(super) struct Built {
    pub nodes: Vec<BihNode>,
    pub tris: Vec<LeafTri>,
    pub bounds: Aabb,
    pub max_depth: usize,
    pub largest_leaf: usize,
    pub median_splits: usize,
    pub cuts: usize,
}

/// Shape counters of one subtree.
#[derive(Clone, Copy, Default)]
struct Shape {
    max_depth: usize,
    largest_leaf: usize,
    median_splits: usize,
    cuts: usize,
}

impl Shape {
    fn merge(self, o: Shape) -> Shape {
        Shape {
            max_depth: self.max_depth.max(o.max_depth),
            largest_leaf: self.largest_leaf.max(o.largest_leaf),
            median_splits: self.median_splits + o.median_splits,
            cuts: self.cuts + o.cuts,
        }
    }
}

/// What every node of one build shares.
struct Ctx {
    max_leaf: usize,
    cap: usize,
    parallel: bool,
}

impl Ctx {
    /// Whether a split at `depth` (one level lower after a cut) whose larger child holds
    /// `deepest` triangles still reaches leaves of `max_leaf` under the cap.
    fn fits(&self, depth: usize, cut: bool, deepest: usize) -> bool {
        depth + 1 + cut as usize + levels_needed(deepest, self.max_leaf) <= self.cap
    }

    /// The node's split: the global heuristic, or the object median where that would pass
    /// the depth cap or cannot separate the centres.
    fn split(&self, prims: &mut [Prim], cell: &Cell, depth: usize) -> Split {
        let n = prims.len();
        let mut cand = cell.candidate;
        let (c, o) = (&cell.centres, &cell.objects);
        // The empty space the last empty half left free of triangles, if any (Sunflow's
        // BIH, after the paper): cut off by a one-sided node above the split.
        let mut cut = None;
        let degenerate = c.lo == c.hi;
        for _ in 0..MAX_HALVINGS {
            if degenerate {
                break;
            }
            let k = longest_axis(&cand);
            let (lo, hi) = (cand.lo[k], cand.hi[k]);
            let mid = 0.5 * (lo + hi);
            if !(lo < mid && mid < hi) {
                break;
            }
            // A half without centres: no node, the candidate shrinks to the other half.
            // Where no triangle reaches into that half either, and its plane is tighter
            // than the ancestors' ones, the space beyond the triangles can be cut off.
            if c.lo[k] >= mid {
                cand.lo[k] = mid;
                cut = (o.lo[k] >= mid && o.lo[k] > cell.clip.lo[k]).then_some(Cut {
                    axis: k,
                    plane: o.lo[k],
                    keep_left: false,
                });
                continue;
            }
            if c.hi[k] < mid {
                cand.hi[k] = mid;
                cut = (o.hi[k] <= mid && o.hi[k] < cell.clip.hi[k]).then_some(Cut {
                    axis: k,
                    plane: o.hi[k],
                    keep_left: true,
                });
                continue;
            }
            let left_len = partition(prims, |p| p.centre(k) < mid);
            let deepest = left_len.max(n - left_len);
            let cut = cut.filter(|_| self.fits(depth, true, deepest));
            if !self.fits(depth, cut.is_some(), deepest) {
                break;
            }
            let (mut lc, mut rc) = (cand, cand);
            lc.hi[k] = mid;
            rc.lo[k] = mid;
            return self.finish(prims, cell, cut, k, left_len, lc, rc, false);
        }
        self.median(prims, cell, cand)
    }

    /// The split at the object median of the centres on their longest axis (ties by
    /// original index, so the tree does not depend on the order prims arrive in).
    fn median(&self, prims: &mut [Prim], cell: &Cell, cand: Aabb) -> Split {
        let k = longest_axis(&cell.centres);
        let left_len = prims.len() / 2;
        prims.select_nth_unstable_by(left_len, |a, b| {
            a.centre(k)
                .total_cmp(&b.centre(k))
                .then(a.index.cmp(&b.index))
        });
        let m = prims[left_len].centre(k);
        let (mut lc, mut rc) = (cand, cand);
        lc.hi[k] = lc.hi[k].min(m);
        rc.lo[k] = rc.lo[k].max(m);
        self.finish(prims, cell, None, k, left_len, lc, rc, true)
    }

    /// The split's children: their triangles' and centres' bounds, their regions.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        prims: &[Prim],
        cell: &Cell,
        cut: Option<Cut>,
        axis: usize,
        left_len: usize,
        left_candidate: Aabb,
        right_candidate: Aabb,
        median: bool,
    ) -> Split {
        let (l, r) = prims.split_at(left_len);
        let ((lo, lc), (ro, rc)) = if self.parallel && prims.len() >= PARALLEL_MIN {
            rayon::join(|| bounds(l), || bounds(r))
        } else {
            (bounds(l), bounds(r))
        };
        let region = cut.map_or(cell.clip, |c| c.clip(cell.clip));
        let (mut left_clip, mut right_clip) = (region, region);
        left_clip.hi[axis] = lo.hi[axis];
        right_clip.lo[axis] = ro.lo[axis];
        Split {
            cut,
            axis,
            left_len,
            left: Cell {
                objects: lo,
                centres: lc,
                candidate: left_candidate,
                clip: left_clip,
            },
            right: Cell {
                objects: ro,
                centres: rc,
                candidate: right_candidate,
                clip: right_clip,
            },
            median,
        }
    }

    /// Builds the subtree over `prims` (at position `first` of the whole array) into `out`,
    /// whose node indices are local to `out`.
    fn grow(
        &self,
        prims: &mut [Prim],
        first: usize,
        cell: Cell,
        depth: usize,
        out: &mut Vec<BihNode>,
    ) -> Shape {
        let n = prims.len();
        if n <= self.max_leaf || depth >= self.cap {
            out.push(BihNode::leaf(first as u32, n as u32));
            return Shape {
                max_depth: depth,
                largest_leaf: n,
                ..Shape::default()
            };
        }
        let s = self.split(prims, &cell, depth);
        let mut depth = depth;
        if let Some(c) = s.cut {
            let child = out.len() as u32 + 1;
            out.push(BihNode::one_sided(c.axis, c.plane, c.keep_left, child));
            depth += 1;
        }
        let k = s.axis;
        let (lp, rp) = prims.split_at_mut(s.left_len);
        let rfirst = first + s.left_len;
        let me = out.len();
        out.push(BihNode::leaf(0, 0));
        let (shape, right) = if self.parallel && n >= PARALLEL_MIN {
            let build = |p: &mut [Prim], f: usize, c: Cell| {
                let mut v = Vec::new();
                let shape = self.grow(p, f, c, depth + 1, &mut v);
                (v, shape)
            };
            let ((a, sa), (b, sb)) =
                rayon::join(|| build(lp, first, s.left), || build(rp, rfirst, s.right));
            out.reserve(a.len() + b.len());
            let base = out.len() as u32;
            out.extend(a.iter().map(|x| x.shifted(base)));
            let right = out.len() as u32;
            out.extend(b.iter().map(|x| x.shifted(right)));
            (sa.merge(sb), right)
        } else {
            let sa = self.grow(lp, first, s.left, depth + 1, out);
            let right = out.len() as u32;
            let sb = self.grow(rp, rfirst, s.right, depth + 1, out);
            (sa.merge(sb), right)
        };
        out[me] = BihNode::inner(k, s.left.objects.hi[k], s.right.objects.lo[k], right);
        Shape {
            median_splits: shape.median_splits + s.median as usize,
            cuts: shape.cuts + s.cut.is_some() as usize,
            ..shape
        }
    }
}

/// Moves the prims for which `left` holds to the front; returns how many there are.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let (mut i, mut j) = (0, prims.len());
    loop {
        while i < j && left(&prims[i]) {
            i += 1;
        }
        while i < j && !left(&prims[j - 1]) {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        prims.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}

/// Builds the tree over the mesh's `included` triangles (memory checked by the caller).
pub(super) fn build(
    mesh: &Mesh,
    included: &[u32],
    max_leaf: usize,
    cap: usize,
    parallel: bool,
) -> Built {
    let prim = |&i: &u32| {
        let b = mesh.triangles[i as usize].bbox();
        Prim {
            lo: b.lo,
            hi: b.hi,
            index: i,
        }
    };
    let mut prims: Vec<Prim> = if parallel {
        included.par_iter().map(prim).collect()
    } else {
        included.iter().map(prim).collect()
    };
    let (objects, centres) = bounds(&prims);
    let ctx = Ctx {
        max_leaf,
        cap,
        parallel,
    };
    let mut nodes = Vec::with_capacity((2 * prims.len()).max(1));
    let shape = ctx.grow(
        &mut prims,
        0,
        Cell {
            objects,
            centres,
            candidate: objects,
            clip: objects,
        },
        0,
        &mut nodes,
    );
    nodes.shrink_to_fit();
    let tri = |p: &Prim| {
        let t = &mesh.triangles[p.index as usize];
        LeafTri {
            v0: t.v[0].into(),
            prim: p.index,
            v1: t.v[1].into(),
            pad1: 0,
            v2: t.v[2].into(),
            pad2: 0,
        }
    };
    let tris = if parallel {
        prims.par_iter().map(tri).collect()
    } else {
        prims.iter().map(tri).collect()
    };
    Built {
        nodes,
        tris,
        bounds: objects,
        max_depth: shape.max_depth,
        largest_leaf: shape.largest_leaf,
        median_splits: shape.median_splits,
        cuts: shape.cuts,
    }
}
