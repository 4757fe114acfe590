//! PLOC, parallel locally-ordered clustering (Meister & Bittner 2018): primitives sorted
//! along a Morton curve start as one cluster each; every round, each cluster finds the
//! cluster within [`RADIUS`] places on the curve whose union box has the least surface area,
//! and mutual nearest neighbours merge into a new node. Every round is data-parallel (the
//! neighbour search, the merges, the compaction), and rounds shrink the cluster list fast,
//! so it suits big scenes. Nodes are numbered by a prefix sum over the merges: the tree is
//! the same on any number of threads.
//!
//! The clustered tree has one primitive per leaf; a bottom-up pass then makes a subtree a
//! leaf wherever the SAH prefers it (the same rule as the other builders). A tree deeper than
//! `max_depth`, or rounds that merge too little to finish in time (both only on pathological
//! input), are not kept: the binned builder, which honours the cap, builds it instead.

use rayon::prelude::*;

use super::cluster_tree::{to_node, Clusters};
use super::prim_ref::{box_area, BoxA};
use super::prims::{Prims, PARALLEL_MIN};
use super::tree::Node;
use super::BuildOptions;
use crate::geometry::Aabb;

/// Places on either side of a cluster searched for its nearest neighbour (the paper's 16
/// gives a little better trees at twice the search time).
pub const RADIUS: usize = 8;

/// Bits per axis of the Morton code.
const BITS: u32 = 21;

/// Spreads the low 21 bits of `v` to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The 63-bit Morton code of a centroid in the cube around the centroid bounds (one scale
/// for all axes: a flat scene's thin axis must not count as much as its wide ones).
fn morton(c: glam::Vec3, cbox: &Aabb) -> u64 {
    let side = cbox.extent().max_element();
    let scale = (1u32 << BITS) as f32 - 1.0;
    let q = |a: usize| {
        let t = if side > 0.0 {
            ((c[a] - cbox.lo[a]) / side).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (t * scale) as u64
    };
    spread(q(0)) | spread(q(1)) << 1 | spread(q(2)) << 2
}

pub(crate) fn build(prims: &Prims, opts: &BuildOptions) -> Option<(Node, Vec<u32>)> {
    let n = prims.len();
    let par = opts.parallel;
    let cbox = (0..n as u32).fold(Aabb::EMPTY, |b, i| b.grow(prims.centroid(i)));
    // Morton order; the sort is stable and starts in index order, so equal codes stay in
    // index order.
    let mut keys: Vec<(u64, u32)> = (0..n as u32)
        .map(|i| (morton(prims.centroid(i), &cbox), i))
        .collect();
    radsort::sort_by_key(&mut keys, |k| k.0);
    let mut tree = Clusters {
        bbox: (0..n as u32).map(|i| prims.bbox(i)).collect(),
        kids: vec![[u32::MAX; 2]; n],
    };
    tree.bbox.reserve(n.saturating_sub(1));
    tree.kids.reserve(n.saturating_sub(1));
    let ids: Vec<u32> = keys.into_iter().map(|(_, i)| i).collect();
    let boxes = ids
        .iter()
        .map(|&k| BoxA::from(tree.bbox[k as usize]))
        .collect();
    // Buffers reused round after round: fresh ones would be faulted in every round.
    let mut now = Round { ids, boxes };
    let mut next = Round {
        ids: Vec::with_capacity(n),
        boxes: Vec::with_capacity(n),
    };
    let mut nn = Vec::with_capacity(n);
    while now.ids.len() > 1 {
        let before = now.ids.len();
        round(&mut tree, &now, &mut nn, &mut next, par);
        std::mem::swap(&mut now, &mut next);
        // Typical rounds merge a third of the clusters; one that merges under 1/64 of them
        // (a pathological input) would make the rounds quadratic.
        if before - now.ids.len() < (before / 64).max(1) {
            log::warn!("PLOC stalled at {before} clusters: built with binned SAH");
            return None;
        }
    }
    to_node("PLOC", &tree, now.ids[0], n, opts)
}

/// The clusters of a round in curve order: their nodes and their boxes (in SIMD lanes, so
/// the search streams through them).
struct Round {
    ids: Vec<u32>,
    boxes: Vec<BoxA>,
}

/// One round: nearest neighbours (into `nn`), merges of mutual pairs, the next clusters.
fn round(tree: &mut Clusters, now: &Round, nn: &mut Vec<u32>, next: &mut Round, par: bool) {
    let c = now.ids.len();
    let boxes = &now.boxes;
    // Pairs are ordered by distance, then by how far apart they lie on the curve, then by
    // the parity and the place of their first cluster: one total order on pairs, the same
    // seen from either end, so the least pair of all is always mutual (a round merges at
    // least once) and equal boxes pair up as (0, 1), (2, 3), … instead of all choosing 0.
    let nearest = |i: usize| {
        let (lo, hi) = (i.saturating_sub(RADIUS), (i + RADIUS).min(c - 1));
        let key = |j: usize| {
            let first = i.min(j);
            (i.abs_diff(j), first % 2, first)
        };
        let mut best = (f32::INFINITY, usize::MAX);
        for j in (lo..=hi).filter(|&j| j != i) {
            let d = box_area(boxes[i].union(boxes[j]));
            // The first candidate is taken whatever its distance (a NaN box's is NaN, above
            // +∞ in the total order): every cluster names a neighbour.
            let better = best.1 == usize::MAX
                || match d.total_cmp(&best.0) {
                    std::cmp::Ordering::Less => true,
                    std::cmp::Ordering::Equal => key(j) < key(best.1),
                    std::cmp::Ordering::Greater => false,
                };
            if better {
                best = (d, j);
            }
        }
        best.1 as u32
    };
    if par && c >= PARALLEL_MIN {
        (0..c).into_par_iter().map(nearest).collect_into_vec(nn);
    } else {
        nn.clear();
        nn.extend((0..c).map(nearest));
    }
    // i merges with j = nn[i] when they are each other's nearest; the lower index holds the
    // new node, the higher one leaves the list.
    let base = tree.bbox.len() as u32;
    next.ids.clear();
    next.boxes.clear();
    let mut made = 0u32;
    for i in 0..c {
        let j = nn[i] as usize;
        let mutual = nn[j] as usize == i;
        if mutual && j < i {
            continue;
        }
        if mutual {
            let merged = boxes[i].union(boxes[j]);
            tree.bbox.push(merged.aabb());
            tree.kids.push([now.ids[i], now.ids[j]]);
            next.ids.push(base + made);
            next.boxes.push(merged);
            made += 1;
        } else {
            next.ids.push(now.ids[i]);
            next.boxes.push(boxes[i]);
        }
    }
}
