//! Inputs shared by the benchmarks.
#![allow(dead_code)]

use std::path::PathBuf;

use glam::Vec3;
use lancer::geometry::Triangle;
use lancer::mesh::{load_obj, Mesh};

/// The bunny from ../shared/models (panics with a clear message when absent).
pub fn bunny() -> Mesh {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/models/stanford-bunny.obj");
    load_obj(&p).unwrap_or_else(|e| panic!("benchmarks need ../shared/models: {e}"))
}

/// A bumpy height-field of about `n` triangles (two per grid cell): a generated
/// large mesh with the spatial coherence of scanned geometry.
pub fn terrain(n: usize) -> Mesh {
    let k = ((n / 2) as f64).sqrt().ceil() as usize;
    let p = |i: usize, j: usize| {
        let (x, z) = (i as f32 / k as f32, j as f32 / k as f32);
        let y = 0.05 * ((x * 23.0).sin() * (z * 17.0).cos()) + 0.02 * ((x * 71.0 + z * 53.0).sin());
        Vec3::new(x, y, z)
    };
    let mut tris = Vec::with_capacity(2 * k * k);
    'outer: for i in 0..k {
        for j in 0..k {
            for t in [
                Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)),
                Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)),
            ] {
                tris.push(t);
                if tris.len() == n {
                    break 'outer;
                }
            }
        }
    }
    Mesh::from_triangles(tris)
}
