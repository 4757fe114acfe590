use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bvh::{build, FlatBvh};
use lancer::geometry::{Ray, TriangleTest};
use lancer::gpu::{BvhMemory, GpuTracer, TraceKernel};
use lancer::scene::{load_mesh, Camera};
use lancer::trace::rays::{default_light, shadow_rays};
use lancer::trace::{trace_batch, Query, RayStats};
use lancer::Result;

use super::trace::{memory_name, open_device, Device};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchCmd {
    #[command(subcommand)]
    what: BenchWhat,
}

#[derive(Subcommand)]
enum BenchWhat {
    /// Trace primary (closest-hit) and shadow (any-hit) rays of the default view.
    Trace(BenchTrace),
    /// Milliseconds per spp on GPU and CPU, specialised vs all-effects kernel.
    Render(super::bench_render::BenchRender),
}

#[derive(Args)]
struct BenchTrace {
    /// OBJ mesh.
    mesh: PathBuf,
    #[arg(long, default_value_t = 1024)]
    width: u32,
    #[arg(long, default_value_t = 1024)]
    height: u32,
    /// auto and gpu measure the GPU kernels and the CPU tracer side by side; cpu only the CPU.
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    device: Device,
    /// Timed runs per configuration (the median is reported).
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    #[command(flatten)]
    build: BuildArgs,
}

impl BenchCmd {
    pub fn run(self) -> Result<()> {
        match self.what {
            BenchWhat::Trace(b) => b.run(),
            BenchWhat::Render(b) => b.run(),
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn nodes_per_ray(s: &[RayStats]) -> f64 {
    s.iter().map(|s| s.nodes as f64).sum::<f64>() / s.len().max(1) as f64
}

impl BenchTrace {
    fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let flat = FlatBvh::new(&build(&mesh, &self.build.options()), &mesh);
        let primary = Camera::default_view(&mesh.bounds(), self.width.max(1), self.height.max(1))
            .primary_rays();
        let (hits, _) = trace_batch(&flat, &primary, Query::Closest, TriangleTest::Watertight);
        let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
        let sets: [(&str, Query, &[Ray]); 2] = [
            ("primary closest-hit", Query::Closest, &primary),
            ("shadow any-hit", Query::Any, &shadow),
        ];
        let ctx = open_device(self.device)?;
        let memories = [BvhMemory::Textures, BvhMemory::Buffers];
        let gpu_configs: Vec<(u32, bool)> = if ctx.is_some() {
            [32, 64, 128]
                .iter()
                .flat_map(|&w| [(w, false), (w, true)])
                .collect()
        } else {
            Vec::new()
        };
        let gpu_runs = memories.len() * gpu_configs.len();
        let repeat = self.repeat.max(1);
        let bar = ProgressBar::new((sets.len() * (1 + gpu_runs) * repeat) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} runs {msg}").unwrap());
        let mut rows = Vec::new();
        for (name, query, rays) in sets {
            let n = rays.len() as f64;
            let mut times = Vec::new();
            let mut stats = Vec::new();
            for _ in 0..repeat {
                let t0 = Instant::now();
                let (_, s) = trace_batch(&flat, rays, query, TriangleTest::Watertight);
                times.push(t0.elapsed().as_secs_f64());
                stats = s;
                bar.inc(1);
            }
            let cpu = n / median(times) / 1e6;
            rows.push(format!(
                "| {name} | {} | cpu ({} threads) | – | – | – | {cpu:.2} | {cpu:.2} | {:.2} |",
                rays.len(),
                rayon::current_num_threads(),
                nodes_per_ray(&stats)
            ));
            let Some(ctx) = &ctx else { continue };
            for memory in memories {
                let mut tracer = GpuTracer::with_memory(ctx, &flat, memory)?;
                let bvh = memory_name(memory);
                for &(wg, trusted) in &gpu_configs {
                    let k = TraceKernel {
                        query,
                        workgroup_size: wg,
                        trusted,
                        ..TraceKernel::default()
                    };
                    tracer.trace(&rays[..rays.len().min(1024)], k)?; // compile outside the timing
                    let (mut gpu, mut wall) = (Vec::new(), Vec::new());
                    for _ in 0..repeat {
                        let (_, _, t) = tracer.trace(rays, k)?;
                        gpu.push(t.gpu_ms.unwrap_or(f64::NAN));
                        wall.push(t.wall_ms);
                        bar.inc(1);
                    }
                    let (_, s, _) = tracer.trace(rays, TraceKernel { stats: true, ..k })?;
                    let module = if trusted { "trusted" } else { "checked" };
                    rows.push(format!(
                        "| {name} | {} | gpu | {bvh} | {wg} | {module} | {:.2} | {:.2} | {:.2} |",
                        rays.len(),
                        n / median(gpu) / 1e3,
                        n / median(wall) / 1e3,
                        nodes_per_ray(&s.unwrap_or_default())
                    ));
                }
            }
        }
        bar.finish_and_clear();
        println!(
            "mesh {}  {} triangles  {}x{}",
            self.mesh.display(),
            flat.tris.len(),
            self.width,
            self.height
        );
        if let Some(ctx) = &ctx {
            println!("adapter {}", ctx.adapter);
        }
        println!("| rays | count | device | BVH memory | workgroup | module | Mrays/s (GPU time) | Mrays/s (wall) | nodes/ray |");
        println!("|---|---|---|---|---|---|---|---|---|");
        for r in rows {
            println!("{r}");
        }
        Ok(())
    }
}
