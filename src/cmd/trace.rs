use std::path::PathBuf;

use clap::Args;
use lancer::trace::files::encode_hits;
use lancer::trace::stats::{TraceReport, TraceStats};
use lancer::{Error, Query, Result, Tracer, TracerOptions, TraversalMode};

use super::input::load_bvh;
use super::out::{check_output, is_std, print_json, read_rays, say, write_output, Say};
use super::{BuildArgs, DeviceArgs, RobustnessArgs, BVH_CONFLICTS};
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
    #[arg(long, value_parser = super::accel_arg(), default_value = "bvh")]
    accel: lancer::AccelKind,
    /// Trace the BVH in this file (`build --out`; docs/src/reference/file-formats.md) instead of
    /// building one: its layout is the file's (--accel, --layout and the builder options are
    /// refused with it), and MESH must be the mesh it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = BVH_CONFLICTS)]
    bvh: Option<PathBuf>,
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
        let rays = read_rays(&self.rays)?;
        let bvh = (self.bvh.as_ref())
            .map(|p| load_bvh(p, &mesh))
            .transpose()?;
        let device = self.device.open_for(self.accel)?;
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
        let kind = self.accel.with_layout(layout);
        let mut tracer = match &bvh {
            Some(file) => Tracer::with_layout(&device, file.layout.clone(), &options)?,
            None => Tracer::with_structure(&device, &mesh, kind, &options)?,
        };
        let result = tracer.trace(&rays, query)?;
        let stats = TraceStats::new(&result, &device, kind, layout, &options);
        if self.stats {
            stats.text().into_iter().for_each(|l| say!(say, "{l}"));
        }
        write_output(&self.out, &encode_hits(&result.hits))?;
        let report = TraceReport::new(&result, &self.out.display().to_string(), None);
        report
            .text(&result)
            .into_iter()
            .for_each(|l| say!(say, "{l}"));
        if self.json {
            print_json(&TraceReport {
                stats: self.stats.then_some(stats),
                ..report
            })?;
        }
        Ok(())
    }
}
