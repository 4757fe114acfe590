use std::path::PathBuf;

use clap::{Args, ValueEnum};
use lancer::accel::bvh::{build, FlatBvh};
use lancer::geometry::TriangleTest;
use lancer::gpu::{BvhMemory, GpuContext, GpuTracer, TraceKernel};
use lancer::scene::load_mesh;
use lancer::trace::rays::{read_rays, write_hits};
use lancer::trace::{trace_batch, Query};
use lancer::Result;

use super::BuildArgs;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Device {
    /// The GPU when an adapter exists, else the CPU (with a printed warning).
    Auto,
    Gpu,
    Cpu,
}

/// Opens the GPU for `device`, or None for the CPU (auto falls back with a warning).
pub fn open_device(device: Device) -> Result<Option<GpuContext>> {
    match device {
        Device::Cpu => Ok(None),
        Device::Gpu => GpuContext::new().map(Some),
        Device::Auto => match GpuContext::new() {
            Ok(ctx) => Ok(Some(ctx)),
            Err(e) => {
                eprintln!("warning: {e}; tracing on the CPU");
                Ok(None)
            }
        },
    }
}

/// A BVH memory as the command line spells it.
pub fn memory_name(m: BvhMemory) -> String {
    m.to_possible_value()
        .map_or(format!("{m:?}"), |v| v.get_name().to_string())
}

#[derive(Args)]
pub struct TraceCmd {
    /// OBJ mesh.
    mesh: PathBuf,
    /// Input ray file (32 bytes a ray).
    #[arg(long)]
    rays: PathBuf,
    /// Output hit file (16 bytes a ray).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    device: Device,
    /// Any hit (occlusion) instead of the closest hit.
    #[arg(long)]
    any_hit: bool,
    /// Triangle test.
    #[arg(long, value_enum, default_value_t = TriangleTest::Watertight)]
    triangle_test: TriangleTest,
    /// Print traversal statistics (and the GPU adapter).
    #[arg(long)]
    stats: bool,
    /// GPU workgroup size.
    #[arg(long, default_value_t = 64)]
    workgroup_size: u32,
    /// GPU: run the shader module without bounds checks / loop bounding (BVH validated first).
    #[arg(long)]
    trusted: bool,
    /// GPU: where the kernels read the BVH from (storage textures or storage buffers).
    #[arg(long, value_enum, default_value_t = BvhMemory::default())]
    bvh_memory: BvhMemory,
    #[command(flatten)]
    build: BuildArgs,
}

impl TraceCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let rays = read_rays(&self.rays)?;
        let flat = FlatBvh::new(&build(&mesh, &self.build.options()), &mesh);
        let query = if self.any_hit {
            Query::Any
        } else {
            Query::Closest
        };
        let (hits, stats) = match open_device(self.device)? {
            None => {
                let (h, s) = trace_batch(&flat, &rays, query, self.triangle_test);
                if self.stats {
                    println!("device    cpu ({} threads)", rayon::current_num_threads());
                }
                (h, s)
            }
            Some(ctx) => {
                let mut tracer = GpuTracer::with_memory(&ctx, &flat, self.bvh_memory)?;
                let kernel = TraceKernel {
                    query,
                    test: self.triangle_test,
                    stats: self.stats,
                    workgroup_size: self.workgroup_size,
                    trusted: self.trusted,
                };
                let (h, s, t) = tracer.trace(&rays, kernel)?;
                if self.stats {
                    println!("device    gpu: {}", ctx.adapter);
                    println!("bvh       in {}", memory_name(tracer.memory()));
                    let gpu = t
                        .gpu_ms
                        .map(|ms| format!("{ms:.2} ms"))
                        .unwrap_or("n/a".into());
                    println!(
                        "gpu time  {gpu} (dispatches)  wall {:.2} ms (upload+dispatch+readback)",
                        t.wall_ms
                    );
                }
                (h, s.unwrap_or_default())
            }
        };
        write_hits(&self.out, &hits)?;
        let n = rays.len().max(1) as f64;
        let hit_count = hits.iter().filter(|h| h.is_hit()).count();
        println!(
            "{} rays, {} hits, written to {}",
            rays.len(),
            hit_count,
            self.out.display()
        );
        if self.stats && !stats.is_empty() {
            let nodes: u64 = stats.iter().map(|s| s.nodes as u64).sum();
            let tris: u64 = stats.iter().map(|s| s.tris as u64).sum();
            println!(
                "nodes/ray {:.2}  triangles/ray {:.2}",
                nodes as f64 / n,
                tris as f64 / n
            );
        }
        Ok(())
    }
}
