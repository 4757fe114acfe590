//! Writes crates on a ramp of long thin strips as a binary PLY: the scene where spatial
//! splits pay (`lancer bench builders`, docs/src/results): every strip's box spans the ramp,
//! so only a split that cuts the strips separates them from the crates lying on them.
//!
//! `cargo run --release --example ramp -- STRIPS CRATES OUT.ply`

#[path = "../benches/common.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [strips, crates, out] = args.as_slice() else {
        return Err("usage: ramp STRIPS CRATES OUT.ply".into());
    };
    let mesh = common::crates_on_a_ramp(strips.parse()?, crates.replace('_', "").parse()?);
    common::write_ply(&mesh, out)?;
    println!("{out}: {} triangles", mesh.triangles.len());
    Ok(())
}
