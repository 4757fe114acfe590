//! Built-in shapes for scene files: triangles with texture coordinates, in object space.

use glam::{Vec2, Vec3};

use crate::geometry::Triangle;

/// Triangles and the texture coordinates of their corners.
pub type ShapeMesh = (Vec<Triangle>, Vec<[Vec2; 3]>);

fn quad_into(out: &mut ShapeMesh, c: [Vec3; 4]) {
    let uv = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    out.0.push(Triangle::new(c[0], c[1], c[2]));
    out.1.push([uv[0], uv[1], uv[2]]);
    out.0.push(Triangle::new(c[0], c[2], c[3]));
    out.1.push([uv[0], uv[2], uv[3]]);
}

/// Unit square in the XZ plane, centred at the origin, counter-clockwise seen from +Y.
pub fn quad() -> ShapeMesh {
    let mut m = (Vec::new(), Vec::new());
    quad_into(
        &mut m,
        [
            Vec3::new(-0.5, 0.0, 0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(-0.5, 0.0, -0.5),
        ],
    );
    m
}

/// Unit cube centred at the origin, faces counter-clockwise seen from outside.
pub fn cube() -> ShapeMesh {
    let mut m = (Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            // n = the face normal, (u, v) spans the face with u × v = n.
            let n = Vec3::AXES[axis] * sign;
            let u = Vec3::AXES[(axis + 1) % 3] * sign;
            let v = n.cross(u);
            let c = n * 0.5;
            quad_into(
                &mut m,
                [
                    c - 0.5 * u - 0.5 * v,
                    c + 0.5 * u - 0.5 * v,
                    c + 0.5 * u + 0.5 * v,
                    c - 0.5 * u + 0.5 * v,
                ],
            );
        }
    }
    m
}

/// Unit-radius UV sphere with `segments` slices around Y and `segments / 2` rings.
pub fn sphere(segments: u32) -> ShapeMesh {
    let (ns, nr) = (segments.max(3), (segments / 2).max(2));
    let point = |i: u32, j: u32| {
        let (phi, theta) = (
            std::f32::consts::TAU * i as f32 / ns as f32,
            std::f32::consts::PI * j as f32 / nr as f32,
        );
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            -theta.sin() * phi.sin(),
        )
    };
    let uv = |i: u32, j: u32| Vec2::new(i as f32 / ns as f32, 1.0 - j as f32 / nr as f32);
    let mut m = (Vec::new(), Vec::new());
    for j in 0..nr {
        for i in 0..ns {
            let (a, b, c, d) = ((i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j));
            // The poles' degenerate halves are left out.
            if j != 0 {
                m.0.push(Triangle::new(
                    point(a.0, a.1),
                    point(b.0, b.1),
                    point(d.0, d.1),
                ));
                m.1.push([uv(a.0, a.1), uv(b.0, b.1), uv(d.0, d.1)]);
            }
            if j != nr - 1 {
                m.0.push(Triangle::new(
                    point(b.0, b.1),
                    point(c.0, c.1),
                    point(d.0, d.1),
                ));
                m.1.push([uv(b.0, b.1), uv(c.0, c.1), uv(d.0, d.1)]);
            }
        }
    }
    m
}

/// Rings of an open stadium bowl, inside out: (radius, height). The floor is the disc inside
/// the first; each later ring is a tier of stands sloping up and out.
const STADIUM_RINGS: [(f32, f32); 3] = [(0.5, 0.0), (0.75, 0.15), (1.0, 0.4)];

/// Triangles per segment of [`stadium`]: one of the floor, two per tier.
pub const STADIUM_TRIS_PER_SEGMENT: u32 = 1 + 2 * (STADIUM_RINGS.len() as u32 - 1);

/// An open stadium bowl of outer radius 1 around Y, standing on y = 0: a flat floor of
/// radius 0.5 and two tiers of stands up to y = 0.4, `segments` slices around (few large
/// triangles: the sparse mesh of a "teapot in a stadium"). Faces point up and inwards.
pub fn stadium(segments: u32) -> ShapeMesh {
    let ns = segments.max(3);
    let point = |i: u32, (r, y): (f32, f32)| {
        let phi = std::f32::consts::TAU * i as f32 / ns as f32;
        Vec3::new(r * phi.cos(), y, -r * phi.sin())
    };
    let uv = |i: u32, ring: usize| Vec2::new(i as f32 / ns as f32, ring as f32 / 2.0);
    let mut m = (Vec::new(), Vec::new());
    for i in 0..ns {
        let rim = STADIUM_RINGS[0];
        m.0.push(Triangle::new(Vec3::ZERO, point(i, rim), point(i + 1, rim)));
        m.1.push([Vec2::new(0.5, 0.0), uv(i, 0), uv(i + 1, 0)]);
        for (k, w) in STADIUM_RINGS.windows(2).enumerate() {
            let (a, b) = (point(i, w[0]), point(i + 1, w[0]));
            let (c, d) = (point(i, w[1]), point(i + 1, w[1]));
            let (ua, ub, uc, ud) = (uv(i, k), uv(i + 1, k), uv(i, k + 1), uv(i + 1, k + 1));
            m.0.push(Triangle::new(a, d, b));
            m.1.push([ua, ud, ub]);
            m.0.push(Triangle::new(a, c, d));
            m.1.push([ua, uc, ud]);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stadium_is_an_open_bowl_facing_in_and_up() {
        let (tris, uvs) = stadium(24);
        assert_eq!(tris.len(), 24 * STADIUM_TRIS_PER_SEGMENT as usize);
        assert_eq!(uvs.len(), tris.len());
        for t in &tris {
            let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
            let c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            assert!(n.length() > 1e-4, "{t:?}");
            // Up, and towards the axis (or flat on the floor).
            assert!(
                n.y > 0.0 && n.dot(Vec3::new(c.x, 0.0, c.z)) <= 1e-6,
                "{t:?} {n}"
            );
            assert!(t
                .v
                .iter()
                .all(|p| p.y >= 0.0 && p.y <= 0.4 && p.length() <= 1.1));
        }
    }
}
