//! Writes a wavy terrain of about N triangles as a binary PLY: the big, spatially coherent
//! input the builder measurements use (`lancer bench builders`, docs/src/benchmarks.md).
//!
//! `cargo run --release --example terrain -- N OUT.ply`

#[path = "../benches/common.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [n, out] = args.as_slice() else {
        return Err("usage: terrain N OUT.ply".into());
    };
    let mesh = common::terrain(n.replace('_', "").parse()?);
    common::write_ply(&mesh, out)?;
    println!("{out}: {} triangles", mesh.triangles.len());
    Ok(())
}
