//! Writes a wavy terrain of about N triangles as a binary PLY: the big, spatially coherent
//! input the builder measurements use (`lancer bench builders`, docs/src/benchmarks.md).
//!
//! `cargo run --release --example terrain -- N OUT.ply`

#[path = "../benches/common.rs"]
mod common;

use std::io::{BufWriter, Write};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [n, out] = args.as_slice() else {
        return Err("usage: terrain N OUT.ply".into());
    };
    let mesh = common::terrain(n.replace('_', "").parse()?);
    // Triangle soup: three vertices per face. Written by hand because ply-rs's writer keeps a
    // map per element (about a kilobyte per vertex at these sizes).
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
    w.flush()?;
    println!("{out}: {} triangles", tris.len());
    Ok(())
}
