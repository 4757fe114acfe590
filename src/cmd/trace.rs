use std::path::PathBuf;

use clap::Args;
use lancer::trace::files::{decode_rays, encode_hits};
use lancer::{Error, Query, RayStats, Result, Tracer, TracerOptions, TraversalMode};
use serde::Serialize;

use super::input::load_bvh;
use super::out::{check_output, is_std, print_json, read_input, say, write_output, Say};
use super::{spelled, AccelArg, BuildArgs, DeviceArgs, RobustnessArgs, BVH_CONFLICTS};
use lancer::render::load_geometry;

#[derive(Args)]
pub struct TraceCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Input ray file (32 bytes a ray; docs/src/reference/file-formats.md), or - for stdin.
    #[arg(long)]
    rays: PathBuf,
    /// Output hit file (16 bytes a ray), or - for stdout (text then goes to stderr).
    #[arg(short, long)]
    out: PathBuf,
    #[command(flatten)]
    device: DeviceArgs,
    /// Any hit (occlusion) instead of the closest hit.
    #[arg(long)]
    any_hit: bool,
    #[command(flatten)]
    robustness: RobustnessArgs,
    /// Print traversal statistics: device, structure, layout, mode, times, work per ray.
    #[arg(long)]
    stats: bool,
    /// Print the summary (and the --stats) as one JSON object on stdout, the text on
    /// stderr; the keys are described in the book's JSON page, docs/src/reference/json.md.
    #[arg(long)]
    json: bool,
    /// GPU: invocations per workgroup (the adapter's limit applies).
    #[arg(long, default_value_t = 64)]
    workgroup_size: u32,
    /// GPU traversal: one ray per invocation, or the lanes of a subgroup together (falls
    /// back to per-ray, with a warning, where the adapter or layout has no subgroup mode).
    #[arg(long, value_enum, default_value_t = TraversalMode::PerRay)]
    mode: TraversalMode,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure (all but the BVH, the kd-tree and the BIH run on the CPU).
    #[arg(long, value_enum, default_value_t = AccelArg::Bvh)]
    accel: AccelArg,
    /// Trace the BVH in this file (`build --out`; docs/src/reference/file-formats.md) instead of
    /// building one: its layout is the file's (--accel, --layout and the builder options are
    /// refused with it), and MESH must be the mesh it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = BVH_CONFLICTS)]
    bvh: Option<PathBuf>,
}

/// `trace --json`: one object a run.
#[derive(Serialize)]
struct TraceReport {
    /// Rays traced.
    rays: usize,
    /// Rays that hit something.
    hits: usize,
    /// The hit file written (`-`: stdout).
    out: String,
    /// The rest, with --stats only (else absent).
    #[serde(flatten)]
    stats: Option<TraceStats>,
}

/// `trace --stats --json`.
#[derive(Serialize)]
struct TraceStats {
    /// "cpu" or "gpu".
    device: &'static str,
    /// The GPU adapter (null on the CPU).
    adapter: Option<String>,
    /// CPU threads (rayon's pool; --threads).
    cpu_threads: usize,
    /// `--accel` structure, e.g. "bvh (dfs-sign)".
    structure: String,
    /// `--layout`.
    layout: String,
    /// Traversal mode that ran (per-ray where subgroup could not).
    mode: String,
    /// Where the GPU read the BVH (null on the CPU).
    bvh_memory: Option<String>,
    /// GPU time of the dispatches in ms (null on the CPU or without timestamp queries).
    gpu_ms: Option<f64>,
    /// Wall time of the trace in ms (GPU: upload, dispatch and read-back).
    wall_ms: f64,
    /// Mean nodes (or cells) visited per ray.
    nodes_per_ray: Option<f64>,
    /// Mean triangles tested per ray.
    triangles_per_ray: Option<f64>,
}

impl TraceCmd {
    pub fn run(self) -> Result<()> {
        let to_stdout = is_std(&self.out);
        if to_stdout && self.json {
            return Err(Error::Usage(
                "--json and --out - both write to stdout: write the hits to a file".into(),
            ));
        }
        let say = Say::new(to_stdout || self.json);
        let mesh = load_geometry(&self.mesh)?;
        let mut inputs = mesh.sources.clone();
        inputs.push(self.rays.clone());
        inputs.extend(self.bvh.clone());
        check_output(&self.out, &inputs)?;
        let rays_name = match is_std(&self.rays) {
            true => PathBuf::from("<stdin>"),
            false => self.rays.clone(),
        };
        let rays = decode_rays(&rays_name, &read_input(&self.rays)?)?;
        let bvh = (self.bvh.as_ref())
            .map(|p| load_bvh(p, &mesh))
            .transpose()?;
        let device = self.accel.open(&self.device)?;
        let layout = bvh
            .as_ref()
            .map_or(self.build.layout_on(&device), |f| f.kind);
        let options = TracerOptions {
            build: self.build.options(),
            layout: Some(layout),
            memory: self.device.bvh_memory,
            robustness: self.robustness.robustness(),
            workgroup_size: self.workgroup_size,
            stats: self.stats,
            mode: self.mode,
        };
        let query = if self.any_hit {
            Query::Any
        } else {
            Query::Closest
        };
        let kind = self.accel.kind(layout);
        let mut tracer = match &bvh {
            Some(file) => Tracer::with_layout(&device, file.layout.clone(), &options)?,
            None => Tracer::with_structure(&device, &mesh, kind, &options)?,
        };
        let result = tracer.trace(&rays, query)?;
        let means = (result.stats.as_ref())
            .filter(|s| !s.is_empty())
            .map(|s| RayStats::means(s));
        if self.stats {
            say!(say, "device    {device}");
            say!(say, "structure {kind}");
            say!(say, "layout    {layout}");
            if result.mode == self.mode {
                say!(say, "mode      {}", result.mode);
            } else {
                say!(
                    say,
                    "mode      {} ({} asked for, see the warning)",
                    result.mode,
                    self.mode
                );
            }
            if !device.is_cpu() {
                say!(say, "bvh       in {}", spelled(self.device.bvh_memory));
                let gpu = (result.timings.gpu_ms)
                    .map(|ms| format!("{ms:.2} ms"))
                    .unwrap_or("n/a".into());
                say!(
                    say,
                    "gpu time  {gpu} (dispatches)  wall {:.2} ms (upload+dispatch+readback)",
                    result.timings.wall_ms
                );
            }
        }
        write_output(&self.out, &encode_hits(&result.hits))?;
        let hit_count = result.hits.iter().filter(|h| h.is_hit()).count();
        say!(
            say,
            "{} rays, {} hits, written to {}",
            rays.len(),
            hit_count,
            self.out.display()
        );
        if let Some((nodes, tris)) = means {
            say!(say, "nodes/ray {nodes:.2}  triangles/ray {tris:.2}");
        }
        if self.json {
            let gpu = device.gpu_context();
            print_json(&TraceReport {
                rays: rays.len(),
                hits: hit_count,
                out: self.out.display().to_string(),
                stats: self.stats.then(|| TraceStats {
                    device: if gpu.is_some() { "gpu" } else { "cpu" },
                    adapter: gpu.map(|c| c.adapter.to_string()),
                    cpu_threads: rayon::current_num_threads(),
                    structure: kind.to_string(),
                    layout: layout.name().to_string(),
                    mode: result.mode.name().to_string(),
                    bvh_memory: gpu.map(|_| spelled(self.device.bvh_memory)),
                    gpu_ms: result.timings.gpu_ms,
                    wall_ms: result.timings.wall_ms,
                    nodes_per_ray: means.map(|m| m.0),
                    triangles_per_ray: means.map(|m| m.1),
                }),
            })?;
        }
        Ok(())
    }
}
