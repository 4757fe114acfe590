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

/// Crates on a ramp: the plane y = x over [0, 10]², made of `strips` long thin strips running
/// up the slope, with `crates` small boxes (12 triangles each) lying on it at random. Every
/// strip's box spans the ramp's whole length and height, so object splits cannot separate a
/// strip from the crates on it: the case spatial splits are for (architecture's roofs,
/// stairs and beams).
pub fn crates_on_a_ramp(strips: usize, crates: usize) -> Mesh {
    let mut tris = Vec::new();
    let w = 10.0 / strips as f32;
    let on_ramp = |x: f32, z: f32| Vec3::new(x, x, z);
    for j in 0..strips {
        let (z0, z1) = (j as f32 * w, (j + 1) as f32 * w);
        let (a, b) = (on_ramp(0.0, z0), on_ramp(10.0, z0));
        let (c, d) = (on_ramp(10.0, z1), on_ramp(0.0, z1));
        tris.push(Triangle::new(a, b, c));
        tris.push(Triangle::new(a, c, d));
    }
    // Fixed sequences (Weyl, one irrational step per coordinate), so the file is the same
    // everywhere.
    let weyl = |i: usize, step: f64| ((i as f64 + 1.0) * step).fract() as f32;
    for i in 0..crates {
        let (x, z) = (9.8 * weyl(i, 0.618_034), 9.8 * weyl(i, 0.414_214));
        let s = 0.02 + 0.08 * weyl(i, 0.732_051);
        let lo = Vec3::new(x, x, z);
        let hi = lo + Vec3::splat(s);
        let corner =
            |i: usize| Vec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), hi, lo);
        for [a, b, c, d] in [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ] {
            tris.push(Triangle::new(corner(a), corner(b), corner(c)));
            tris.push(Triangle::new(corner(a), corner(c), corner(d)));
        }
    }
    Mesh::from_triangles(tris)
}

/// Writes a mesh as a binary little-endian PLY triangle soup (three vertices per face).
/// Written by hand because ply-rs's writer keeps a map per element (about a kilobyte per
/// vertex at the sizes the benches use).
pub fn write_ply(mesh: &Mesh, out: &str) -> std::io::Result<()> {
    use std::io::{BufWriter, Write};
    let mut w = BufWriter::new(std::fs::File::create(out)?);
    let tris = &mesh.triangles;
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        3 * tris.len(),
        tris.len()
    )?;
    for v in tris.iter().flat_map(|t| t.v) {
        for c in v.to_array() {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    for i in 0..tris.len() as i32 {
        w.write_all(&[3])?;
        for k in 0..3 {
            w.write_all(&(3 * i + k).to_le_bytes())?;
        }
    }
    w.flush()
}

/// Writes a mesh as an indexed OBJ file (each distinct vertex once, `f a b c` rows), the
/// shape scanners and converters write. Coordinates in Rust's shortest round-trip form, so
/// reading the file gives back the same `f32` values.
pub fn write_obj(mesh: &Mesh, out: &str) -> std::io::Result<()> {
    use std::collections::HashMap;
    use std::io::{BufWriter, Write};
    let mut index: HashMap<[u32; 3], usize> = HashMap::new();
    let mut vertices = Vec::new();
    let faces: Vec<[usize; 3]> = (mesh.triangles.iter())
        .map(|t| {
            t.v.map(|v| {
                let key = v.to_array().map(f32::to_bits);
                *index.entry(key).or_insert_with(|| {
                    vertices.push(v);
                    vertices.len()
                })
            })
        })
        .collect();
    let mut w = BufWriter::new(std::fs::File::create(out)?);
    writeln!(
        w,
        "# {} vertices, {} triangles",
        vertices.len(),
        faces.len()
    )?;
    for v in &vertices {
        writeln!(w, "v {:?} {:?} {:?}", v.x, v.y, v.z)?;
    }
    for [a, b, c] in &faces {
        writeln!(w, "f {a} {b} {c}")?;
    }
    w.flush()
}
