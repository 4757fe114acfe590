//! Constructed hard cases for the box tests and the traversal: each a small mesh and rays
//! built so that the right answer is clear to the f64 oracle. Most are exact in f32 too (the
//! ray's direction and the vertices are chosen so the triangle test rounds nothing that
//! matters): there a tracer must hit exactly when the oracle does.

use glam::Vec3;

use crate::geometry::{Ray, Triangle};
use crate::mesh::Mesh;
use crate::render::Rng;

/// One hard case: a mesh and the rays that stress it.
pub struct HardCase {
    /// What it stresses.
    pub name: &'static str,
    /// The triangles.
    pub mesh: Mesh,
    /// The rays.
    pub rays: Vec<Ray>,
    /// Whether every ray's hit or miss is exact in f32 (a tracer must hit exactly when the
    /// oracle does); otherwise rays near an edge may go either way (ties).
    pub exact: bool,
}

/// Every case, `n` rays each (the box-corner case: `n` rays over 64 triangles).
pub fn all(n: usize, seed: u32) -> Vec<HardCase> {
    vec![
        axis_parallel(n, seed),
        grazing(n, seed ^ 1),
        box_corners(n, seed ^ 2),
        behind_origin(n, seed ^ 3),
        in_plane(n, seed ^ 4),
    ]
}

/// Side of the tilings, in unit quads.
const TILES: u32 = 8;

/// An 8 × 8 tiling of unit quads (two triangles each) in the plane `axis` = `c`, spanning
/// [0, 8] on the other two axes: every box below the root is flat (min == max on `axis`).
fn tiling(axis: usize, c: f32) -> Vec<Triangle> {
    let at = |u: f32, v: f32| {
        let mut p = [0.0; 3];
        p[axis] = c;
        p[(axis + 1) % 3] = u;
        p[(axis + 2) % 3] = v;
        Vec3::from(p)
    };
    let mut tris = Vec::new();
    for i in 0..TILES {
        for j in 0..TILES {
            let (u, v) = (i as f32, j as f32);
            tris.push(Triangle::new(
                at(u, v),
                at(u + 1.0, v),
                at(u + 1.0, v + 1.0),
            ));
            tris.push(Triangle::new(
                at(u, v),
                at(u + 1.0, v + 1.0),
                at(u, v + 1.0),
            ));
        }
    }
    tris
}

/// A coordinate of the tiling's span: an integer (a shared edge or vertex, a slab plane of
/// the flat boxes, the tiling's outer edge at 0 and 8), a quarter, or any multiple of
/// 1/1024 (few bits: differences with the vertices round nothing).
fn span_coord(rng: &mut Rng) -> f32 {
    let k = rng.next_u32();
    match k % 3 {
        0 => ((k >> 2) % (TILES + 1)) as f32,
        1 => ((k >> 2) % (4 * TILES + 1)) as f32 * 0.25,
        _ => ((k >> 2) % (1024 * TILES + 1)) as f32 / 1024.0,
    }
}

/// ±0.0, the sign at random.
fn signed_zero(rng: &mut Rng) -> f32 {
    if rng.next_u32() & 1 == 0 {
        0.0
    } else {
        -0.0
    }
}

/// Three tilings (one per axis, flat boxes) hit by axis-parallel rays whose other direction
/// components are +0.0 or −0.0, from origins whose other coordinates lie exactly on the
/// boxes' slab planes (shared edges and vertices, the outer edges) or between them; a third
/// of the rays tilt in one other axis (one zero component left). Every number is a
/// dyadic of few bits, so the triangle test rounds nothing: exact.
pub fn axis_parallel(n: usize, seed: u32) -> HardCase {
    let mut rng = Rng::new(seed, 0, 0);
    let planes = [(0usize, 3.0f32), (1, -2.0), (2, 0.5)];
    let tris = planes.iter().flat_map(|&(a, c)| tiling(a, c)).collect();
    let rays = (0..n)
        .map(|i| {
            let (axis, c) = planes[i % planes.len()];
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let side = if rng.next_u32() & 1 == 0 { 1.0 } else { -1.0 };
            let mut o = [0.0f32; 3];
            o[axis] = c + side * (0.5 + (rng.next_u32() % 64) as f32 / 16.0);
            o[u] = span_coord(&mut rng);
            o[v] = span_coord(&mut rng);
            let mut d = [signed_zero(&mut rng), signed_zero(&mut rng), 0.0];
            d.rotate_right(axis + 1);
            d[axis] = -side;
            if i % 3 == 2 {
                d[u] = ((rng.next_u32() % 33) as f32 - 16.0) / 64.0;
            }
            Ray::new(Vec3::from(o), Vec3::from(d), 0.0, 3.4e38)
        })
        .collect();
    HardCase {
        name: "axis-parallel, ±0 directions, origins on slab planes",
        mesh: Mesh::from_triangles(tris),
        rays,
        exact: true,
    }
}

/// A tiling in z = 0 (flat boxes) hit by grazing rays: 1e-5 to 0.1 radians above the
/// plane, from up to 1000 units away, aimed at points of the tiling (its shared edges
/// included).
pub fn grazing(n: usize, seed: u32) -> HardCase {
    let mut rng = Rng::new(seed, 0, 0);
    let rays = (0..n)
        .map(|_| {
            let target = Vec3::new(span_coord(&mut rng), span_coord(&mut rng), 0.0);
            let elevation = 10f32.powf(-5.0 + 4.0 * rng.next_f32());
            let azimuth = rng.next_f32() * std::f32::consts::TAU;
            let (s, c) = azimuth.sin_cos();
            let back = Vec3::new(c * elevation.cos(), s * elevation.cos(), elevation.sin());
            let o = target + back * 10f32.powf(3.0 * rng.next_f32());
            Ray::new(o, target - o, 0.0, 3.4e38)
        })
        .collect();
    HardCase {
        name: "grazing rays on flat boxes",
        mesh: Mesh::from_triangles(tiling(2, 0.0)),
        rays,
        exact: false,
    }
}

/// 64 triangles, 40 units apart (each its own leaf), each with a vertex at a corner of its
/// box, and rays through exactly that vertex that enter the box on one axis and leave it on
/// another at the same point: the box's entry and exit distances are equal, and the plain
/// slab test's rounding decides. Exact: the direction's dominant component is ±4 and the
/// others are multiples of 1/64, so the watertight test (f32 and f64) hits at t = 1.
pub fn box_corners(n: usize, seed: u32) -> HardCase {
    let mut rng = Rng::new(seed, 0, 0);
    let mut tris = Vec::new();
    let mut corners = Vec::new();
    for i in 0..64u32 {
        let corner = Vec3::new((i % 4) as f32, (i / 4 % 4) as f32, (i / 16) as f32) * 40.0;
        // The triangle extends from its corner towards −signs on each axis.
        let signs = Vec3::new(
            if i & 1 == 0 { 1.0 } else { -1.0 },
            if i & 2 == 0 { 1.0 } else { -1.0 },
            if i & 4 == 0 { 1.0 } else { -1.0 },
        );
        tris.push(Triangle::new(
            corner,
            corner - signs * Vec3::new(1.0, 0.5, 0.75),
            corner - signs * Vec3::new(0.5, 1.0, 0.25),
        ));
        corners.push((corner, signs));
    }
    let rays = (0..n)
        .map(|i| {
            let (corner, signs) = corners[i % corners.len()];
            // Out of the box (along +sign) on some axes, into it on the others, never all
            // the same way.
            let pattern = 1 + rng.next_u32() % 6;
            let dominant = (rng.next_u32() % 3) as usize;
            let mut d = [0.0f32; 3];
            for (k, dk) in d.iter_mut().enumerate() {
                let out = pattern & (1 << k) != 0;
                let m = if k == dominant {
                    4.0
                } else {
                    (16 + rng.next_u32() % 240) as f32 / 64.0
                };
                *dk = if out { signs[k] * m } else { -signs[k] * m };
            }
            let d = Vec3::from(d);
            Ray::new(corner - d, d, 0.0, 3.4e38)
        })
        .collect();
    HardCase {
        name: "rays through a box corner (entry = exit)",
        mesh: Mesh::from_triangles(tris),
        rays,
        exact: true,
    }
}

/// A tiling in z = 0 (every box flat) behind the ray's origin: rays leave the plane
/// (t_far < 0) with tmin = −100, so the hit lies at a negative t. A far-plane widening that
/// scales a negative t_far inwards loses it.
pub fn behind_origin(n: usize, seed: u32) -> HardCase {
    let mut rng = Rng::new(seed, 0, 0);
    let rays = (0..n)
        .map(|_| {
            let target = Vec3::new(span_coord(&mut rng), span_coord(&mut rng), 0.0);
            let d = Vec3::new(
                (rng.next_f32() - 0.5) * 0.5,
                (rng.next_f32() - 0.5) * 0.5,
                1.0,
            );
            let o = target + d * (0.5 + 4.0 * rng.next_f32());
            Ray::new(o, d, -100.0, 100.0)
        })
        .collect();
    HardCase {
        name: "flat boxes behind the origin (tmin < 0)",
        mesh: Mesh::from_triangles(tiling(2, 0.0)),
        rays,
        exact: false,
    }
}

/// A tiling in z = 0 and rays lying in its plane (origin z = 0, direction z = ±0), through
/// it and past it: the triangles are edge-on, so there is nothing to hit (the watertight
/// test's determinant is exactly 0 in f32 and f64 alike).
pub fn in_plane(n: usize, seed: u32) -> HardCase {
    let mut rng = Rng::new(seed, 0, 0);
    let rays = (0..n)
        .map(|_| {
            let o = Vec3::new(
                span_coord(&mut rng) * 1.5 - 2.0,
                span_coord(&mut rng) * 1.5 - 2.0,
                signed_zero(&mut rng),
            );
            let a = rng.next_f32() * std::f32::consts::TAU;
            let d = Vec3::new(a.cos(), a.sin(), signed_zero(&mut rng));
            Ray::new(o, d, 0.0, 3.4e38)
        })
        .collect();
    HardCase {
        name: "rays in the triangles' plane",
        mesh: Mesh::from_triangles(tiling(2, 0.0)),
        rays,
        exact: true,
    }
}
