//! Writes a wavy terrain of about N triangles as a binary PLY (a triangle soup) or an
//! indexed OBJ, by the output's extension: the big, spatially coherent input the builder and
//! reader measurements use (`lancer bench builders`, docs/src/benchmarks.md).
//!
//! `cargo run --release --example terrain -- N OUT.ply|OUT.obj`

#[path = "../benches/common.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [n, out] = args.as_slice() else {
        return Err("usage: terrain N OUT.ply|OUT.obj".into());
    };
    let mesh = common::terrain(n.replace('_', "").parse()?);
    if out.ends_with(".obj") {
        common::write_obj(&mesh, out)?;
    } else {
        common::write_ply(&mesh, out)?;
    }
    println!("{out}: {} triangles", mesh.triangles.len());
    Ok(())
}
