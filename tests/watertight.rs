//! Watertightness, the hard way: closed icospheres of 81,920 triangles (and a 12-triangle
//! cube) hit by rays aimed exactly at vertices (fans of 5 and 6) and at points of shared
//! edges, from outside and from inside, at scales 1e-4 … 1e4 and moved out to 1e5 and 1e6,
//! on the CPU and the GPU. Every ray must hit. Möller–Trumbore, the fast setting, leaks on
//! the same rays (asserted, so the test can fail).

mod common;

use std::collections::HashMap;

use common::{gpu_device, Rng};
use glam::Vec3;
use lancer::geometry::{Robustness, Triangle, TriangleTest};
use lancer::mesh::Mesh;
use lancer::{Device, Query, Ray, Tracer, TracerOptions};

/// An icosphere of radius 1: the icosahedron, each triangle split in four `levels` times,
/// vertices pushed onto the sphere and shared by index, so the mesh is closed.
fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
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
fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
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
/// from a direction in front of every face that holds its target (at least 0.1 along each
/// face normal): a ray that only grazes the surface may miss it rightly, and is not a leak.
fn aimed_rays(
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
    let mut edge_faces: HashMap<(u32, u32), Vec<Vec3>> = HashMap::new();
    for t in f {
        let nrm = normal(t);
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            vertex_faces[p as usize].push(nrm);
            edge_faces
                .entry((p.min(q), p.max(q)))
                .or_default()
                .push(nrm);
        }
    }
    // (target, normals of the faces that hold it)
    let mut targets: Vec<(Vec3, &[Vec3])> = v
        .iter()
        .zip(&vertex_faces)
        .map(|(p, n)| (*p, &n[..]))
        .collect();
    let mut edges: Vec<_> = edge_faces.iter().collect();
    edges.sort_by_key(|(k, _)| **k);
    for ((p, q), normals) in edges {
        let (p, q) = (v[*p as usize], v[*q as usize]);
        targets.push((p + (q - p) * 0.5, normals));
        targets.push((p + (q - p) * rng.f32(), normals));
    }
    (0..n)
        .map(|i| {
            let (target, normals) = targets[i % targets.len()];
            let origin = if i % 2 == 0 {
                let mut u = rng.dir();
                while normals.iter().any(|nrm| u.dot(*nrm) < 0.1) {
                    u = rng.dir();
                }
                target + u * (3.0 * radius)
            } else {
                centre + rng.dir() * (0.05 * radius * rng.f32())
            };
            Ray::new(origin, target - origin, 0.0, 3.4e38)
        })
        .collect()
}

/// Misses among `rays` on `device` with the given triangle test.
fn misses(mesh: &Mesh, rays: &[Ray], test: TriangleTest, device: &Device) -> usize {
    let options = TracerOptions {
        robustness: Robustness {
            triangle_test: test,
            ..Robustness::default()
        },
        ..TracerOptions::default()
    };
    let mut tracer = Tracer::new(device, mesh, &options).unwrap();
    let hits = tracer.trace(rays, Query::Closest).unwrap().hits;
    hits.iter().filter(|h| !h.is_hit()).count()
}

#[test]
fn closed_meshes_leak_no_ray_at_any_scale_on_cpu_and_gpu() {
    let mut rng = Rng::new(2024);
    let mut mt_leaks = 0;
    let shapes = [("icosphere 81,920", icosphere(6)), ("cube", cube())];
    for (name, (v0, f)) in &shapes {
        for (scale, shift) in [
            (1.0f32, 0.0f32),
            (1e-4, 0.0),
            (1e4, 0.0),
            (100.0, 1e5),
            (1000.0, 1e6),
        ] {
            let v: Vec<Vec3> = v0.iter().map(|p| *p * scale + Vec3::splat(shift)).collect();
            let tris = f
                .iter()
                .map(|&[a, b, c]| Triangle::new(v[a as usize], v[b as usize], v[c as usize]))
                .collect();
            let mesh = Mesh::from_triangles(tris);
            let n = if f.len() > 1000 { 1_000_000 } else { 100_000 };
            let rays = aimed_rays(&v, f, Vec3::splat(shift), scale, n, &mut rng);
            for device in [&Device::cpu(), gpu_device()] {
                let leaks = misses(&mesh, &rays, TriangleTest::Watertight, device);
                let mt = misses(&mesh, &rays, TriangleTest::MollerTrumbore, device);
                println!("{name} ×{scale:e} +{shift:e} on {device}: {n} rays, watertight {leaks} leaks, Möller–Trumbore {mt}");
                assert_eq!(
                    leaks, 0,
                    "{name} ×{scale:e} +{shift:e} on {device}: {leaks} rays leak"
                );
                mt_leaks += mt;
            }
        }
    }
    assert!(
        mt_leaks > 0,
        "Möller–Trumbore leaked nowhere: these rays do not test watertightness"
    );
}
