use std::path::PathBuf;
use std::sync::Arc;

use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::build_gpu;
use lancer::camera::Camera;
use lancer::gpu::BvhMemory;
use lancer::layout::Layout;
use lancer::mesh::load_mesh;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{
    DeviceChoice, Error, Query, Ray, RayStats, Result, Robustness, Tracer, TracerOptions,
};

use super::{open_bench_device, spelled, AccelArg, BuildArgs};

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
    /// Every acceleration structure on one mesh (CPU): build, memory, work and speed.
    Structures(super::bench_structures::BenchStructures),
    /// Every flattened layout on one mesh: bytes, work and bytes loaded per ray, CPU twin
    /// and GPU speed for primary, shadow and bounce rays.
    Layouts(super::bench_layouts::BenchLayouts),
    /// What each robustness knob costs in time and the error it leaves, CPU and GPU.
    Accuracy(super::bench_accuracy::BenchAccuracy),
}

#[derive(Args)]
struct BenchTrace {
    /// OBJ mesh.
    mesh: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// auto, gpu or cpu. auto and gpu measure the GPU kernels and the CPU tracer side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    /// Timed runs per configuration (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure: one with a GPU kernel (the BVH in `--layout`, the kd-tree, the BIH).
    #[arg(long, value_enum, default_value_t = AccelArg::Bvh)]
    accel: AccelArg,
}

impl BenchCmd {
    pub fn run(self) -> Result<()> {
        match self.what {
            BenchWhat::Trace(b) => b.run(),
            BenchWhat::Render(b) => b.run(),
            BenchWhat::Structures(b) => b.run(),
            BenchWhat::Layouts(b) => b.run(),
            BenchWhat::Accuracy(b) => b.run(),
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn nodes_per_ray(s: &[RayStats]) -> f64 {
    RayStats::means(s).0
}

impl BenchTrace {
    fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        lancer::limits::check_image(
            self.width,
            self.height,
            200,
            "use a smaller --width/--height",
        )?;
        let build_options = self.build.options();
        let kind = self.accel.kind(self.build.layout);
        let layout: Arc<dyn Layout> = build_gpu(kind, &mesh, &build_options)?.ok_or_else(|| {
            Error::Usage(format!(
                "the {kind} structure has no GPU kernel: use `lancer bench structures`"
            ))
        })?;
        let primary = Camera::default_view(&mesh.bounds(), self.width.max(1), self.height.max(1))
            .primary_rays();
        let rob = Robustness::default();
        let (hits, _) = layout.trace_batch(&primary, Query::Closest, &rob);
        let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
        let sets: [(&str, Query, &[Ray]); 2] = [
            ("primary closest-hit", Query::Closest, &primary),
            ("shadow any-hit", Query::Any, &shadow),
        ];
        let device = open_bench_device(self.device)?;
        let memories = [BvhMemory::Textures, BvhMemory::Buffers];
        let gpu_configs: Vec<(u32, bool)> = if device.is_cpu() {
            Vec::new()
        } else {
            [32, 64, 128]
                .iter()
                .flat_map(|&w| [(w, false), (w, true)])
                .collect()
        };
        let gpu_runs = memories.len() * gpu_configs.len();
        let repeat = self.repeat as usize;
        let bar = ProgressBar::new((sets.len() * (1 + gpu_runs) * repeat) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} runs {msg}").unwrap());
        let mut rows = Vec::new();
        let cpu = lancer::Device::cpu();
        for (name, query, rays) in sets {
            let n = rays.len() as f64;
            let stats_on = TracerOptions {
                stats: true,
                ..TracerOptions::default()
            };
            let mut tracer = Tracer::with_layout(&cpu, layout.clone(), &stats_on)?;
            let mut times = Vec::new();
            let mut stats = Vec::new();
            for _ in 0..repeat {
                let r = tracer.trace(rays, query)?;
                times.push(r.timings.wall_ms * 1e-3);
                stats = r.stats.unwrap_or_default();
                bar.inc(1);
            }
            let rate = n / median(times) / 1e6;
            rows.push(format!(
                "| {name} | {} | cpu ({} threads) | – | – | – | {rate:.2} | {rate:.2} | {:.2} |",
                rays.len(),
                rayon::current_num_threads(),
                nodes_per_ray(&stats)
            ));
            if device.is_cpu() {
                continue;
            }
            for memory in memories {
                let options = TracerOptions {
                    memory,
                    ..TracerOptions::default()
                };
                let mut tracer = Tracer::with_layout(&device, layout.clone(), &options)?;
                let bvh = spelled(memory);
                for &(wg, trusted) in &gpu_configs {
                    let rob = Robustness {
                        checked_module: !trusted,
                        ..Robustness::default()
                    };
                    tracer.set_kernel(rob, wg, false);
                    tracer.trace(&rays[..rays.len().min(1024)], query)?; // compile outside the timing
                    let (mut gpu, mut wall) = (Vec::new(), Vec::new());
                    for _ in 0..repeat {
                        let t = tracer.trace(rays, query)?.timings;
                        gpu.push(t.gpu_ms.unwrap_or(f64::NAN));
                        wall.push(t.wall_ms);
                        bar.inc(1);
                    }
                    tracer.set_kernel(rob, wg, true);
                    let s = tracer.trace(rays, query)?.stats;
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
            "mesh {}  {} triangles in leaves  {}x{}  structure {}",
            self.mesh.display(),
            layout.triangles(),
            self.width,
            self.height,
            layout.name()
        );
        if let Some(ctx) = device.gpu_context() {
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
