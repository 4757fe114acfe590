//! The part of a triangle inside a box: Sutherland–Hodgman clipping of the triangle's
//! polygon against the box's six planes; the bounds of what is left (the kd-tree's and the
//! spatial splits' references) and its area (the end-point overlap metric).
//!
//! The bounds are conservative: the cell is first grown by a margin above the clipping's rounding, the
//! result's bounds grown by it again, then cut back to the triangle's own (exact) bounds and
//! to the cell. So a triangle is never left out of a cell it touches (a sliver too thin to
//! see is kept, at the cost of an extra reference), and a triangle whose vertex lies exactly
//! on a split plane keeps that exact coordinate as its bound.

use glam::{DVec3, Vec3};

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

impl Poly {
    /// In one pass: the bounds of the part with `p[axis] ≤ c` (None when empty) and the
    /// part with `p[axis] ≥ c` (vertices on the plane belong to both).
    fn split_off_below(&self, axis: usize, c: f32) -> (Option<Aabb>, Poly) {
        let mut below = Aabb::EMPTY;
        let mut above = Poly {
            v: [Vec3::ZERO; MAX_VERTS],
            n: 0,
        };
        let push = |p: Vec3, above: &mut Poly| {
            if above.n < MAX_VERTS {
                above.v[above.n] = p;
                above.n += 1;
            }
        };
        for i in 0..self.n {
            let a = self.v[i];
            let b = self.v[if i + 1 == self.n { 0 } else { i + 1 }];
            if a[axis] <= c {
                below = below.grow(a);
            }
            if a[axis] >= c {
                push(a, &mut above);
            }
            if (a[axis] < c && b[axis] > c) || (a[axis] > c && b[axis] < c) {
                let s = ((c - a[axis]) / (b[axis] - a[axis])).clamp(0.0, 1.0);
                let mut p = a + (b - a) * s;
                p[axis] = c;
                below = below.grow(p);
                push(p, &mut above);
            }
        }
        ((!below.is_empty()).then_some(below), above)
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

/// The bounds of the parts of `tri` inside `cell` cut, on each axis a, by the planes
/// `cuts[a]` (ascending): `each(a, i, b)` for the part between `cuts[a][i - 1]` and
/// `cuts[a][i]` (the first and last parts reaching the cell's faces). Exact clipping with no
/// margin: an estimate (the spatial split's binning), not a bound.
pub(crate) fn chopped_bounds(
    tri: &Triangle,
    cell: &Aabb,
    cuts: [&[f32]; 3],
    mut each: impl FnMut(usize, usize, Aabb),
) {
    let part = clipped(tri, cell.lo, cell.hi);
    for (axis, cuts) in cuts.into_iter().enumerate() {
        if cuts.is_empty() {
            continue;
        }
        let mut rest = Poly {
            v: part.v,
            n: part.n,
        };
        for (i, &c) in cuts.iter().enumerate() {
            if rest.n == 0 {
                break;
            }
            let (below, above) = rest.split_off_below(axis, c);
            if let Some(b) = below {
                each(axis, i, b);
            }
            rest = above;
        }
        if rest.n > 0 {
            each(axis, cuts.len(), Aabb::from_points(&rest.v[..rest.n]));
        }
    }
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

/// Whether the closed boxes together hold every point of `tri`, up to f64 rounding: the
/// parts of the triangle outside each box in turn (cut off face by face, in f64), dropping a
/// part no wider than 2⁻⁴⁰ of the triangle's largest coordinate across the face that cut it
/// off (a part only touching the face; the face itself stays with the rest). False for a
/// triangle with a non-finite vertex.
pub(crate) fn covered(tri: &Triangle, boxes: &[Aabb]) -> bool {
    if !tri.v.iter().all(|v| v.is_finite()) {
        return false;
    }
    let scale = tri
        .v
        .iter()
        .map(|v| v.abs().max_element())
        .fold(0.0f32, f32::max) as f64;
    let tol = scale * (1.0 / (1u64 << 40) as f64);
    let mut left: Vec<Vec<DVec3>> = vec![tri.v.iter().map(|v| v.as_dvec3()).collect()];
    for b in boxes {
        let mut outside = Vec::new();
        for mut rest in left {
            for axis in 0..3 {
                let (below, r) = split_poly(&rest, axis, b.lo[axis] as f64);
                if width(&below, axis) > tol {
                    outside.push(below);
                }
                let (r, above) = split_poly(&r, axis, b.hi[axis] as f64);
                if width(&above, axis) > tol {
                    outside.push(above);
                }
                rest = r;
            }
        }
        left = outside;
        if left.is_empty() {
            return true;
        }
    }
    false
}

/// A convex polygon's parts with `p[axis] ≤ c` and `p[axis] ≥ c` (f64; vertices on the
/// plane in both).
fn split_poly(poly: &[DVec3], axis: usize, c: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let (mut below, mut above) = (Vec::new(), Vec::new());
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        if a[axis] <= c {
            below.push(a);
        }
        if a[axis] >= c {
            above.push(a);
        }
        if (a[axis] < c && b[axis] > c) || (a[axis] > c && b[axis] < c) {
            let s = ((c - a[axis]) / (b[axis] - a[axis])).clamp(0.0, 1.0);
            let mut p = a + (b - a) * s;
            p[axis] = c;
            below.push(p);
            above.push(p);
        }
    }
    (below, above)
}

/// A polygon's extent on `axis` (−1 when empty).
fn width(poly: &[DVec3], axis: usize) -> f64 {
    let lo = poly.iter().map(|p| p[axis]).fold(f64::INFINITY, f64::min);
    let hi = poly
        .iter()
        .map(|p| p[axis])
        .fold(f64::NEG_INFINITY, f64::max);
    if poly.is_empty() {
        -1.0
    } else {
        hi - lo
    }
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
    fn boxes_that_meet_at_a_plane_cover_a_triangle_and_a_gap_of_one_step_does_not() {
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        // Split at x = 1: the two parts' exact bounds meet on the plane.
        let left = cell([0.0, 0.0, 0.0], [1.0, 2.0, 0.0]);
        let right = cell([1.0, 0.0, 0.0], [2.0, 1.0, 0.0]);
        assert!(covered(&t, &[left, right]));
        assert!(covered(&t, &[right, left]));
        assert!(!covered(&t, &[left]));
        // One f32 step between them: the strip is uncovered.
        let mut gap = right;
        gap.lo.x = 1f32.next_up();
        assert!(!covered(&t, &[left, gap]));
        // The right part's box one step too low in y: its top corner pokes out.
        let mut short = right;
        short.hi.y = 1f32.next_down();
        assert!(!covered(&t, &[left, short]));
        // The bounds clip_bounds gives the two sides of any plane cover the triangle.
        for c in [0.3f32, 1.0, 1.7] {
            let l = clip_bounds(&t, &cell([-1.0; 3], [c, 3.0, 1.0])).unwrap();
            let r = clip_bounds(&t, &cell([c, -1.0, -1.0], [3.0; 3])).unwrap();
            assert!(covered(&t, &[l, r]), "cut at {c}");
        }
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
