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

/// For each slot, the index in `children` of the child it holds (at most [`WIDTH`]
/// children, all inside `parent`).
pub(crate) fn assign(parent: &Aabb, children: &[Aabb]) -> [Option<usize>; WIDTH] {
    let centre = parent.center();
    let n = children.len().min(WIDTH);
    // Every (child, slot) cost once, rather than once per round.
    let mut cost = [[0.0f32; WIDTH]; WIDTH];
    for (c, row) in cost.iter_mut().enumerate().take(n) {
        let offset = children[c].center() - centre;
        for (s, x) in row.iter_mut().enumerate() {
            *x = offset.dot(diagonal(s));
        }
    }
    let mut slots = [None; WIDTH];
    let mut placed = [false; WIDTH];
    for _ in 0..n {
        let mut best: Option<(f32, usize, usize)> = None;
        for c in (0..n).filter(|&c| !placed[c]) {
            for s in (0..WIDTH).filter(|&s| slots[s].is_none()) {
                let x = cost[c][s];
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
