//! The SAH kd-tree build of Wald & Havran 2006, the O(N log N) variant: every triangle's
//! (clipped) bounds give start, end or planar events on each axis; the three event lists are
//! sorted once at the root and kept sorted through every split — events of triangles that
//! fall on one side are filtered in order (flags classify each triangle left, right or both),
//! and only the triangles that straddle the plane are clipped to each child cell, their new
//! events sorted (few) and merged in.
//!
//! The split is the cheapest of all event positions strictly inside the cell on all three
//! axes, with triangles lying in the plane put on the cheaper side:
//! C = λ·(K_T + K_I·(A_L/A·N_L + A_R/A·N_R)), λ = the empty bonus when a side is empty, 1
//! otherwise. A node is a leaf when K_I·N ≤ every split's cost, or at the depth cap.
//!
//! Memory: the references made so far (one per triangle at the root, plus one per triangle
//! a split duplicates) are counted across threads; the build stops with an error as soon as
//! its estimate, [`BYTES_PER_REF`] per reference, passes the budget.

use std::cell::RefCell;
use std::cmp::Ordering;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering as AtomicOrdering};
use std::sync::Mutex;

use rayon::prelude::*;

use super::{KdOptions, KdTri, Node, NODE_FIELD_MAX};
use crate::error::{Error, Result};
use crate::geometry::clip_bounds;
use crate::geometry::{Aabb, Triangle};
use crate::limits::available_memory;
use crate::util::human_bytes;

/// Event kinds, in the order events at one position are swept.
const END: u32 = 0;
const PLANAR: u32 = 1;
const START: u32 = 2;

/// Triangle classes while a node is split.
const LEFT: u8 = 0;
const RIGHT: u8 = 1;
const BOTH: u8 = 2;

/// Build memory per triangle reference: up to six 8-byte events while its node is pending,
/// its 4-byte entry in the finished build, and its 48-byte leaf triangle in the tree.
const BYTES_PER_REF: u64 = 6 * 8 + 4 + 48;

/// Build memory per triangle beyond its references: the 40-byte triangle and a flag byte
/// per thread.
const BYTES_PER_TRI: u64 = 40 + 8;

/// Nodes with at least this many triangles build their two subtrees in parallel.
const PARALLEL_MIN: usize = 4096;

/// What to do instead, when the build is refused.
const HINT: &str = "raise KdOptions::max_memory, lower KdOptions::max_depth, or use the BVH \
                    (its size is linear in the triangles)";

/// A bound of one triangle on one axis: position, and (triangle << 2 | kind).
#[derive(Clone, Copy, Debug)]
struct Event {
    pos: f32,
    key: u32,
}

impl Event {
    fn new(pos: f32, tri: u32, kind: u32) -> Event {
        // + 0.0 turns −0 into +0: equal positions compare equal and sort together.
        Event {
            pos: pos + 0.0,
            key: (tri << 2) | kind,
        }
    }
    #[inline(always)]
    fn tri(self) -> usize {
        (self.key >> 2) as usize
    }
    #[inline(always)]
    fn kind(self) -> u32 {
        self.key & 3
    }
}

/// Sweep order: position, then end < planar < start, then triangle (a total order, so the
/// unstable sorts are deterministic).
fn order(a: &Event, b: &Event) -> Ordering {
    a.pos
        .partial_cmp(&b.pos)
        .unwrap_or(Ordering::Equal)
        .then(a.kind().cmp(&b.kind()))
        .then(a.key.cmp(&b.key))
}

/// A node's events, one sorted list per axis.
type Events = [Vec<Event>; 3];

/// Appends the events of a triangle whose bounds in the cell are `b`.
fn push_events(ev: &mut Events, tri: u32, b: &Aabb) {
    for (k, list) in ev.iter_mut().enumerate() {
        if b.lo[k] == b.hi[k] {
            list.push(Event::new(b.lo[k], tri, PLANAR));
        } else {
            list.push(Event::new(b.lo[k], tri, START));
            list.push(Event::new(b.hi[k], tri, END));
        }
    }
}

/// Merges two sorted lists.
fn merge(a: Vec<Event>, b: Vec<Event>) -> Vec<Event> {
    if b.is_empty() {
        return a;
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if order(&b[j], &a[i]) == Ordering::Less {
            out.push(b[j]);
            j += 1;
        } else {
            out.push(a[i]);
            i += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The chosen split of a node.
#[derive(Clone, Copy, Debug)]
struct Split {
    axis: usize,
    pos: f32,
    /// Triangles lying in the plane go left (else right).
    planar_left: bool,
    cost: f64,
}

/// A child node waiting to be built.
struct Child {
    cell: Aabb,
    n: usize,
    ev: Events,
}

/// The finished tree (or subtree, indices relative to its own arrays).
#[derive(Default)]
pub(super) struct Built {
    pub(super) nodes: Vec<Node>,
    pub(super) refs: Vec<u32>,
    pub(super) max_depth: usize,
}

/// The build stopped; the reason is in [`Ctx::error`].
struct Stop;

/// What every node of one build shares.
struct Ctx<'a> {
    tris: &'a [KdTri],
    kt: f64,
    ki: f64,
    bonus: f64,
    cap: usize,
    parallel: bool,
    /// Bytes the build may use, and what that limit is, for the error.
    budget: u64,
    budget_name: &'static str,
    /// References made so far (= the finished tree's references once the build is done).
    refs: AtomicU64,
    nodes: AtomicU64,
    /// Set with `error`: every branch stops at its next node.
    stop: AtomicBool,
    error: Mutex<Option<Error>>,
}

thread_local! {
    /// One class byte per triangle, per thread: set and read within one node's split.
    static FLAGS: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

impl Ctx<'_> {
    fn fail(&self, e: Error) -> Stop {
        let mut slot = self.error.lock().unwrap_or_else(|p| p.into_inner());
        slot.get_or_insert(e);
        self.stop.store(true, AtomicOrdering::Relaxed);
        Stop
    }

    fn stopped(&self) -> bool {
        self.stop.load(AtomicOrdering::Relaxed)
    }

    /// The refusal: "needs {amount} {bytes} of memory{detail}, more than the budget".
    fn too_big(&self, amount: &str, bytes: u64, detail: &str) -> Error {
        Error::Usage(format!(
            "a kd-tree over {} triangles needs {amount} {} of memory{detail}, more than {} \
             ({}): {HINT}",
            self.tris.len(),
            human_bytes(bytes),
            human_bytes(self.budget),
            self.budget_name,
        ))
    }

    /// Counts `added` references and 2 nodes; stops when the estimate passes the budget.
    fn account(&self, added: u64, depth: usize) -> std::result::Result<(), Stop> {
        let refs = self.refs.fetch_add(added, AtomicOrdering::Relaxed) + added;
        let nodes = self.nodes.fetch_add(2, AtomicOrdering::Relaxed) + 2;
        let bytes = refs
            .saturating_mul(BYTES_PER_REF)
            .saturating_add(nodes.saturating_mul(8))
            .saturating_add(self.tris.len() as u64 * BYTES_PER_TRI);
        if bytes > self.budget {
            let detail =
                format!(" ({refs} triangle references so far, splitting at depth {depth})");
            return Err(self.fail(self.too_big("more than", bytes, &detail)));
        }
        if refs > u32::MAX as u64 || nodes > NODE_FIELD_MAX as u64 {
            return Err(self.fail(Error::Usage(format!(
                "a kd-tree over {} triangles needs more than {} references or {} nodes: {HINT}",
                self.tris.len(),
                u32::MAX,
                NODE_FIELD_MAX
            ))));
        }
        Ok(())
    }

    /// The cheapest split of a node, when it is cheaper than a leaf.
    fn find_split(&self, cell: &Aabb, n: usize, ev: &Events) -> Option<Split> {
        let e = (cell.hi - cell.lo).as_dvec3();
        let area = |k: usize, ek: f64| {
            let (e1, e2) = (e[(k + 1) % 3], e[(k + 2) % 3]);
            2.0 * (e1 * e2 + ek * (e1 + e2))
        };
        let a = area(0, e.x);
        if a.is_nan() || a <= 0.0 {
            return None;
        }
        let leaf_cost = self.ki * n as f64;
        let mut best: Option<Split> = None;
        let mut best_cost = leaf_cost;
        let cost = |pl: f64, nl: usize, pr: f64, nr: usize| {
            let lambda = if nl == 0 || nr == 0 { self.bonus } else { 1.0 };
            lambda * (self.kt + self.ki * (pl * nl as f64 + pr * nr as f64))
        };
        for (k, list) in ev.iter().enumerate() {
            let (lo, hi) = (cell.lo[k], cell.hi[k]);
            if lo >= hi {
                continue;
            }
            let (mut nl, mut nr) = (0usize, n);
            let mut i = 0;
            while i < list.len() {
                let p = list[i].pos;
                let mut count = [0usize; 3];
                for kind in [END, PLANAR, START] {
                    while i < list.len() && list[i].pos == p && list[i].kind() == kind {
                        count[kind as usize] += 1;
                        i += 1;
                    }
                }
                let np = count[PLANAR as usize];
                nr -= np + count[END as usize];
                // A plane on the cell's face would make a child equal to its parent.
                if p > lo && p < hi {
                    let pl = area(k, p as f64 - lo as f64) / a;
                    let pr = area(k, hi as f64 - p as f64) / a;
                    let left = cost(pl, nl + np, pr, nr);
                    let right = cost(pl, nl, pr, nr + np);
                    let (c, planar_left) = if left <= right {
                        (left, true)
                    } else {
                        (right, false)
                    };
                    if c < best_cost {
                        best_cost = c;
                        best = Some(Split {
                            axis: k,
                            pos: p,
                            planar_left,
                            cost: c,
                        });
                    }
                }
                nl += count[START as usize] + np;
            }
        }
        best.filter(|s| s.cost < leaf_cost)
    }

    /// Classifies the node's triangles, filters its sorted events into the children, clips
    /// the straddling triangles to each child and merges their new events.
    fn split(
        &self,
        cell: &Aabb,
        n: usize,
        ev: Events,
        s: &Split,
        depth: usize,
    ) -> std::result::Result<(Child, Child), Stop> {
        let (k, p) = (s.axis, s.pos);
        let mut lcell = *cell;
        lcell.hi[k] = p;
        let mut rcell = *cell;
        rcell.lo[k] = p;
        let mut both = Vec::new();
        let mut el: Events = Default::default();
        let mut er: Events = Default::default();
        let (mut nl, mut nr) = (0usize, 0usize);
        FLAGS.with(|f| {
            let mut flags = f.borrow_mut();
            if flags.len() < self.tris.len() {
                flags.resize(self.tris.len(), BOTH);
            }
            for e in &ev[k] {
                if e.kind() != END {
                    flags[e.tri()] = BOTH;
                }
            }
            for e in &ev[k] {
                let class = match e.kind() {
                    END if e.pos <= p => LEFT,
                    START if e.pos >= p => RIGHT,
                    PLANAR if e.pos < p || (e.pos == p && s.planar_left) => LEFT,
                    PLANAR => RIGHT,
                    _ => continue,
                };
                flags[e.tri()] = class;
            }
            for e in &ev[k] {
                if e.kind() != END {
                    match flags[e.tri()] {
                        LEFT => nl += 1,
                        RIGHT => nr += 1,
                        _ => both.push(e.tri() as u32),
                    }
                }
            }
            for j in 0..3 {
                let (l, r) = (&mut el[j], &mut er[j]);
                l.reserve(ev[j].len() * nl / n.max(1) + 2 * both.len());
                r.reserve(ev[j].len() * nr / n.max(1) + 2 * both.len());
                for &e in &ev[j] {
                    match flags[e.tri()] {
                        LEFT => l.push(e),
                        RIGHT => r.push(e),
                        _ => {}
                    }
                }
            }
        });
        drop(ev);
        let mut newl: Events = Default::default();
        let mut newr: Events = Default::default();
        for &t in &both {
            let tri = Triangle {
                v: self.tris[t as usize].v,
            };
            let (mut bl, mut br) = (clip_bounds(&tri, &lcell), clip_bounds(&tri, &rcell));
            if bl.is_none() && br.is_none() {
                // Not reachable (it straddles the plane); never lose a triangle anyway.
                let tb = tri.bbox();
                let clamp = |c: &Aabb| Aabb {
                    lo: tb.lo.clamp(c.lo, c.hi),
                    hi: tb.hi.clamp(c.lo, c.hi),
                };
                (bl, br) = (Some(clamp(&lcell)), Some(clamp(&rcell)));
            }
            if let Some(b) = bl {
                push_events(&mut newl, t, &b);
                nl += 1;
            }
            if let Some(b) = br {
                push_events(&mut newr, t, &b);
                nr += 1;
            }
        }
        self.account((nl + nr - n) as u64, depth)?;
        let finish = |old: &mut Events, new: Events| {
            for (o, mut x) in old.iter_mut().zip(new) {
                x.sort_unstable_by(order);
                *o = merge(std::mem::take(o), x);
            }
        };
        finish(&mut el, newl);
        finish(&mut er, newr);
        Ok((
            Child {
                cell: lcell,
                n: nl,
                ev: el,
            },
            Child {
                cell: rcell,
                n: nr,
                ev: er,
            },
        ))
    }

    /// The split to make at this node, or None for a leaf.
    fn decide(&self, c: &Child, depth: usize) -> Option<Split> {
        if depth >= self.cap || c.n == 0 {
            None
        } else {
            self.find_split(&c.cell, c.n, &c.ev)
        }
    }

    /// Appends a leaf of the node's triangles (ascending).
    fn leaf(&self, c: &Child, depth: usize, out: &mut Built) -> std::result::Result<(), Stop> {
        let first = out.refs.len();
        out.refs.extend(
            c.ev[0]
                .iter()
                .filter(|e| e.kind() != END)
                .map(|e| e.tri() as u32),
        );
        out.refs[first..].sort_unstable();
        let count = out.refs.len() - first;
        if count > NODE_FIELD_MAX || out.refs.len() > u32::MAX as usize {
            return Err(self.fail(Error::Usage(format!(
                "a kd-tree leaf of {count} triangles is more than {NODE_FIELD_MAX}: {HINT}"
            ))));
        }
        out.nodes.push(Node::leaf(first as u32, count as u32));
        out.max_depth = out.max_depth.max(depth);
        Ok(())
    }

    /// Builds the subtree of `c` serially, appending to `out` (depth-first, the child below
    /// the split right after its parent).
    fn grow(&self, c: Child, depth: usize, out: &mut Built) -> std::result::Result<(), Stop> {
        if self.stopped() {
            return Err(Stop);
        }
        let Some(s) = self.decide(&c, depth) else {
            return self.leaf(&c, depth, out);
        };
        let (l, r) = self.split(&c.cell, c.n, c.ev, &s, depth)?;
        let me = out.nodes.len();
        out.nodes.push(Node::leaf(0, 0));
        self.grow(l, depth + 1, out)?;
        let above = out.nodes.len();
        self.grow(r, depth + 1, out)?;
        let (lo, hi) = (out.nodes[me + 1], out.nodes[above]);
        out.nodes[me] = Node::inner(s.axis, s.pos, above as u32, lo, hi);
        Ok(())
    }

    /// Builds the subtree of `c`, the two children of a big node in parallel; the result is
    /// the serial one's.
    fn grow_parallel(&self, c: Child, depth: usize) -> std::result::Result<Built, Stop> {
        let mut out = Built::default();
        if !self.parallel || c.n < PARALLEL_MIN {
            self.grow(c, depth, &mut out)?;
            return Ok(out);
        }
        if self.stopped() {
            return Err(Stop);
        }
        let Some(s) = self.decide(&c, depth) else {
            self.leaf(&c, depth, &mut out)?;
            return Ok(out);
        };
        let (l, r) = self.split(&c.cell, c.n, c.ev, &s, depth)?;
        let (a, b) = rayon::join(
            || self.grow_parallel(l, depth + 1),
            || self.grow_parallel(r, depth + 1),
        );
        let (a, b) = (a?, b?);
        let above = 1 + a.nodes.len();
        out.nodes.reserve(above + b.nodes.len());
        out.nodes.push(Node::inner(
            s.axis,
            s.pos,
            above as u32,
            a.nodes[0],
            b.nodes[0],
        ));
        out.nodes.extend(a.nodes.iter().map(|n| n.shifted(1, 0)));
        let refs = a.refs.len() as u32;
        out.nodes
            .extend(b.nodes.iter().map(|n| n.shifted(above as u32, refs)));
        out.refs = a.refs;
        out.refs.extend_from_slice(&b.refs);
        out.max_depth = a.max_depth.max(b.max_depth);
        Ok(out)
    }
}

/// Builds the tree over `tris` (positions in `tris` are the references) in the cell `bounds`.
pub(super) fn build(tris: &[KdTri], bounds: &Aabb, opts: &KdOptions, cap: usize) -> Result<Built> {
    let n = tris.len();
    let (budget, budget_name) = match opts.max_memory {
        Some(b) => (b, "the limit, KdOptions::max_memory"),
        None => (
            available_memory().unwrap_or(u64::MAX),
            "the memory available",
        ),
    };
    let ctx = Ctx {
        tris,
        kt: opts.traversal_cost.max(0.0) as f64,
        ki: opts.intersection_cost.max(0.0) as f64,
        bonus: opts.empty_bonus.clamp(0.0, 1.0) as f64,
        cap,
        parallel: opts.parallel,
        budget,
        budget_name,
        refs: AtomicU64::new(0),
        nodes: AtomicU64::new(0),
        stop: AtomicBool::new(false),
        error: Mutex::new(None),
    };
    if n > NODE_FIELD_MAX {
        return Err(Error::Usage(format!(
            "a kd-tree holds at most {NODE_FIELD_MAX} triangles, this mesh has {n}: use the BVH"
        )));
    }
    // Up front: the root's references and triangles.
    let upfront = (n as u64) * (BYTES_PER_REF + BYTES_PER_TRI) + 8;
    if upfront > budget {
        return Err(ctx.too_big(
            "at least",
            upfront,
            " (its triangles and one reference each)",
        ));
    }
    ctx.refs.store(n as u64, AtomicOrdering::Relaxed);
    let mut ev: Events = Default::default();
    for list in ev.iter_mut() {
        list.reserve(2 * n);
    }
    for (i, t) in tris.iter().enumerate() {
        push_events(&mut ev, i as u32, &Triangle { v: t.v }.bbox());
    }
    for list in ev.iter_mut() {
        if opts.parallel {
            list.par_sort_unstable_by(order);
        } else {
            list.sort_unstable_by(order);
        }
    }
    let root = Child {
        cell: *bounds,
        n,
        ev,
    };
    let result = if n == 0 {
        Ok(Built {
            nodes: vec![Node::leaf(0, 0)],
            ..Built::default()
        })
    } else {
        ctx.grow_parallel(root, 0)
    };
    result.map_err(|Stop| {
        ctx.error
            .into_inner()
            .unwrap_or_else(|p| p.into_inner())
            .unwrap_or_else(|| Error::Usage("the kd-tree build stopped".into()))
    })
}
