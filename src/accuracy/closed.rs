//! Closed meshes and the rays that test their watertightness: rays aimed exactly at every
//! vertex (fans of 5 and 6 triangles) and at points of every shared edge, from outside and
//! from inside. A closed mesh has no gap, so every such ray that misses is a **leak**.

use std::collections::HashMap;

use glam::Vec3;

use super::random_dir;
use crate::geometry::{Hit, Ray, Triangle};
use crate::mesh::Mesh;
use crate::render::Rng;

/// Vertices and triangles (indices into the vertices) of a closed mesh.
pub type Indexed = (Vec<Vec3>, Vec<[u32; 3]>);

/// An icosphere of radius 1: the icosahedron, each triangle split in four `levels` times,
/// vertices pushed onto the sphere and shared by index, so the mesh is closed.
pub fn icosphere(levels: u32) -> Indexed {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut m = |a: u32, b: u32, v: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                v.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let (ab, bc, ca) = (m(a, b, &mut v), m(b, c, &mut v), m(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// The unit cube as 12 triangles sharing its 8 corners.
pub fn cube() -> Indexed {
    let v = (0..8)
        .map(|i| {
            Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * 2.0 - 1.0
        })
        .collect();
    let f = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (v, f)
}

/// Rays aimed exactly at every vertex and at points of every shared edge (the edge's
/// midpoint and a random point on it, computed from the f32 vertices), half from outside
/// (3 radii out) and half from inside (near the centre), `n` in all. An outside ray comes
/// from a direction in front of every face around its target's vertex or edge (at least 0.1
/// along each face normal): a ray that only grazes the surface may miss it rightly, and is
/// not a leak.
/// A target with no such direction (in a crease of a non-convex mesh) is aimed at from inside.
pub fn aimed_rays(
    v: &[Vec3],
    f: &[[u32; 3]],
    centre: Vec3,
    radius: f32,
    n: usize,
    rng: &mut Rng,
) -> Vec<Ray> {
    let normal = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| v[i as usize]);
        (b - a).cross(c - a).normalize()
    };
    let mut vertex_faces: Vec<Vec<Vec3>> = vec![Vec::new(); v.len()];
    let mut edges = Vec::new();
    for t in f {
        let nrm = normal(t);
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            vertex_faces[p as usize].push(nrm);
            edges.push((p.min(q), p.max(q)));
        }
    }
    edges.sort_unstable();
    edges.dedup();
    // (target, the vertices whose faces the ray must meet from the front): an outside ray
    // passes its f32-rounded target by up to an ulp of the coordinates, so it must be in
    // front of every face near the target, not only of those that hold it — else at a
    // crease of a real mesh it may rightly pass beside the surface.
    let mut targets: Vec<(Vec3, u32, u32)> = (v.iter().enumerate())
        .map(|(i, p)| (*p, i as u32, i as u32))
        .collect();
    for (p, q) in edges {
        let (a, b) = (v[p as usize], v[q as usize]);
        targets.push((a + (b - a) * 0.5, p, q));
        targets.push((a + (b - a) * rng.next_f32(), p, q));
    }
    (0..n)
        .map(|i| {
            let (target, p, q) = targets[i % targets.len()];
            let normals = || {
                vertex_faces[p as usize]
                    .iter()
                    .chain(&vertex_faces[q as usize])
            };
            // A direction in front of every face at the target; a target in a crease (a
            // real mesh's) may have none: it is then aimed at from inside.
            let outside = (i % 2 == 0)
                .then(|| {
                    (0..256)
                        .map(|_| random_dir(rng))
                        .find(|u| normals().all(|nrm| u.dot(*nrm) >= 0.1))
                })
                .flatten();
            let origin = match outside {
                Some(u) => target + u * (3.0 * radius),
                None => centre + random_dir(rng) * (0.05 * radius * rng.next_f32()),
            };
            Ray::new(origin, target - origin, 0.0, 3.4e38)
        })
        .collect()
}

/// The mesh of `v` scaled by `scale` and moved by `shift`, with its vertices. A triangle
/// naming a vertex the shape does not have keeps its index with NaN corners (left out of
/// the BVH, never hit).
pub fn placed(shape: &Indexed, scale: f32, shift: Vec3) -> (Mesh, Vec<Vec3>) {
    let v: Vec<Vec3> = shape.0.iter().map(|p| *p * scale + shift).collect();
    let at = |i: u32| v.get(i as usize).copied().unwrap_or(Vec3::NAN);
    let tris = (shape.1.iter())
        .map(|&[a, b, c]| Triangle::new(at(a), at(b), at(c)))
        .collect();
    (Mesh::from_triangles(tris), v)
}

/// Leaks: aimed rays that hit nothing.
pub fn leaks(hits: &[Hit]) -> usize {
    hits.iter().filter(|h| !h.is_hit()).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriStatus;

    #[test]
    fn a_triangle_naming_no_vertex_is_left_out_not_indexed_past() {
        let shape: Indexed = (
            vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            vec![[0, 1, 2], [0, 1, 9]],
        );
        let (mesh, v) = placed(&shape, 2.0, Vec3::Z);
        assert_eq!((mesh.len(), v.len()), (2, 3));
        assert_eq!(mesh.status[0], TriStatus::Ok);
        assert_ne!(mesh.status[1], TriStatus::Ok);
        assert_eq!(mesh.triangles[0].v[1], Vec3::new(2.0, 0.0, 1.0));
    }
}
