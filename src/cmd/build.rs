use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use lancer::accel::bvh::{build, BvhStats};
use lancer::layout::flatten;
use lancer::Result;

use super::input::load_geometry;
use super::BuildArgs;

#[derive(Args)]
pub struct BuildCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

impl BuildCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_geometry(&self.mesh)?;
        let opts = self.build.options();
        let t0 = Instant::now();
        let bvh = build(&mesh, &opts);
        let layout = flatten(self.build.layout, &bvh, &mesh);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let s = BvhStats::of(&bvh, &opts);
        if self.json {
            let j = serde_json::json!({
                "triangles": s.triangles, "nodes": s.nodes, "leaves": s.leaves,
                "max_depth": s.max_depth, "sah_cost": s.sah_cost, "build_ms": ms,
                "bytes": layout.bytes(), "layout": self.build.layout.name(),
            });
            println!("{j}");
        } else {
            println!("builder     {:?}", opts.builder);
            println!("layout      {}", self.build.layout);
            println!("triangles   {}", s.triangles);
            println!("nodes       {}", s.nodes);
            println!("leaves      {}", s.leaves);
            println!("max depth   {}", s.max_depth);
            println!("SAH cost    {:.3}", s.sah_cost);
            println!("build ms    {ms:.2}");
            println!("GPU bytes   {}", layout.bytes());
        }
        Ok(())
    }
}
