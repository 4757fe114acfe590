//! Exact triangle–box overlap: the separating-axis test of Akenine-Möller ("Fast 3D
//! Triangle-Box Overlap Testing", JGT 6(1), 2001), in f64: the box's three face normals, the
//! triangle's normal and the nine cross products of a triangle edge with a box axis.

use glam::DVec3;

/// Whether the triangle `v` overlaps the box of centre `c` and half-extent `h` (touching
/// counts). A degenerate triangle (collinear in f64) is tested as the segment it is.
pub(crate) fn tri_box_overlap(c: DVec3, h: DVec3, v: &[DVec3; 3]) -> bool {
    let p = [v[0] - c, v[1] - c, v[2] - c];
    // The box's face normals: the triangle's bounds against the box.
    let lo = p[0].min(p[1]).min(p[2]);
    let hi = p[0].max(p[1]).max(p[2]);
    if lo.cmpgt(h).any() || hi.cmplt(-h).any() {
        return false;
    }
    // The nine edge × axis directions.
    let e = [p[1] - p[0], p[2] - p[1], p[0] - p[2]];
    for edge in e {
        for a in 0..3 {
            let mut unit = DVec3::ZERO;
            unit[a] = 1.0;
            let axis = edge.cross(unit);
            let (d0, d1, d2) = (axis.dot(p[0]), axis.dot(p[1]), axis.dot(p[2]));
            let r = h.dot(axis.abs());
            if d0.min(d1).min(d2) > r || d0.max(d1).max(d2) < -r {
                return false;
            }
        }
    }
    // The triangle's plane against the box.
    let n = e[0].cross(e[1]);
    let r = h.dot(n.abs());
    let s = n.dot(p[0]);
    s.abs() <= r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [DVec3::from(a), DVec3::from(b), DVec3::from(c)]
    }

    #[test]
    fn separating_axes() {
        let (c, h) = (DVec3::ZERO, DVec3::ONE);
        // Inside, crossing, touching a face, beyond a face.
        assert!(tri_box_overlap(
            c,
            h,
            &tri([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0])
        ));
        assert!(tri_box_overlap(
            c,
            h,
            &tri([-5.0, 0.0, 0.0], [5.0, 0.1, 0.0], [0.0, 5.0, 0.3])
        ));
        assert!(tri_box_overlap(
            c,
            h,
            &tri([1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0])
        ));
        assert!(!tri_box_overlap(
            c,
            h,
            &tri([1.01, 0.0, 0.0], [2.0, 0.0, 0.0], [1.5, 1.0, 0.0])
        ));
        // Bounds overlap but the plane misses the box (a tilted triangle past the corner).
        assert!(!tri_box_overlap(
            c,
            h,
            &tri([3.5, 0.0, 0.0], [0.0, 3.5, 0.0], [0.0, 0.0, 3.5])
        ));
        assert!(tri_box_overlap(
            c,
            h,
            &tri([2.9, 0.0, 0.0], [0.0, 2.9, 0.0], [0.0, 0.0, 2.9])
        ));
        // The plane x + y = 2.2 passes beside the box's edge at x = y = 1.
        assert!(!tri_box_overlap(
            c,
            h,
            &tri([2.2, 0.0, -3.0], [0.0, 2.2, -3.0], [0.0, 2.2, 3.0])
        ));
    }

    /// The polygon left of `poly` after clipping by the six faces (Sutherland–Hodgman).
    fn clip(mut poly: Vec<DVec3>, h: DVec3) -> Vec<DVec3> {
        for a in 0..3 {
            for s in [1.0, -1.0] {
                // Keep s·x[a] <= h[a].
                let inside = |p: DVec3| s * p[a] <= h[a];
                let mut out = Vec::new();
                for i in 0..poly.len() {
                    let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                    if inside(p) {
                        out.push(p);
                    }
                    if inside(p) != inside(q) {
                        let t = (h[a] - s * p[a]) / (s * q[a] - s * p[a]);
                        out.push(p + (q - p) * t);
                    }
                }
                poly = out;
                if poly.is_empty() {
                    return poly;
                }
            }
        }
        poly
    }

    #[test]
    fn agrees_with_clipping() {
        let mut x = 0x1234_5678_9abc_def0u64;
        let mut rnd = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 * 6.0 - 3.0
        };
        let h = DVec3::ONE;
        let (mut yes, mut no) = (0, 0);
        for _ in 0..20000 {
            let mut v = [DVec3::ZERO; 3];
            let c = DVec3::new(rnd(), rnd(), rnd());
            for p in &mut v {
                *p = c + DVec3::new(rnd(), rnd(), rnd()) * 0.5;
            }
            let sat = tri_box_overlap(DVec3::ZERO, h, &v);
            if sat {
                yes += 1;
                assert!(!clip(v.to_vec(), h * (1.0 + 1e-9)).is_empty(), "{v:?}");
            } else {
                no += 1;
                assert!(clip(v.to_vec(), h * (1.0 - 1e-9)).is_empty(), "{v:?}");
            }
        }
        assert!(yes > 1000 && no > 1000, "{yes} {no}");
    }
}
