use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use lancer::accel::bvh::layouts::{bvh_file, try_flatten};
use lancer::accel::bvh::{build, BvhStats};
use lancer::Result;
use serde::Serialize;

use super::out::{print_json, say, Say};
use super::{spelled, BuildArgs};
use lancer::render::load_geometry;

#[derive(Args)]
pub struct BuildCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Also write the flattened layout to this BVH file (docs/src/reference/file-formats.md), for
    /// `trace`, `check` and `heatmap --bvh`.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print one JSON object instead of text (keys: the book's JSON page, docs/src/reference/json.md).
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
        // No device here: a BVH file is for a GPU kernel (or a twin), so the GPU's default.
        let kind = (self.build.layout).unwrap_or(lancer::trace::defaults::GPU_LAYOUT);
        let layout = try_flatten(kind, &bvh, &mesh)?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let s = BvhStats::of(&bvh, &opts);
        if let Some(out) = &self.out {
            bvh_file::write(out, layout.as_ref(), mesh.len())?;
        }
        let out = self.out.as_ref().map(|p| p.display().to_string());
        if self.json {
            print_json(&BuildReport {
                builder: spelled(opts.builder),
                layout: kind.name(),
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
            let say = Say::new(false);
            say!(say, "builder     {}", spelled(opts.builder));
            say!(say, "layout      {kind}");
            say!(say, "triangles   {}", s.triangles);
            say!(say, "nodes       {}", s.nodes);
            say!(say, "leaves      {}", s.leaves);
            say!(say, "max depth   {}", s.max_depth);
            say!(say, "SAH cost    {:.3}", s.sah_cost);
            say!(say, "build ms    {ms:.2}");
            say!(say, "GPU bytes   {}", layout.bytes());
            if let Some(out) = out {
                say!(say, "written to  {out}");
            }
        }
        Ok(())
    }
}
