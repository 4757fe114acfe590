//! Which of a wide node's 8 slots each child takes (Ylitie et al. 2017, §4.2). A ray in
//! octant o (bit k set when its direction is negative on axis k) visits the hit children in
//! slot order o, o^1, o^2, …, o^7 (traversal takes the highest bit of slot ^ (7 ^ o)), so
//! slot o should hold the child met first along octant o's diagonal. The paper solves the
//! assignment by auction; this is the greedy approximation it compares against: repeatedly
//! the cheapest (child, free slot) pair, cost = the child centre's offset from the parent
//! centre along the slot's diagonal. Deterministic (first minimum in index order).

use glam::Vec3;

use crate::geometry::Aabb;

use super::WIDTH;

/// The diagonal direction of octant `o`: −1 on axis k when bit k of `o` is set.
fn diagonal(o: usize) -> Vec3 {
    let sign = |k: usize| if o >> k & 1 == 1 { -1.0 } else { 1.0 };
    Vec3::new(sign(0), sign(1), sign(2))
}

/// Every (child, slot) pair as a bit of a `u64` mask: bit `c * WIDTH + s`.
const _: () = assert!(WIDTH * WIDTH == 64);
/// A child's pairs (shifted by `c * WIDTH`).
const CHILD_PAIRS: u64 = (1 << WIDTH) - 1;
/// A slot's pairs (shifted by `s`).
const SLOT_PAIRS: u64 = u64::MAX / CHILD_PAIRS;

/// For each slot, the index in `children` of the child it holds (at most [`WIDTH`]
/// children, all inside `parent`).
pub(crate) fn assign(parent: &Aabb, children: &[Aabb]) -> [Option<usize>; WIDTH] {
    let centre = parent.center();
    let n = children.len().min(WIDTH);
    // Every (child, slot) cost once, rather than once per round.
    let mut cost = [0.0f32; WIDTH * WIDTH];
    for (c, row) in cost.chunks_exact_mut(WIDTH).enumerate().take(n) {
        let offset = children[c].center() - centre;
        for (s, x) in row.iter_mut().enumerate() {
            *x = offset.dot(diagonal(s));
        }
    }
    // The pairs still open (child unplaced, slot free), walked in index order (child, then
    // slot) by their set bits: the first smallest cost wins, as in a scan of every pair.
    let mut open = if n == WIDTH {
        u64::MAX
    } else {
        (1u64 << (n * WIDTH)) - 1
    };
    let mut slots = [None; WIDTH];
    while open != 0 {
        let first = open.trailing_zeros() as usize;
        let mut best = (cost[first], first);
        let mut rest = open & (open - 1);
        while rest != 0 {
            let i = rest.trailing_zeros() as usize;
            if cost[i] < best.0 {
                best = (cost[i], i);
            }
            rest &= rest - 1;
        }
        let (c, s) = (best.1 / WIDTH, best.1 % WIDTH);
        slots[s] = Some(c);
        open &= !(CHILD_PAIRS << (c * WIDTH)) & !(SLOT_PAIRS << s);
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use proptest::prelude::*;

    /// The greedy assignment as first written: each round scans every (unplaced child,
    /// free slot) pair for the first smallest cost.
    fn scanned(parent: &Aabb, children: &[Aabb]) -> [Option<usize>; WIDTH] {
        let centre = parent.center();
        let n = children.len().min(WIDTH);
        let cost = |c: usize, s: usize| (children[c].center() - centre).dot(diagonal(s));
        let mut slots = [None; WIDTH];
        let mut placed = [false; WIDTH];
        for _ in 0..n {
            let mut best: Option<(f32, usize, usize)> = None;
            for c in (0..n).filter(|&c| !placed[c]) {
                for s in (0..WIDTH).filter(|&s| slots[s].is_none()) {
                    let x = cost(c, s);
                    if best.is_none_or(|(b, _, _)| x < b) {
                        best = Some((x, c, s));
                    }
                }
            }
            if let Some((_, c, s)) = best {
                slots[s] = Some(c);
                placed[c] = true;
            }
        }
        slots
    }

    proptest! {
        /// The same slots as the scan of every pair, for any number of children, with
        /// coarse coordinates so that equal costs (and −0 against +0) are common.
        #[test]
        fn the_mask_walk_assigns_as_the_scan(
            boxes in prop::collection::vec(
                (prop::array::uniform3(-4i8..4), prop::array::uniform3(0i8..3)),
                0..=WIDTH,
            ),
        ) {
            let children: Vec<Aabb> = boxes
                .iter()
                .map(|(lo, size)| {
                    let lo = Vec3::from(lo.map(|x| x as f32 * 0.5));
                    Aabb { lo, hi: lo + Vec3::from(size.map(|x| x as f32)) }
                })
                .collect();
            let parent = children.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
            prop_assert_eq!(assign(&parent, &children), scanned(&parent, &children));
        }
    }
}
