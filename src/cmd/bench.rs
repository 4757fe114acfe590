use std::path::PathBuf;
use std::sync::Arc;

use clap::{Args, Subcommand};
use indicatif::ProgressStyle;
use lancer::accel::build_gpu;
use lancer::accel::GpuForm;
use lancer::camera::Camera;
use lancer::gpu::BvhMemory;
use lancer::mesh::load_mesh;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{
    DeviceChoice, Error, Query, Ray, RayStats, Result, Robustness, Tracer, TracerOptions,
};

use serde::Serialize;

use super::out::{json_to, say, JsonTo, Say};
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
    /// Every acceleration structure on one mesh or scene: build, memory, work and speed (on
    /// the CPU, and on the GPU for those with a GPU kernel).
    Structures(super::bench_structures::BenchStructures),
    /// Every flattened layout on one mesh: bytes, work and bytes loaded per ray, CPU twin
    /// and GPU speed for primary, shadow and bounce rays.
    Layouts(super::bench_layouts::BenchLayouts),
    /// What each robustness knob costs in time and the error it leaves, CPU and GPU.
    Accuracy(super::bench_accuracy::BenchAccuracy),
}

#[derive(Args)]
struct BenchTrace {
    /// Mesh (.obj, .ply, .gltf, .glb).
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
    /// Acceleration structure: one with a GPU kernel (the BVH in --layout, the kd-tree, the BIH).
    #[arg(long, value_enum, default_value_t = AccelArg::Bvh)]
    accel: AccelArg,
    #[command(flatten)]
    json: JsonArg,
}

/// `--json [FILE.json]`, shared by the benches.
#[derive(Args)]
pub struct JsonArg {
    /// Also write the results as one JSON object: on stdout with --json alone or --json -
    /// (the tables then go to stderr), or in FILE.json (keys: the book's JSON page, docs/src/reference/json.md).
    #[arg(long, value_name = "FILE.json", num_args = 0..=1, default_missing_value = "-", value_parser = json_to)]
    pub json: Option<JsonTo>,
}

impl JsonArg {
    /// Where the tables go.
    pub fn say(&self) -> Say {
        Say::new(self.json.as_ref().is_some_and(JsonTo::is_stdout))
    }

    /// Checks a JSON file's path before work starts.
    pub fn check(&self, inputs: &[PathBuf]) -> Result<()> {
        self.json.as_ref().map_or(Ok(()), |j| j.check(inputs))
    }

    /// Writes the report where --json asks (nowhere without it).
    pub fn write(&self, report: &impl Serialize, say: Say) -> Result<()> {
        self.json.as_ref().map_or(Ok(()), |j| j.write(report, say))
    }
}

/// `bench trace --json`: one object a run.
#[derive(Serialize)]
struct BenchTraceReport {
    /// The mesh file.
    mesh: String,
    /// Triangles in the structure's leaves.
    triangles: usize,
    /// Width of the default view.
    width: u32,
    /// Height of the default view.
    height: u32,
    /// The structure timed.
    structure: String,
    /// The GPU adapter, or null.
    adapter: Option<String>,
    /// CPU threads.
    cpu_threads: usize,
    /// Timed runs per configuration (the median is reported).
    repeat: u64,
    /// One object per ray set and configuration.
    runs: Vec<BenchTraceRun>,
}

/// One ray set × device configuration.
#[derive(Serialize)]
struct BenchTraceRun {
    /// "primary closest-hit" or "shadow any-hit".
    rays: &'static str,
    /// Rays in the set.
    count: usize,
    /// "cpu" or "gpu".
    device: &'static str,
    /// GPU: "textures" or "buffers" (null on the CPU).
    bvh_memory: Option<String>,
    /// GPU: invocations per workgroup (null on the CPU).
    workgroup_size: Option<u32>,
    /// GPU: "checked" or "trusted" shader module (null on the CPU).
    module: Option<&'static str>,
    /// Million rays per second by GPU time (the CPU's: by wall time; null without
    /// timestamp queries).
    mrays_per_s_gpu_time: Option<f64>,
    /// Million rays per second by wall time (GPU: upload, dispatch and read-back).
    mrays_per_s_wall: f64,
    /// Mean nodes (or cells) visited per ray.
    nodes_per_ray: f64,
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

/// The median: the middle value, or the mean of the two middle ones (NaN when empty, or
/// when a middle value is NaN).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

fn nodes_per_ray(s: &[RayStats]) -> f64 {
    RayStats::means(s).0
}

impl BenchTrace {
    fn run(self) -> Result<()> {
        let say = self.json.say();
        self.json.check(std::slice::from_ref(&self.mesh))?;
        let mesh = load_mesh(&self.mesh)?;
        lancer::limits::check_image(
            self.width,
            self.height,
            200,
            "use a smaller --width/--height",
        )?;
        let build_options = self.build.options();
        // A GPU kernel's bench: the GPU's default layout unless one is named.
        let layout_kind = (self.build.layout).unwrap_or(lancer::trace::defaults::GPU_LAYOUT);
        let kind = self.accel.kind(layout_kind);
        let layout: Arc<dyn GpuForm> =
            build_gpu(kind, &mesh, &build_options)?.ok_or_else(|| {
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
        let bar = super::out::progress_bar((sets.len() * (1 + gpu_runs) * repeat) as u64);
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
            rows.push(BenchTraceRun {
                rays: name,
                count: rays.len(),
                device: "cpu",
                bvh_memory: None,
                workgroup_size: None,
                module: None,
                mrays_per_s_gpu_time: Some(rate),
                mrays_per_s_wall: rate,
                nodes_per_ray: nodes_per_ray(&stats),
            });
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
                    let gpu = n / median(gpu) / 1e3;
                    rows.push(BenchTraceRun {
                        rays: name,
                        count: rays.len(),
                        device: "gpu",
                        bvh_memory: Some(bvh.clone()),
                        workgroup_size: Some(wg),
                        module: Some(module),
                        mrays_per_s_gpu_time: gpu.is_finite().then_some(gpu),
                        mrays_per_s_wall: n / median(wall) / 1e3,
                        nodes_per_ray: nodes_per_ray(&s.unwrap_or_default()),
                    });
                }
            }
        }
        bar.finish_and_clear();
        say!(
            say,
            "mesh {}  {} triangles in leaves  {}x{}  structure {}",
            self.mesh.display(),
            layout.triangles(),
            self.width,
            self.height,
            layout.name()
        );
        if let Some(ctx) = device.gpu_context() {
            say!(say, "adapter {}", ctx.adapter);
        }
        say!(say, "| rays | count | device | BVH memory | workgroup | module | Mrays/s (GPU time) | Mrays/s (wall) | nodes/ray |");
        say!(say, "|---|---|---|---|---|---|---|---|---|");
        let threads = rayon::current_num_threads();
        let or_dash = |x: Option<String>| x.unwrap_or("–".into());
        for r in &rows {
            let device = match r.device {
                "cpu" => format!("cpu ({threads} threads)"),
                d => d.to_string(),
            };
            say!(
                say,
                "| {} | {} | {device} | {} | {} | {} | {} | {:.2} | {:.2} |",
                r.rays,
                r.count,
                or_dash(r.bvh_memory.clone()),
                or_dash(r.workgroup_size.map(|w| w.to_string())),
                or_dash(r.module.map(String::from)),
                or_dash(r.mrays_per_s_gpu_time.map(|m| format!("{m:.2}"))),
                r.mrays_per_s_wall,
                r.nodes_per_ray
            );
        }
        let report = BenchTraceReport {
            mesh: self.mesh.display().to_string(),
            triangles: layout.triangles(),
            width: self.width,
            height: self.height,
            structure: layout.name().to_string(),
            adapter: device.gpu_context().map(|c| c.adapter.to_string()),
            cpu_threads: threads,
            repeat: self.repeat,
            runs: rows,
        };
        self.json.write(&report, say)
    }
}
