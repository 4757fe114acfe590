use std::path::PathBuf;

use clap::Args;
use lancer::trace::files::{read_rays, write_hits};
use lancer::{Query, RayStats, Result, Tracer, TracerOptions, TraversalMode};

use super::input::load_geometry;
use super::{spelled, AccelArg, BuildArgs, DeviceArgs, RobustnessArgs};

#[derive(Args)]
pub struct TraceCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Input ray file (32 bytes a ray).
    #[arg(long)]
    rays: PathBuf,
    /// Output hit file (16 bytes a ray).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    device: DeviceArgs,
    /// Any hit (occlusion) instead of the closest hit.
    #[arg(long)]
    any_hit: bool,
    #[command(flatten)]
    robustness: RobustnessArgs,
    /// Print traversal statistics (and the GPU adapter).
    #[arg(long)]
    stats: bool,
    /// GPU workgroup size.
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
}

impl TraceCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_geometry(&self.mesh)?;
        let mut inputs = mesh.sources.clone();
        inputs.push(self.rays.clone());
        lancer::output::check_output(&self.out, &inputs)?;
        let rays = read_rays(&self.rays)?;
        let device = self.accel.open(&self.device)?;
        let options = TracerOptions {
            build: self.build.options(),
            layout: self.build.layout,
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
        let kind = self.accel.kind(self.build.layout);
        let result = Tracer::with_structure(&device, &mesh, kind, &options)?.trace(&rays, query)?;
        if self.stats {
            println!("device    {device}");
            println!("structure {}", self.accel.kind(self.build.layout));
            println!("layout    {}", self.build.layout);
            if result.mode == self.mode {
                println!("mode      {}", result.mode);
            } else {
                println!(
                    "mode      {} ({} asked for, see the warning)",
                    result.mode, self.mode
                );
            }
            if !device.is_cpu() {
                println!("bvh       in {}", spelled(self.device.bvh_memory));
                let gpu = (result.timings.gpu_ms)
                    .map(|ms| format!("{ms:.2} ms"))
                    .unwrap_or("n/a".into());
                println!(
                    "gpu time  {gpu} (dispatches)  wall {:.2} ms (upload+dispatch+readback)",
                    result.timings.wall_ms
                );
            }
        }
        write_hits(&self.out, &result.hits)?;
        let hit_count = result.hits.iter().filter(|h| h.is_hit()).count();
        println!(
            "{} rays, {} hits, written to {}",
            rays.len(),
            hit_count,
            self.out.display()
        );
        if let Some(stats) = result.stats.filter(|s| !s.is_empty()) {
            let (nodes, tris) = RayStats::means(&stats);
            println!("nodes/ray {nodes:.2}  triangles/ray {tris:.2}");
        }
        Ok(())
    }
}
