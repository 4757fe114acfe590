//! The part of a triangle inside a box: Sutherland–Hodgman clipping of the triangle's
//! polygon against the box's six planes; the bounds of what is left (the kd-tree's and the
//! spatial splits' references) and its area (the end-point overlap metric).
//!
//! The bounds are conservative: the cell is first grown by a margin above the clipping's rounding, the
//! result's bounds grown by it again, then cut back to the triangle's own (exact) bounds and
//! to the cell. So a triangle is never left out of a cell it touches (a sliver too thin to
//! see is kept, at the cost of an extra reference), and a triangle whose vertex lies exactly
//! on a split plane keeps that exact coordinate as its bound.

use glam::Vec3;

use crate::geometry::{Aabb, Triangle};

/// Relative margin, 2⁻¹⁸ (32 f32 ulps) of the triangle's largest coordinate per axis: each
/// clip interpolates between (already clipped) points with a few ulps of error, six clips
/// at most.
const MARGIN: f32 = 1.0 / 262_144.0;

/// A triangle clipped by six planes has at most 3 + 6 vertices.
const MAX_VERTS: usize = 9;

/// A convex polygon of at most [`MAX_VERTS`] vertices.
struct Poly {
    v: [Vec3; MAX_VERTS],
    n: usize,
}

impl Poly {
    /// Keeps the part with `sign·(p[axis] − c) ≥ 0`; the new vertices lie exactly on the
    /// plane in `axis`.
    fn clip(&self, axis: usize, c: f32, keep_above: bool) -> Poly {
        let inside = |p: Vec3| {
            if keep_above {
                p[axis] >= c
            } else {
                p[axis] <= c
            }
        };
        let mut out = Poly {
            v: [Vec3::ZERO; MAX_VERTS],
            n: 0,
        };
        for i in 0..self.n {
            let a = self.v[i];
            let b = self.v[(i + 1) % self.n];
            let (ia, ib) = (inside(a), inside(b));
            if ia && out.n < MAX_VERTS {
                out.v[out.n] = a;
                out.n += 1;
            }
            if ia != ib && out.n < MAX_VERTS {
                // a and b lie on opposite sides, so the denominator is not zero.
                let s = ((c - a[axis]) / (b[axis] - a[axis])).clamp(0.0, 1.0);
                let mut p = a + (b - a) * s;
                p[axis] = c;
                out.v[out.n] = p;
                out.n += 1;
            }
        }
        out
    }
}

/// The part of `tri` inside the box [`lo`, `hi`]: the triangle clipped by the planes its
/// bounds cross (empty when nothing is left).
fn clipped(tri: &Triangle, lo: Vec3, hi: Vec3) -> Poly {
    let tb = tri.bbox();
    let mut poly = Poly {
        v: [Vec3::ZERO; MAX_VERTS],
        n: 3,
    };
    poly.v[..3].copy_from_slice(&tri.v);
    for axis in 0..3 {
        if tb.lo[axis] < lo[axis] {
            poly = poly.clip(axis, lo[axis], true);
        }
        if tb.hi[axis] > hi[axis] {
            poly = poly.clip(axis, hi[axis], false);
        }
        if poly.n == 0 {
            break;
        }
    }
    poly
}

/// Bounds of the part of `tri` inside `cell` (a subset of both the cell and the triangle's
/// bounds), or `None` when the triangle misses the cell by more than the margin.
pub(crate) fn clip_bounds(tri: &Triangle, cell: &Aabb) -> Option<Aabb> {
    let tb = tri.bbox();
    let margin = tb.lo.abs().max(tb.hi.abs()) * MARGIN;
    let poly = clipped(tri, cell.lo - margin, cell.hi + margin);
    if poly.n == 0 {
        return None;
    }
    let b = Aabb::from_points(&poly.v[..poly.n]);
    // Grown by the margin, cut back to the exact triangle bounds, then clamped into the cell
    // (clamping is monotone, so lo ≤ hi stays true).
    let lo = (b.lo - margin).max(tb.lo).clamp(cell.lo, cell.hi);
    let hi = (b.hi + margin).min(tb.hi).clamp(cell.lo, cell.hi);
    Some(Aabb { lo, hi })
}

/// Area of the part of `tri` inside `cell` (exact clipping, no margin: a metric, not a
/// bound). 0 when they do not overlap.
pub(crate) fn clipped_area(tri: &Triangle, cell: &Aabb) -> f64 {
    let poly = clipped(tri, cell.lo, cell.hi);
    // A convex polygon: a fan from its first vertex, in f64.
    let p = |i: usize| poly.v[i].as_dvec3();
    let mut twice = glam::DVec3::ZERO;
    for i in 1..poly.n.saturating_sub(1) {
        twice += (p(i) - p(0)).cross(p(i + 1) - p(0));
    }
    0.5 * twice.length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(lo: [f32; 3], hi: [f32; 3]) -> Aabb {
        Aabb {
            lo: Vec3::from(lo),
            hi: Vec3::from(hi),
        }
    }

    #[test]
    fn the_clipped_area_is_the_part_inside() {
        // The right triangle (0,0)-(2,0)-(0,2), area 2: x ≤ 1 keeps 2 − 0.5 = 1.5; inside
        // a bigger box all of it; beside the hypotenuse nothing.
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        let area = |lo, hi| clipped_area(&t, &cell(lo, hi));
        assert!((area([-1.0; 3], [1.0, 3.0, 1.0]) - 1.5).abs() < 1e-6);
        assert!((area([-1.0; 3], [3.0; 3]) - 2.0).abs() < 1e-6);
        assert_eq!(area([1.5, 1.5, -1.0], [3.0, 3.0, 1.0]), 0.0);
    }

    #[test]
    fn a_triangle_inside_keeps_its_bounds() {
        let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let b = clip_bounds(&t, &cell([-1.0; 3], [2.0; 3])).unwrap();
        assert_eq!(b, t.bbox());
    }

    #[test]
    fn clipping_shrinks_the_bounds_to_the_part_inside() {
        // The triangle (0,0)-(2,0)-(0,2) cut by x ≥ 1.5: the corner x ∈ [1.5, 2], y ≤ 0.5.
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        let b = clip_bounds(&t, &cell([1.5, -1.0, -1.0], [3.0, 3.0, 1.0])).unwrap();
        assert_eq!(b.lo.x, 1.5);
        assert_eq!(b.hi.x, 2.0);
        assert!(b.hi.y >= 0.5 && b.hi.y < 0.5001, "{b:?}");
    }

    #[test]
    fn a_triangle_beside_the_cell_is_dropped_but_one_touching_it_is_kept() {
        // Its bounds overlap the cell, the triangle does not: the cell is in the corner the
        // hypotenuse cuts off.
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        assert!(clip_bounds(&t, &cell([1.5, 1.5, -1.0], [3.0, 3.0, 1.0])).is_none());
        // Touching at the vertex (2, 0): kept, flat at x = 2.
        let b = clip_bounds(&t, &cell([2.0, -1.0, -1.0], [3.0, 1.0, 1.0])).unwrap();
        assert_eq!((b.lo.x, b.hi.x), (2.0, 2.0));
    }
}
