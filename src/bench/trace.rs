//! `lancer bench trace`: one structure's GPU kernel on the default view's primary
//! (closest-hit) and shadow (any-hit) rays, over BVH memory × workgroup size × checked or
//! trusted module, beside the CPU tracer.

use std::sync::Arc;

use serde::Serialize;

use crate::accel::bvh::BuildOptions;
use crate::accel::{build_gpu, AccelKind, GpuForm, Query, RayStats};
use crate::camera::Camera;
use crate::device::{Device, DeviceChoice};
use crate::error::{Error, Result};
use crate::geometry::{Ray, Robustness};
use crate::gpu::BvhMemory;
use crate::mesh::Mesh;
use crate::trace::{Tracer, TracerOptions};

use super::markdown::{dash, Table};
use super::timing::median;
use super::{BenchReport, Progress, Ticker};

/// What `bench trace` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// The mesh.
    pub mesh: Mesh,
    /// The mesh's name in the report (its file).
    pub name: String,
    /// Width of the default view.
    pub width: u32,
    /// Height of the default view.
    pub height: u32,
    /// Where to run beside the CPU: auto and gpu time the GPU kernels on any adapter (a
    /// software one included); cpu measures the CPU alone.
    pub device: DeviceChoice,
    /// Timed runs per configuration (the median is reported), at least 1.
    pub repeat: usize,
    /// The structure: one with a GPU kernel (the BVH in a layout, the kd-tree, the BIH).
    pub accel: AccelKind,
    /// How the BVH is built.
    pub build: BuildOptions,
}

/// `bench trace`'s results (`--json`: one object a run).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The mesh file.
    pub mesh: String,
    /// Triangles in the structure's leaves.
    pub triangles: usize,
    /// Width of the default view.
    pub width: u32,
    /// Height of the default view.
    pub height: u32,
    /// The structure timed.
    pub structure: String,
    /// The GPU adapter, or null.
    pub adapter: Option<String>,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per configuration (the median is reported).
    pub repeat: u64,
    /// One object per ray set and configuration.
    pub runs: Vec<Run>,
}

/// One ray set × device configuration.
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// "primary closest-hit" or "shadow any-hit".
    pub rays: &'static str,
    /// Rays in the set.
    pub count: usize,
    /// "cpu" or "gpu".
    pub device: &'static str,
    /// GPU: "textures" or "buffers" (null on the CPU).
    pub bvh_memory: Option<String>,
    /// GPU: invocations per workgroup (null on the CPU).
    pub workgroup_size: Option<u32>,
    /// GPU: "checked" or "trusted" shader module (null on the CPU).
    pub module: Option<&'static str>,
    /// Million rays per second by GPU time (the CPU's: by wall time; null without
    /// timestamp queries).
    pub mrays_per_s_gpu_time: Option<f64>,
    /// Million rays per second by wall time (GPU: upload, dispatch and read-back).
    pub mrays_per_s_wall: f64,
    /// Mean nodes (or cells) visited per ray.
    pub nodes_per_ray: f64,
}

/// The workgroup sizes timed on the GPU.
const WORKGROUPS: [u32; 3] = [32, 64, 128];

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    let (width, height) = (config.width.max(1), config.height.max(1));
    crate::limits::check_image(width, height, 200, "use a smaller --width/--height")?;
    let kind = config.accel;
    let layout: Arc<dyn GpuForm> =
        build_gpu(kind, &config.mesh, &config.build)?.ok_or_else(|| {
            Error::Usage(format!(
                "the {kind} structure has no GPU kernel: use `lancer bench structures`"
            ))
        })?;
    let camera = Camera::default_view(&config.mesh.bounds(), width, height);
    let (primary, shadow) = super::rays::primary_and_shadow(&config.mesh, layout.as_ref(), &camera);
    let sets: [(&str, Query, &[Ray]); 2] = [
        ("primary closest-hit", Query::Closest, &primary),
        ("shadow any-hit", Query::Any, &shadow),
    ];
    let device = super::open_device(config.device)?;
    let memories = [BvhMemory::Textures, BvhMemory::Buffers];
    let gpu_configs: Vec<(u32, bool)> = match device.is_cpu() {
        true => Vec::new(),
        false => (WORKGROUPS.iter())
            .flat_map(|&w| [(w, false), (w, true)])
            .collect(),
    };
    let repeat = config.repeat.max(1);
    let per_set = 1 + memories.len() * gpu_configs.len();
    let ticker = Ticker::new(progress, (sets.len() * per_set * repeat) as u64);
    let mut runs = Vec::new();
    let cpu = Device::cpu();
    for (name, query, rays) in sets {
        let n = rays.len() as f64;
        let stats_on = TracerOptions {
            stats: true,
            ..TracerOptions::default()
        };
        let mut tracer = Tracer::with_layout(&cpu, layout.clone(), &stats_on)?;
        let (mut times, mut stats) = (Vec::new(), Vec::new());
        for _ in 0..repeat {
            let r = tracer.trace(rays, query)?;
            times.push(r.timings.wall_ms * 1e-3);
            stats = r.stats.unwrap_or_default();
            ticker.inc(1);
        }
        let rate = n / median(times) / 1e6;
        runs.push(Run {
            rays: name,
            count: rays.len(),
            device: "cpu",
            bvh_memory: None,
            workgroup_size: None,
            module: None,
            mrays_per_s_gpu_time: Some(rate),
            mrays_per_s_wall: rate,
            nodes_per_ray: RayStats::means(&stats).0,
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
                    ticker.inc(1);
                }
                tracer.set_kernel(rob, wg, true);
                let s = tracer.trace(rays, query)?.stats;
                let gpu = n / median(gpu) / 1e3;
                runs.push(Run {
                    rays: name,
                    count: rays.len(),
                    device: "gpu",
                    bvh_memory: Some(super::kebab(memory)),
                    workgroup_size: Some(wg),
                    module: Some(if trusted { "trusted" } else { "checked" }),
                    mrays_per_s_gpu_time: gpu.is_finite().then_some(gpu),
                    mrays_per_s_wall: n / median(wall) / 1e3,
                    nodes_per_ray: RayStats::means(&s.unwrap_or_default()).0,
                });
            }
        }
    }
    Ok(Report {
        mesh: config.name.clone(),
        triangles: layout.triangles(),
        width,
        height,
        structure: layout.name().to_string(),
        adapter: super::adapter_of(&device),
        cpu_threads: super::cpu_threads(),
        repeat: repeat as u64,
        runs,
    })
}

impl Report {
    /// A configuration's name in the chart's legend.
    #[cfg(feature = "charts")]
    fn configuration(&self, r: &Run) -> String {
        match (r.device, &r.bvh_memory, r.workgroup_size, r.module) {
            ("cpu", ..) => format!("cpu ({} threads)", self.cpu_threads),
            (d, Some(m), Some(w), Some(module)) => format!("{d} {m} {w} {module}"),
            (d, ..) => d.to_string(),
        }
    }
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!("bench trace: {}", super::file_name(&self.mesh))
    }

    fn adapter(&self) -> Option<String> {
        self.adapter.clone()
    }

    fn text(&self) -> String {
        let mut out = format!(
            "mesh {}  {} triangles in leaves  {}x{}  structure {}\n",
            self.mesh, self.triangles, self.width, self.height, self.structure
        );
        if let Some(a) = &self.adapter {
            out += &format!("adapter {a}\n");
        }
        let mut t = Table::new(&[
            "rays",
            "count",
            "device",
            "BVH memory",
            "workgroup",
            "module",
            "Mrays/s (GPU time)",
            "Mrays/s (wall)",
            "nodes/ray",
        ]);
        let or_dash = |x: Option<String>| x.unwrap_or("–".into());
        for r in &self.runs {
            let device = match r.device {
                "cpu" => format!("cpu ({} threads)", self.cpu_threads),
                d => d.to_string(),
            };
            t.row(vec![
                r.rays.to_string(),
                r.count.to_string(),
                device,
                or_dash(r.bvh_memory.clone()),
                or_dash(r.workgroup_size.map(|w| w.to_string())),
                or_dash(r.module.map(String::from)),
                dash(r.mrays_per_s_gpu_time, 2),
                format!("{:.2}", r.mrays_per_s_wall),
                format!("{:.2}", r.nodes_per_ray),
            ]);
        }
        out + &t.text()
    }

    /// Mrays/s (GPU time where measured), one group per ray set, one bar per configuration.
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let mut categories: Vec<String> = Vec::new();
        let mut series: Vec<(String, Vec<f64>)> = Vec::new();
        for r in &self.runs {
            if !categories.iter().any(|c| c == r.rays) {
                categories.push(r.rays.to_string());
            }
        }
        for r in &self.runs {
            let name = self.configuration(r);
            let c = categories.iter().position(|c| c == r.rays).unwrap_or(0);
            let i = match series.iter().position(|s| s.0 == name) {
                Some(i) => i,
                None => {
                    series.push((name, vec![f64::NAN; categories.len()]));
                    series.len() - 1
                }
            };
            series[i].1[c] = r.mrays_per_s_gpu_time.unwrap_or(r.mrays_per_s_wall);
        }
        let title = format!(
            "{} {}x{}: {}",
            super::file_name(&self.mesh),
            self.width,
            self.height,
            self.structure
        );
        for path in paths {
            super::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)?;
        }
        Ok(paths.to_vec())
    }
}
