use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use lancer::accel::bvh::{build, BvhStats};
use lancer::layout::{bvh_file, try_flatten};
use lancer::Result;
use serde::Serialize;

use super::input::load_geometry;
use super::out::print_json;
use super::{spelled, BuildArgs};

#[derive(Args)]
pub struct BuildCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Also write the flattened layout to this BVH file (the README's "File formats"), for
    /// `trace`, `check` and `heatmap --bvh`.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print one JSON object instead of text (keys: the README's "JSON output").
    #[arg(long)]
    json: bool,
}

/// `build --json`: one object a run.
#[derive(Serialize)]
struct BuildReport {
    /// `--builder`.
    builder: String,
    /// `--layout`.
    layout: &'static str,
    /// Triangles in the BVH (those with NaN, zero area or out of range are left out).
    triangles: usize,
    /// Nodes, leaves included.
    nodes: usize,
    /// Leaves.
    leaves: usize,
    /// Depth of the deepest leaf (the root is depth 0).
    max_depth: usize,
    /// SAH cost of the tree with --t-cube and --t-obj.
    sah_cost: f64,
    /// Wall time to build and flatten, in ms.
    build_ms: f64,
    /// Bytes of the flattened layout (what the GPU holds).
    bytes: usize,
    /// The BVH file written (`--out`; absent without).
    #[serde(skip_serializing_if = "Option::is_none")]
    out: Option<String>,
}

impl BuildCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_geometry(&self.mesh)?;
        if let Some(out) = &self.out {
            lancer::output::check_output(out, &mesh.sources)?;
        }
        let opts = self.build.options();
        let t0 = Instant::now();
        let bvh = build(&mesh, &opts);
        let layout = try_flatten(self.build.layout, &bvh, &mesh)?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let s = BvhStats::of(&bvh, &opts);
        if let Some(out) = &self.out {
            bvh_file::write(out, layout.as_ref(), mesh.len())?;
        }
        let out = self.out.as_ref().map(|p| p.display().to_string());
        if self.json {
            print_json(&BuildReport {
                builder: spelled(opts.builder),
                layout: self.build.layout.name(),
                triangles: s.triangles,
                nodes: s.nodes,
                leaves: s.leaves,
                max_depth: s.max_depth,
                sah_cost: s.sah_cost,
                build_ms: ms,
                bytes: layout.bytes(),
                out,
            })?;
        } else {
            println!("builder     {}", spelled(opts.builder));
            println!("layout      {}", self.build.layout);
            println!("triangles   {}", s.triangles);
            println!("nodes       {}", s.nodes);
            println!("leaves      {}", s.leaves);
            println!("max depth   {}", s.max_depth);
            println!("SAH cost    {:.3}", s.sah_cost);
            println!("build ms    {ms:.2}");
            println!("GPU bytes   {}", layout.bytes());
            if let Some(out) = out {
                println!("written to  {out}");
            }
        }
        Ok(())
    }
}
