//! The geometric half of every layout's [`validate`](super::GpuForm::validate), one walk for
//! all of them: each layout describes its tree as nodes with slots ([`BoxTree`]), and
//! [`check_boxes`] checks that
//!
//! - every slot's box holds everything below it: a leaf slot every vertex of its triangles,
//!   an inner slot every vertex under the node it refers to. Exactly, in f32 with no
//!   tolerance: the boxes as the traversal reads them (for `cwbvh`, dequantised), so a ray
//!   that meets a triangle passes every box on the way to it;
//! - except for a triangle split in space (an SBVH's: its records in several leaves, each
//!   leaf bounding a part of it): there, the boxes on the way to its leaves — each path's
//!   boxes intersected — must together cover the whole triangle, checked by cutting the
//!   triangle against them in f64 ([`covered`]), so a ray that meets it passes every box on
//!   the way to one of those leaves;
//! - the leaves under each root refer to every record of the triangle array exactly once
//!   (`threaded`'s eight copies each on their own).
//!
//! A slot is checked against what lies below it, not against the slot boxes of the node it
//! refers to: a `cwbvh` child node's dequantised boxes may reach up to a step past its
//! parent's (each is rounded outwards on its own grid), while both hold the triangles.
//!
//! The structural checks run first (indices in range, a tree: each node reached once), so
//! the walk meets every node once: linear in nodes and triangles, with one flag per
//! triangle and one frame per level (a stack, not recursion: a `threaded` file's tree has
//! no depth cap). A big tree is first walked on all threads, its top split into tasks.

use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use crate::accel::LeafTri;
use crate::geometry::{covered, Aabb};

/// What a slot refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Child {
    /// An inner node, by the index [`BoxTree::slots`] takes.
    Node(u32),
    /// A leaf: records `first..first + count` of the triangle array.
    Tris {
        /// First record.
        first: u32,
        /// Records.
        count: u32,
    },
}

/// Where a slot's box is stored, for messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum At {
    /// In slot `slot` of node `node` (wide nodes: `bvh2-wide-node`, `cwbvh`, `bvh4`/`bvh8`).
    Slot {
        /// The node holding the slot.
        node: u32,
        /// The slot.
        slot: u32,
    },
    /// In the node itself (`dfs-sign`, `threaded`: a node's box is its own).
    Node(u32),
    /// Nowhere: a root the traversal enters without a box test.
    Root,
}

impl std::fmt::Display for At {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            At::Slot { node, slot } => write!(f, "node {node} slot {slot}"),
            At::Node(node) => write!(f, "node {node}"),
            At::Root => f.write_str("the root"),
        }
    }
}

/// One slot: a box (none for a root entered without one), what it holds, where it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Slot {
    /// The box the traversal tests before it enters `child`.
    pub bbox: Option<Aabb>,
    /// What it refers to.
    pub child: Child,
    /// Where the box is stored.
    pub at: At,
}

/// A layout's tree as [`check_boxes`] walks it.
pub(crate) trait BoxTree {
    /// The root slots, each the entry to a whole tree over the triangle array (one;
    /// `threaded`: one per copy).
    fn roots(&self) -> impl Iterator<Item = Slot> + '_;

    /// The occupied slots of inner node `node` (one a [`Child::Node`] names), in any
    /// order. Called only after the layout's structural checks passed, so indices are in
    /// range.
    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_;

    /// The triangle array leaves refer to.
    fn tris(&self) -> &[LeafTri];
}

/// The one root of a layout whose node 0 is the root and holds no box of its own (the wide
/// layouts: their boxes are the slots').
pub(crate) fn node_zero() -> impl Iterator<Item = Slot> {
    std::iter::once(Slot {
        bbox: None,
        child: Child::Node(0),
        at: At::Root,
    })
}

/// `[lo]..[hi]`, for messages.
fn show(b: &Aabb) -> String {
    format!("{:?}..{:?}", b.lo.to_array(), b.hi.to_array())
}

/// Whether `b` holds `p`: f32 comparisons, faces included; a NaN is held by nothing.
#[inline(always)]
fn holds_point(b: &Aabb, p: glam::Vec3) -> bool {
    b.lo.cmple(p).all() && p.cmple(b.hi).all()
}

/// One inner node being walked: the slot it was entered through, its slots still to walk,
/// the union of the vertices below the slots walked so far, and the intersection of the
/// boxes on the way to it (what a ray must pass to reach it).
struct Frame<I> {
    entered: Slot,
    slots: I,
    below: Aabb,
    within: Aabb,
}

/// Everything.
const ALL: Aabb = Aabb {
    lo: glam::Vec3::splat(f32::NEG_INFINITY),
    hi: glam::Vec3::splat(f32::INFINITY),
};

/// `within` cut to a slot's box.
fn narrowed(within: &Aabb, slot: &Slot) -> Aabb {
    match &slot.bbox {
        Some(b) => Aabb {
            lo: within.lo.max(b.lo),
            hi: within.hi.min(b.hi),
        },
        None => *within,
    }
}

/// The prims with several records, counted the first time one is asked about (only trees
/// with a triangle outside a box on the way to its leaf pay for it).
struct Several(Option<HashSet<u32>>);

impl Several {
    fn holds(&mut self, tris: &[LeafTri], prim: u32) -> bool {
        self.0
            .get_or_insert_with(|| several_prims(tris))
            .contains(&prim)
    }
}

/// The prims with more than one record.
fn several_prims(tris: &[LeafTri]) -> HashSet<u32> {
    let mut count = std::collections::HashMap::<u32, u32>::new();
    for t in tris {
        *count.entry(t.prim).or_default() += 1;
    }
    count
        .into_iter()
        .filter(|&(_, n)| n > 1)
        .map(|(p, _)| p)
        .collect()
}

/// A triangle record whose leaf box does not hold it all: where it is, the box, a vertex
/// outside, and what a ray must pass to reach it.
struct Part {
    at: At,
    record: u32,
    bbox: Aabb,
    vertex: glam::Vec3,
    within: Aabb,
}

/// Checks that every slot's box holds the triangles below it and that the leaves under
/// each root refer to every triangle record once; the error names the first bad slot.
/// A big tree is walked on all threads first ([`holds_everywhere`]); only where that finds a
/// fault does the walk in order run, to name the first one (the same whatever the threads).
pub(crate) fn check_boxes<T: BoxTree + Sync>(tree: &T) -> Result<(), String> {
    if tree.tris().len() >= PARALLEL_TRIS && holds_everywhere(tree) {
        return Ok(());
    }
    check_in_order(tree)
}

/// Trees of at least this many triangle records are checked on all threads first.
const PARALLEL_TRIS: usize = 1 << 16;

/// [`check_boxes`]'s walk in depth-first order on one thread.
fn check_in_order<T: BoxTree>(tree: &T) -> Result<(), String> {
    let tris = tree.tris();
    let roots: Vec<Slot> = tree.roots().collect();
    let several = roots.len() > 1;
    let mut walk = Walk {
        seen: vec![false; tris.len()],
        parts: Vec::new(),
        several: Several(None),
    };
    for root in roots {
        walk.seen.fill(false);
        walk.parts.clear();
        let below = walk_slot(tree, &root, narrowed(&ALL, &root), &mut walk)?;
        inner(&root, &below)?;
        check_parts(tris, &walk.parts)?;
        let seen = &walk.seen;
        if let Some(t) = seen.iter().position(|s| !s) {
            let end = (seen[t..].iter().position(|&s| s)).map_or(seen.len(), |k| t + k);
            let under = match several {
                true => format!(" under {}", root.at),
                false => String::new(),
            };
            return Err(format!("triangles {t}..{end} are in no leaf{under}"));
        }
    }
    Ok(())
}

/// The box of the vertices below `slot` (reached within `within`, its own box included),
/// walked depth first in slot order with a stack of frames rather than recursion (a
/// `threaded` file's tree has no depth cap); the error names the first fault.
fn walk_slot<T: BoxTree>(
    tree: &T,
    slot: &Slot,
    within: Aabb,
    marks: &mut impl Marks,
) -> Result<Aabb, String> {
    let n = match slot.child {
        Child::Tris { first, count } => {
            return leaf(slot, (first, count), tree.tris(), within, marks)
        }
        Child::Node(n) => n,
    };
    let mut stack = vec![Frame {
        entered: *slot,
        slots: tree.slots(n),
        below: Aabb::EMPTY,
        within,
    }];
    while let Some(top) = stack.last_mut() {
        let Some(slot) = top.slots.next() else {
            // Every slot walked: the box it was entered through must hold it all.
            let Some(done) = stack.pop() else { break };
            inner(&done.entered, &done.below)?;
            match stack.last_mut() {
                Some(parent) => parent.below = parent.below.union(done.below),
                None => return Ok(done.below),
            }
            continue;
        };
        let within = narrowed(&top.within, &slot);
        match slot.child {
            Child::Tris { first, count } => {
                let b = leaf(&slot, (first, count), tree.tris(), within, marks)?;
                top.below = top.below.union(b);
            }
            Child::Node(n) => stack.push(Frame {
                entered: slot,
                slots: tree.slots(n),
                below: Aabb::EMPTY,
                within,
            }),
        }
    }
    Ok(Aabb::EMPTY)
}

/// What the walk under one root gathers: the records seen, the parts of split triangles,
/// which prims have several records.
struct Walk {
    seen: Vec<bool>,
    parts: Vec<Part>,
    several: Several,
}

/// What a leaf step records: the walk's own ([`Walk`]), or shared by all threads
/// ([`SharedMarks`]).
trait Marks {
    /// Marks record `r` seen; returns whether it was seen before.
    fn mark(&mut self, r: usize) -> bool;
    /// Keeps a part of a split triangle for [`check_parts`].
    fn part(&mut self, p: Part);
    /// Whether `prim` has several records.
    fn several(&mut self, tris: &[LeafTri], prim: u32) -> bool;
}

impl Marks for Walk {
    fn mark(&mut self, r: usize) -> bool {
        std::mem::replace(&mut self.seen[r], true)
    }
    fn part(&mut self, p: Part) {
        self.parts.push(p);
    }
    fn several(&mut self, tris: &[LeafTri], prim: u32) -> bool {
        self.several.holds(tris, prim)
    }
}

/// Marks records seen; checks their vertices against the leaf's box; returns the box of
/// those vertices. A triangle with several records (a spatial split's) and a vertex
/// outside the boxes on the way here (`within`, this leaf's included) is kept as a part
/// for [`check_parts`] (its other leaves may hold the rest), and only its bounds within
/// `within` count as below. The usual case, every vertex inside, is inlined into the
/// walk; the rest is [`leaf_in_parts`].
#[inline(always)]
fn leaf(
    slot: &Slot,
    (first, count): (u32, u32),
    tris: &[LeafTri],
    within: Aabb,
    marks: &mut impl Marks,
) -> Result<Aabb, String> {
    let (first, end) = (first as usize, first as usize + count as usize);
    let Some(ts) = tris.get(first..end) else {
        return Err(out_of_range(slot, (first, end), tris.len()));
    };
    let Some(below) = whole_inside(ts, &within) else {
        return leaf_in_parts(slot, first, ts, tris, within, marks);
    };
    // Only the marks can fail, in the order the walk of `leaf_in_parts` meets them.
    for record in first..end {
        if marks.mark(record) {
            return Err(twice(slot, record));
        }
    }
    Ok(below)
}

#[cold]
fn out_of_range(slot: &Slot, (first, end): (usize, usize), len: usize) -> String {
    format!("{} refers to triangles {first}..{end} of {len}", slot.at)
}

#[cold]
fn twice(slot: &Slot, record: usize) -> String {
    format!("{}: triangle {record} is in two leaves", slot.at)
}

/// [`leaf`] where a vertex lies outside a box on the way, triangle by triangle.
#[cold]
#[inline(never)]
fn leaf_in_parts(
    slot: &Slot,
    first: usize,
    ts: &[LeafTri],
    tris: &[LeafTri],
    within: Aabb,
    marks: &mut impl Marks,
) -> Result<Aabb, String> {
    let mut below = Aabb::EMPTY;
    for (k, t) in ts.iter().enumerate() {
        let record = first + k;
        if marks.mark(record) {
            return Err(twice(slot, record));
        }
        let vs = [t.v0, t.v1, t.v2].map(glam::Vec3::from);
        let out_of = |b: &Aabb| {
            vs.into_iter()
                .find(|&v| !holds_point(b, v))
                .map(|v| (*b, v))
        };
        // `within` lies inside the slot's own box: the slot is asked about only where a
        // vertex is outside `within` (rarely).
        let outside_slot = || slot.bbox.as_ref().and_then(out_of);
        match out_of(&within) {
            // Whole inside every box on the way (the usual case).
            None => below = vs.into_iter().fold(below, Aabb::grow),
            // A part of a triangle other leaves hold too: only its bounds within count here,
            // and the parts together must cover it.
            Some(off) if vs.iter().all(|v| v.is_finite()) && marks.several(tris, t.prim) => {
                let (bbox, vertex) = outside_slot().unwrap_or(off);
                let tb = Aabb::from_points(&vs);
                below = below.union(Aabb {
                    lo: tb.lo.max(within.lo),
                    hi: tb.hi.min(within.hi),
                });
                marks.part(Part {
                    at: slot.at,
                    record: record as u32,
                    bbox,
                    vertex,
                    within,
                });
            }
            Some(_) => match outside_slot() {
                Some((bbox, vertex)) => {
                    return Err(outside_message(slot.at, record, t, &bbox, vertex));
                }
                // Inside its own box, outside one above: that box's check names it.
                None => below = vs.into_iter().fold(below, Aabb::grow),
            },
        }
    }
    Ok(below)
}

/// The box of the triangles' vertices where every one lies inside `within` (faces
/// included, none NaN), else None: [`leaf`]'s usual case, checked in SIMD lanes (a
/// record's vertex is loaded with the 4 bytes after it, a lane whose comparison is masked
/// off and whose value is never returned).
#[inline(always)]
fn whole_inside(ts: &[LeafTri], within: &Aabb) -> Option<Aabb> {
    use glam::{Vec3A, Vec4};
    let (wlo, whi) = (Vec3A::from(within.lo), Vec3A::from(within.hi));
    let (mut lo, mut hi) = (Vec3A::from(Aabb::EMPTY.lo), Vec3A::from(Aabb::EMPTY.hi));
    let mut inside = glam::BVec3A::TRUE;
    for t in ts {
        let f: &[f32; 12] = bytemuck::cast_ref(t);
        for v in f.chunks_exact(4) {
            let v = Vec3A::from_vec4(Vec4::from_slice(v));
            // False for a NaN lane: the box below is then never returned.
            inside &= wlo.cmple(v) & v.cmple(whi);
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    inside.all().then(|| Aabb {
        lo: lo.into(),
        hi: hi.into(),
    })
}

/// What the walk on all threads shares: the records' flags, the count of marks, the parts
/// of split triangles, which prims have several records. Only a task marks
/// ([`TaskMarks`]), so that every mark is counted.
#[derive(Clone, Copy)]
struct SharedMarks<'a> {
    seen: &'a [AtomicBool],
    records: &'a AtomicUsize,
    parts: &'a Mutex<Vec<Part>>,
    several: &'a OnceLock<HashSet<u32>>,
}

/// One task's marks. A record is marked by a plain load and store, not an atomic swap (a
/// locked instruction a triangle): two threads marking one record may then both find it
/// unmarked, so the task counts its marks and adds them to `records` when it ends,
/// however it ends ([`each_once`] then finds the mark too many).
struct TaskMarks<'a> {
    shared: SharedMarks<'a>,
    marked: usize,
}

impl Drop for TaskMarks<'_> {
    fn drop(&mut self) {
        self.shared
            .records
            .fetch_add(self.marked, Ordering::Relaxed);
    }
}

impl Marks for TaskMarks<'_> {
    fn mark(&mut self, r: usize) -> bool {
        self.marked += 1;
        let seen = &self.shared.seen[r];
        let before = seen.load(Ordering::Relaxed);
        seen.store(true, Ordering::Relaxed);
        before
    }
    fn part(&mut self, p: Part) {
        // A poisoned lock only means another thread panicked: its parts are still there.
        let mut parts = self.shared.parts.lock().unwrap_or_else(|e| e.into_inner());
        parts.push(p);
    }
    fn several(&mut self, tris: &[LeafTri], prim: u32) -> bool {
        self.shared
            .several
            .get_or_init(|| several_prims(tris))
            .contains(&prim)
    }
}

/// Tasks the walk on all threads spreads the top of the tree over.
const TASKS: usize = 64;

/// Whether every check of [`check_in_order`] passes, the tree walked on all threads: each
/// slot's subtree is checked on its own and returns the box of the vertices below it.
fn holds_everywhere<T: BoxTree + Sync>(tree: &T) -> bool {
    use rayon::prelude::*;
    let tris = tree.tris();
    let seen: Vec<AtomicBool> = (0..tris.len())
        .into_par_iter()
        .map(|_| AtomicBool::new(false))
        .collect();
    let several = OnceLock::new();
    for root in tree.roots() {
        seen.par_iter()
            .for_each(|s| s.store(false, Ordering::Relaxed));
        let parts = Mutex::new(Vec::new());
        let records = AtomicUsize::new(0);
        let marks = SharedMarks {
            seen: &seen,
            records: &records,
            parts: &parts,
            several: &several,
        };
        if subtree(tree, &root, narrowed(&ALL, &root), marks, TASKS).is_none() {
            return false;
        }
        let parts = parts.into_inner().unwrap_or_else(|e| e.into_inner());
        if check_parts(tris, &parts).is_err() || !each_once(&seen, records.into_inner()) {
            return false;
        }
    }
    true
}

/// Whether the walk on all threads marked every record once: each one seen, and as many
/// marks as records (a record two threads both found unmarked was seen with one mark too
/// many).
fn each_once(seen: &[AtomicBool], marks: usize) -> bool {
    use rayon::prelude::*;
    marks == seen.len() && seen.par_iter().all(|s| s.load(Ordering::Relaxed))
}

/// The box of the vertices below `slot` (reached within `within`), every check below it
/// passed; None at the first that fails. The top of the tree is split into `tasks` tasks,
/// evenly among the slots of each node (recursing a few levels at most); each walks its
/// subtree with [`walk_slot`].
fn subtree<T: BoxTree + Sync>(
    tree: &T,
    slot: &Slot,
    within: Aabb,
    marks: SharedMarks<'_>,
    tasks: usize,
) -> Option<Aabb> {
    let below = match slot.child {
        Child::Node(n) if tasks > 1 => {
            use rayon::prelude::*;
            let slots: Vec<Slot> = tree.slots(n).collect();
            let each = tasks / slots.len().max(1);
            slots
                .par_iter()
                .map(|s| subtree(tree, s, narrowed(&within, s), marks, each))
                .try_reduce(|| Aabb::EMPTY, |a, b| Some(a.union(b)))?
        }
        // One task: the walk in order (no recursion, whatever the depth).
        _ => {
            let mut task = TaskMarks {
                shared: marks,
                marked: 0,
            };
            return walk_slot(tree, slot, within, &mut task).ok();
        }
    };
    inner(slot, &below).ok()?;
    Some(below)
}

fn outside_message(at: At, record: usize, t: &LeafTri, bbox: &Aabb, v: glam::Vec3) -> String {
    format!(
        "{at}: triangle {record} (prim {}) lies outside the box {}: its vertex {:?}",
        t.prim,
        show(bbox),
        v.to_array()
    )
}

/// Checks the triangles whose leaf boxes hold only parts of them: the records of the same
/// triangle (same `prim`, same vertices) together, the boxes on the way to each must cover
/// it — unless another record of it sits whole in its leaf.
fn check_parts(tris: &[LeafTri], parts: &[Part]) -> Result<(), String> {
    if parts.is_empty() {
        return Ok(());
    }
    let key = |t: &LeafTri| (t.prim, bytemuck::cast::<_, [u32; 9]>([t.v0, t.v1, t.v2]));
    let mut split: std::collections::HashMap<_, Vec<&Part>> = std::collections::HashMap::new();
    for p in parts {
        split
            .entry(key(&tris[p.record as usize]))
            .or_default()
            .push(p);
    }
    // In record order, whatever order the walk met them in (the walk on all threads).
    split.values_mut().for_each(|g| g.sort_by_key(|p| p.record));
    // A record that is not a part sits whole in its leaf: its triangle is covered.
    let mut is_part = vec![false; tris.len()];
    for p in parts {
        is_part[p.record as usize] = true;
    }
    for (r, t) in tris.iter().enumerate() {
        if !is_part[r] {
            split.remove(&key(t));
        }
    }
    let mut bad: Vec<&Vec<&Part>> = split
        .values()
        .filter(|group| {
            let t = tris[group[0].record as usize].triangle();
            let boxes: Vec<Aabb> = group.iter().map(|p| p.within).collect();
            !covered(&t, &boxes)
        })
        .collect();
    bad.sort_by_key(|group| group[0].record);
    match bad.first() {
        None => Ok(()),
        Some(group) => {
            let p = group[0];
            let t = &tris[p.record as usize];
            let mut msg = outside_message(p.at, p.record as usize, t, &p.bbox, p.vertex);
            if group.len() > 1 {
                msg += &format!(
                    ", and the boxes of its {} leaves do not cover it together",
                    group.len()
                );
            }
            Err(msg)
        }
    }
}

/// Checks that an inner slot's box holds `below`, the box of the vertices under it (each
/// vertex was checked against its leaf's box, so none is NaN; nothing below is held by any
/// box).
fn inner(slot: &Slot, below: &Aabb) -> Result<(), String> {
    let Some(b) = &slot.bbox else {
        return Ok(());
    };
    if below.is_empty() || (holds_point(b, below.lo) && holds_point(b, below.hi)) {
        return Ok(());
    }
    Err(format!(
        "{}: the triangles below it span {}, outside the box {}",
        slot.at,
        show(below),
        show(b)
    ))
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// A tree given as lists: node i's slots are `nodes[i]`.
    struct Lists {
        roots: Vec<Slot>,
        nodes: Vec<Vec<Slot>>,
        tris: Vec<LeafTri>,
    }

    impl BoxTree for Lists {
        fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
            self.roots.iter().copied()
        }
        fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
            self.nodes[node as usize].iter().copied()
        }
        fn tris(&self) -> &[LeafTri] {
            &self.tris
        }
    }

    fn slot(lo: f32, hi: f32, child: Child, at: At) -> Slot {
        Slot {
            bbox: Some(Aabb {
                lo: Vec3::splat(lo),
                hi: Vec3::splat(hi),
            }),
            child,
            at,
        }
    }

    /// Triangle i spans i..i + 1 on every axis.
    fn tri(i: u32) -> LeafTri {
        let p = Vec3::splat(i as f32);
        LeafTri::new([p, p + Vec3::X + Vec3::Y, p + Vec3::ONE], i)
    }

    /// Node 0 holds a leaf of triangles 0..2 and node 1, which holds a leaf of triangle 2.
    fn good() -> Lists {
        let at = |node, slot| At::Slot { node, slot };
        Lists {
            roots: vec![Slot {
                bbox: None,
                child: Child::Node(0),
                at: At::Root,
            }],
            nodes: vec![
                vec![
                    slot(0.0, 2.0, Child::Tris { first: 0, count: 2 }, at(0, 0)),
                    slot(2.0, 3.0, Child::Node(1), at(0, 1)),
                ],
                vec![slot(2.0, 3.0, Child::Tris { first: 2, count: 1 }, at(1, 0))],
            ],
            tris: (0..3).map(tri).collect(),
        }
    }

    /// A binary tree over `n` triangles (leaves of at most 4), its boxes exact.
    fn big(n: u32) -> Lists {
        fn add(nodes: &mut Vec<Vec<Slot>>, (a, b): (u32, u32), at: At) -> Slot {
            if b - a <= 4 {
                let leaf = Child::Tris {
                    first: a,
                    count: b - a,
                };
                return slot(a as f32, b as f32, leaf, at);
            }
            let node = nodes.len() as u32;
            nodes.push(Vec::new());
            let m = (a + b) / 2;
            let kids = [(a, m), (m, b)].into_iter().enumerate();
            let slots = kids.map(|(k, r)| {
                add(
                    nodes,
                    r,
                    At::Slot {
                        node,
                        slot: k as u32,
                    },
                )
            });
            nodes[node as usize] = slots.collect();
            slot(a as f32, b as f32, Child::Node(node), at)
        }
        let mut nodes = Vec::new();
        let root = add(&mut nodes, (0, n), At::Root);
        Lists {
            roots: vec![root],
            nodes,
            tris: (0..n).map(tri).collect(),
        }
    }

    #[test]
    fn the_walk_on_all_threads_passes_what_the_walk_in_order_passes() {
        let n = PARALLEL_TRIS as u32 + 1000;
        let t = big(n);
        assert!(holds_everywhere(&t));
        check_boxes(&t).unwrap();
        // Where it finds a fault, the walk in order names it: the same message.
        type Fault<'f> = (&'f str, &'f dyn Fn(&mut Lists));
        let faults: [Fault; 5] = [
            ("a leaf box short", &|t| {
                let leaf = (t.nodes.iter_mut().rev().flatten())
                    .find(|s| matches!(s.child, Child::Tris { .. }))
                    .unwrap();
                leaf.bbox.as_mut().unwrap().hi.x -= 0.5;
            }),
            ("an inner box short", &|t| {
                t.nodes[7][1].bbox.as_mut().unwrap().lo.y += 0.5;
            }),
            ("a NaN vertex", &|t| t.tris[40_000].v2[1] = f32::NAN),
            ("a triangle in two leaves", &|t| {
                let leaf = (t.nodes.iter_mut().flatten())
                    .find(|s| matches!(s.child, Child::Tris { first, .. } if first > 30_000))
                    .unwrap();
                if let Child::Tris { first, count } = &mut leaf.child {
                    (*first, *count) = (*first - 1, *count + 1);
                }
            }),
            ("a triangle in no leaf", &|t| {
                let leaf = (t.nodes.iter_mut().flatten())
                    .find(|s| matches!(s.child, Child::Tris { count: 4, .. }))
                    .unwrap();
                leaf.child = Child::Tris { first: 0, count: 3 };
            }),
        ];
        for (what, f) in faults {
            let mut t = big(n);
            f(&mut t);
            assert!(!holds_everywhere(&t), "{what}: passed on all threads");
            let (e, want) = (check_boxes(&t), check_in_order(&t));
            assert!(e.is_err(), "{what}: passed");
            assert_eq!(e, want, "{what}");
        }
    }

    #[test]
    fn a_record_marked_twice_unnoticed_is_refused_by_the_count() {
        let seen = |flags: &[bool]| {
            flags
                .iter()
                .map(|&f| AtomicBool::new(f))
                .collect::<Vec<_>>()
        };
        assert!(each_once(&seen(&[true; 5]), 5));
        // Two threads found record 3 unmarked: all seen, one mark too many.
        assert!(!each_once(&seen(&[true; 5]), 6));
        assert!(!each_once(&seen(&[true, true, false, true, true]), 5));
    }

    #[test]
    fn a_chain_deeper_than_any_stack_is_walked() {
        // A `threaded` file's tree has no depth cap: node i holds triangle i and node i + 1.
        let n = PARALLEL_TRIS as u32 + 1000;
        let at = |node, slot| At::Slot { node, slot };
        let nodes = (0..n)
            .map(|i| {
                let mut slots = vec![slot(
                    i as f32,
                    i as f32 + 1.0,
                    Child::Tris { first: i, count: 1 },
                    at(i, 0),
                )];
                if i + 1 < n {
                    let below = Child::Node(i + 1);
                    slots.push(slot(i as f32 + 1.0, n as f32, below, at(i, 1)));
                }
                slots
            })
            .collect();
        let root = slot(0.0, n as f32, Child::Node(0), At::Root);
        let mut t = Lists {
            roots: vec![root],
            nodes,
            tris: (0..n).map(tri).collect(),
        };
        assert!(holds_everywhere(&t));
        check_boxes(&t).unwrap();
        t.tris[n as usize - 2].v1[2] = n as f32 + 1.0;
        let e = check_boxes(&t).unwrap_err();
        assert!(e.contains("lies outside the box"), "{e}");
    }

    #[test]
    fn built_layouts_pass_the_walk_on_all_threads() {
        use crate::accel::bvh::layouts::{cwbvh::Cwbvh, dfs_sign::DfsSign, threaded::Threaded};
        use crate::accel::bvh::{build, BuildOptions, Builder};
        // Small triangles on a grid and long thin ones across it: the SBVH splits the long
        // ones (records in several leaves); threaded walks eight roots.
        let n = PARALLEL_TRIS + 500;
        let small = (0..n).map(|i| {
            let p = Vec3::new((i % 256) as f32, (i / 256) as f32, (i % 7) as f32 * 0.1);
            crate::geometry::Triangle::new(p, p + Vec3::X * 0.5, p + Vec3::Y * 0.5)
        });
        let long = (0..300).map(|k| {
            let p = Vec3::new(k as f32 * 0.8, 0.0, (k % 5) as f32 * 0.2);
            let d = Vec3::new(((k * 37) % 200) as f32 - 100.0, 250.0, 0.3);
            crate::geometry::Triangle::new(p, p + d, p + Vec3::Z * 0.05)
        });
        let triangles: Vec<_> = small.chain(long).collect();
        let n = triangles.len();
        let mesh = crate::mesh::Mesh::from_triangles(triangles);
        for builder in [Builder::Sweep, Builder::Sbvh] {
            let opts = BuildOptions {
                builder,
                ..BuildOptions::default()
            };
            let bvh = build(&mesh, &opts);
            let split = Cwbvh::flatten(&bvh, &mesh).leaf_tris().len() - n;
            // The SBVH's leaves hold parts of the long triangles; the sweep's none.
            assert_eq!(
                split > 0,
                builder == Builder::Sbvh,
                "{builder:?}: {split} records beyond the triangles"
            );
            assert!(
                holds_everywhere(&Threaded::flatten(&bvh, &mesh)),
                "{builder:?}"
            );
            assert!(
                holds_everywhere(&Cwbvh::flatten(&bvh, &mesh)),
                "{builder:?}"
            );
            assert!(
                holds_everywhere(&DfsSign::flatten(&bvh, &mesh)),
                "{builder:?}"
            );
            if builder == Builder::Sbvh {
                assert!(split > 0, "the SBVH split nothing");
            }
        }
    }

    #[test]
    fn boxes_hold_their_triangles_exactly_and_leaves_cover_every_triangle_once() {
        // Faces included: the boxes are the triangles' exact bounds.
        check_boxes(&good()).unwrap();
        let refused = |what: &str, want: &str, f: &dyn Fn(&mut Lists)| {
            let mut t = good();
            f(&mut t);
            let e = check_boxes(&t).expect_err(what);
            assert!(e.contains(want), "{what}: {e}");
        };
        refused(
            "a leaf box one step short",
            "node 0 slot 0: triangle 1 (prim 1) lies outside the box",
            &|t| {
                t.nodes[0][0].bbox.as_mut().unwrap().hi.z = 2f32.next_down();
            },
        );
        refused(
            "an inner box one step short",
            "node 0 slot 1: the triangles below it span",
            &|t| {
                t.nodes[0][1].bbox.as_mut().unwrap().lo.y = 2f32.next_up();
            },
        );
        refused("a NaN vertex", "triangle 2 (prim 2) lies outside", &|t| {
            t.tris[2].v1[0] = f32::NAN;
        });
        refused(
            "a triangle in two leaves",
            "node 1 slot 0: triangle 1 is in two leaves",
            &|t| {
                t.nodes[1][0].child = Child::Tris { first: 1, count: 2 };
            },
        );
        refused(
            "a triangle in no leaf",
            "triangles 1..2 are in no leaf",
            &|t| {
                t.nodes[0][0].child = Child::Tris { first: 0, count: 1 };
            },
        );
        refused(
            "a leaf past the end",
            "node 1 slot 0 refers to triangles 2..4 of 3",
            &|t| {
                t.nodes[1][0].child = Child::Tris { first: 2, count: 2 };
            },
        );
        // Each root covers every triangle (threaded's copies): a second root over node 1
        // leaves triangles 0..2 out.
        refused(
            "a root short of triangles",
            "triangles 0..2 are in no leaf under node 1",
            &|t| {
                t.roots.push(slot(2.0, 3.0, Child::Node(1), At::Node(1)));
            },
        );
        // A root box is checked too; nothing below is held by any box.
        refused(
            "a root box",
            "the root: the triangles below it span",
            &|t| {
                t.roots[0].bbox = Some(Aabb::EMPTY);
            },
        );
        // A triangle split in space: two records of prim 0, each leaf bounding one side of
        // the plane x = 1. Together they cover it; a leaf one step short on x does not.
        let t = LeafTri::new(
            [
                Vec3::ZERO,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
            ],
            0,
        );
        let boxed = |lo: [f32; 3], hi: [f32; 3], first, at| Slot {
            bbox: Some(Aabb {
                lo: Vec3::from(lo),
                hi: Vec3::from(hi),
            }),
            child: Child::Tris { first, count: 1 },
            at,
        };
        let split = |right_lo: f32| Lists {
            roots: node_zero().collect(),
            nodes: vec![vec![
                boxed([0.0; 3], [1.0, 2.0, 0.0], 0, At::Slot { node: 0, slot: 0 }),
                boxed(
                    [right_lo, 0.0, 0.0],
                    [2.0, 1.0, 0.0],
                    1,
                    At::Slot { node: 0, slot: 1 },
                ),
            ]],
            tris: vec![t, t],
        };
        check_boxes(&split(1.0)).unwrap();
        let e = check_boxes(&split(1f32.next_up())).unwrap_err();
        assert!(
            e.contains("triangle 0 (prim 0) lies outside the box")
                && e.contains("the boxes of its 2 leaves do not cover it together"),
            "{e}"
        );
        // A leaf box rounded out past its parent's (cwbvh's quantised boxes) may hold a split
        // triangle whole: what counts is the boxes on the way there, which hold a part.
        let rounded = Lists {
            roots: node_zero().collect(),
            nodes: vec![
                vec![
                    Slot {
                        child: Child::Node(1),
                        ..boxed([0.0; 3], [1.0, 2.0, 0.0], 0, At::Slot { node: 0, slot: 0 })
                    },
                    boxed(
                        [1.0, 0.0, 0.0],
                        [2.0, 1.0, 0.0],
                        1,
                        At::Slot { node: 0, slot: 1 },
                    ),
                ],
                vec![boxed(
                    [0.0; 3],
                    [2.0, 2.0, 0.0],
                    0,
                    At::Slot { node: 1, slot: 0 },
                )],
            ],
            tris: vec![t, t],
        };
        check_boxes(&rounded).unwrap();
        let empty = Lists {
            roots: vec![slot(
                0.0,
                0.0,
                Child::Tris { first: 0, count: 0 },
                At::Node(0),
            )],
            nodes: Vec::new(),
            tris: Vec::new(),
        };
        check_boxes(&empty).unwrap();
    }
}
