//! `lancer bench refit`: a deforming mesh, its BVH refit ([`Bvh::refit`]) against rebuilt
//! at every step — the time each takes, and how the refit tree's SAH cost and trace speed
//! decay against the rebuilt tree's as the mesh moves away from the one it was built for.
//! The mesh is twisted about its longest axis, by up to `max_twist` degrees from one end to
//! the other, in `steps` equal steps.

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use super::markdown::Table;
use super::rays::primary_and_shadow;
use super::timing::{median, mrays};
use super::{BenchReport, Progress, Ticker};
use crate::accel::bvh::layouts::try_flatten;
use crate::accel::bvh::{build, BuildOptions, Bvh, BvhStats};
use crate::accel::{GpuForm, Query, RayStats};
use crate::camera::Camera;
use crate::device::{Device, DeviceChoice};
use crate::error::Result;
use crate::geometry::{Ray, Robustness, Triangle};
use crate::gpu::BvhMemory;
use crate::mesh::Mesh;
use crate::trace::{Tracer, TracerOptions};
use crate::LayoutKind;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Config {
    /// The mesh deformed.
    pub mesh: Mesh,
    /// Its name in the report.
    pub name: String,
    /// Deformation steps after the undeformed mesh.
    pub steps: usize,
    /// Twist at the last step, degrees from one end of the longest axis to the other.
    pub max_twist: f32,
    /// Primary rays' image width.
    pub width: u32,
    /// Primary rays' image height.
    pub height: u32,
    /// The GPU measured beside the CPU twin (auto: any adapter that opens).
    pub device: DeviceChoice,
    /// GPU: where the kernel reads the layout from.
    pub bvh_memory: BvhMemory,
    /// Flattened layout (None: the device's default).
    pub layout: Option<LayoutKind>,
    /// Timed runs per measurement (the median is reported).
    pub repeat: usize,
    /// The builder of the initial tree and of every rebuild.
    pub build: BuildOptions,
}

/// One deformation step.
#[derive(Clone, Debug, Serialize)]
pub struct Step {
    /// Twist of this step, degrees end to end.
    pub twist_deg: f64,
    /// Refitting the tree built for the undeformed mesh.
    pub refit_ms: f64,
    /// Building a tree for this step's mesh from scratch.
    pub rebuild_ms: f64,
    /// Flattening either tree into the layout.
    pub flatten_ms: f64,
    /// SAH cost of the refit tree.
    pub refit_sah: f64,
    /// SAH cost of the rebuilt tree.
    pub rebuild_sah: f64,
    /// Nodes visited per primary ray, refit tree.
    pub refit_nodes_per_ray: f64,
    /// Nodes visited per primary ray, rebuilt tree.
    pub rebuild_nodes_per_ray: f64,
    /// CPU twin, primary rays, Mrays/s: refit, rebuilt.
    pub cpu_mrays_per_s: [f64; 2],
    /// GPU, primary rays, Mrays/s: refit, rebuilt (None on the CPU alone).
    pub gpu_mrays_per_s: Option<[f64; 2]>,
}

/// The whole bench.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The mesh.
    pub mesh: String,
    /// Its triangles.
    pub triangles: usize,
    /// The builder.
    pub builder: &'static str,
    /// The layout traced.
    pub layout: &'static str,
    /// Primary rays per step.
    pub rays: usize,
    /// The GPU adapter, or "none".
    pub adapter: String,
    /// The GPU driver (None on the CPU alone).
    pub gpu_driver: Option<String>,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per measurement.
    pub repeat: usize,
    /// One row per step, the undeformed mesh first.
    pub steps: Vec<Step>,
}

/// `mesh` twisted about its longest axis through its centre, by `degrees` from one end to
/// the other.
pub fn twisted(mesh: &Mesh, degrees: f32) -> Mesh {
    let b = mesh.bounds();
    let (c, e) = (b.center(), b.extent());
    let axis = if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    };
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let per_unit = degrees.to_radians() / e[axis].max(f32::MIN_POSITIVE);
    let turn = |p: Vec3| {
        let a = (p[axis] - b.lo[axis]) * per_unit;
        let (s, co) = a.sin_cos();
        let (x, y) = (p[u] - c[u], p[v] - c[v]);
        let mut q = p;
        q[u] = c[u] + x * co - y * s;
        q[v] = c[v] + x * s + y * co;
        q
    };
    let triangles = (mesh.triangles.iter())
        .map(|t| Triangle { v: t.v.map(turn) })
        .collect();
    Mesh {
        triangles,
        ..mesh.clone()
    }
}

/// The median seconds of `repeat` runs of `f`, each on a fresh input from `fresh`.
fn timed<T>(repeat: usize, fresh: impl Fn() -> T, mut f: impl FnMut(T)) -> f64 {
    let times = (0..repeat)
        .map(|_| {
            let x = fresh();
            let t0 = Instant::now();
            f(x);
            t0.elapsed().as_secs_f64()
        })
        .collect();
    median(times)
}

/// CPU seconds of one trace of `rays` through each form, in turns (median of `repeat`).
fn cpu_pair(forms: [&dyn GpuForm; 2], rays: &[Ray], repeat: usize) -> [f64; 2] {
    let rob = Robustness::default();
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..repeat {
        for (k, f) in forms.iter().enumerate() {
            f.trace_hits(rays, Query::Closest, &rob);
            let t0 = Instant::now();
            f.trace_hits(rays, Query::Closest, &rob);
            times[k].push(t0.elapsed().as_secs_f64());
        }
    }
    times.map(median)
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    crate::limits::check_image(
        config.width,
        config.height,
        200,
        "use a smaller --width/--height",
    )?;
    let repeat = config.repeat.max(1);
    let device = super::open_device(config.device)?;
    let gpu = !device.is_cpu();
    let layout = (config.layout).unwrap_or_else(|| crate::trace::default_layout(&device));
    let ticker = Ticker::new(progress, 1 + config.steps as u64 + 1);
    ticker.say("building the undeformed mesh's tree");
    let base: Bvh = build(&config.mesh, &config.build);
    ticker.inc(1);
    let options = TracerOptions {
        memory: config.bvh_memory,
        ..TracerOptions::default()
    };
    let mut steps = Vec::new();
    let mut rays_n = 0;
    for s in 0..=config.steps {
        let twist = config.max_twist * s as f32 / config.steps.max(1) as f32;
        ticker.say(format!("twist {twist:.0}°"));
        let moved = twisted(&config.mesh, twist);
        // Checked before it is timed: a twist can carry a mesh near the supported range out
        // of it, and a refused refit costs nothing worth timing.
        let mut refit = base.clone();
        refit.refit(&moved).map_err(|e| {
            crate::Error::Usage(format!(
                "the mesh twisted by {twist:.0}°: {e} (bench refit twists it about its longest \
                 axis: give a smaller --max-twist, or a mesh further inside the range)"
            ))
        })?;
        let refit_s = timed(
            repeat,
            || base.clone(),
            |mut t| t.refit(&moved).unwrap_or(()),
        );
        let rebuild_s = timed(repeat, || (), |_| drop(build(&moved, &config.build)));
        let rebuilt = build(&moved, &config.build);
        let (refit_sah, rebuild_sah) = (
            BvhStats::of(&refit, &config.build).sah_cost,
            BvhStats::of(&rebuilt, &config.build).sah_cost,
        );
        let t0 = Instant::now();
        let a: std::sync::Arc<dyn GpuForm> = try_flatten(layout, &refit, &moved)?.into();
        let flatten_ms = t0.elapsed().as_secs_f64() * 1e3;
        let b: std::sync::Arc<dyn GpuForm> = try_flatten(layout, &rebuilt, &moved)?.into();
        let camera = Camera::default_view(&moved.bounds(), config.width, config.height);
        let (primary, _) = primary_and_shadow(&moved, b.as_ref(), &camera);
        rays_n = primary.len();
        let rob = Robustness::default();
        let nodes =
            [&a, &b].map(|f| RayStats::means(&f.trace_batch(&primary, Query::Closest, &rob).1).0);
        let cpu = cpu_pair([a.as_ref(), b.as_ref()], &primary, repeat);
        let gpu_times = match gpu {
            true => Some(gpu_pair(&device, [&a, &b], &primary, repeat, &options)?),
            false => None,
        };
        steps.push(Step {
            twist_deg: twist as f64,
            refit_ms: refit_s * 1e3,
            rebuild_ms: rebuild_s * 1e3,
            flatten_ms,
            refit_sah,
            rebuild_sah,
            refit_nodes_per_ray: nodes[0],
            rebuild_nodes_per_ray: nodes[1],
            cpu_mrays_per_s: cpu.map(|t| mrays(primary.len(), t)),
            gpu_mrays_per_s: gpu_times.map(|g| g.map(|t| mrays(primary.len(), t))),
        });
        ticker.inc(1);
    }
    Ok(Report {
        mesh: config.name.clone(),
        triangles: config.mesh.len(),
        builder: config.build.builder.name(),
        layout: layout.name(),
        rays: rays_n,
        adapter: device.to_string(),
        gpu_driver: super::adapter_of(&device),
        cpu_threads: super::cpu_threads(),
        repeat,
        steps,
    })
}

/// GPU seconds of one trace of `rays` through each form, in turns (median of `repeat`).
fn gpu_pair(
    device: &Device,
    forms: [&std::sync::Arc<dyn GpuForm>; 2],
    rays: &[Ray],
    repeat: usize,
    options: &TracerOptions,
) -> Result<[f64; 2]> {
    let mut tracers = (forms.iter())
        .map(|f| Tracer::with_layout(device, (*f).clone(), options))
        .collect::<Result<Vec<_>>>()?;
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..repeat {
        for (k, t) in tracers.iter_mut().enumerate() {
            t.trace(rays, Query::Closest)?;
            let t0 = Instant::now();
            t.trace(rays, Query::Closest)?;
            times[k].push(t0.elapsed().as_secs_f64());
        }
    }
    Ok(times.map(median))
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!("bench refit: {}", super::file_name(&self.mesh))
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = format!(
            "mesh {}  {} triangles  builder {}  layout {}  {} primary rays  {} CPU threads\n",
            self.mesh, self.triangles, self.builder, self.layout, self.rays, self.cpu_threads
        );
        out += &format!("adapter {}\n\n", self.adapter);
        let gpu = self.gpu_driver.is_some();
        let mut head = vec![
            "twist °",
            "refit ms",
            "rebuild ms",
            "flatten ms",
            "SAH refit ÷ rebuilt",
            "nodes/ray refit ÷ rebuilt",
            "CPU time/ray refit ÷ rebuilt",
        ];
        if gpu {
            head.push("GPU time/ray refit ÷ rebuilt");
        }
        let mut t = Table::new(&head);
        for s in &self.steps {
            let mut row = vec![
                format!("{:.0}", s.twist_deg),
                format!("{:.2}", s.refit_ms),
                format!("{:.1}", s.rebuild_ms),
                format!("{:.1}", s.flatten_ms),
                format!("{:.3}", s.refit_sah / s.rebuild_sah),
                format!("{:.3}", s.refit_nodes_per_ray / s.rebuild_nodes_per_ray),
                format!("{:.3}", s.cpu_mrays_per_s[1] / s.cpu_mrays_per_s[0]),
            ];
            if let Some(g) = s.gpu_mrays_per_s {
                row.push(format!("{:.3}", g[1] / g[0]));
            }
            t.row(row);
        }
        out += &t.text();
        out += "\nRatios above 1: the refit tree costs more than a rebuild for the same \
                triangles. Times are medians; the two trees are traced in turns.\n";
        out
    }

    /// The refit tree's cost against the rebuilt tree's by twist: SAH, nodes per ray, and
    /// time per ray on each device.
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let series_of = |name: &str, f: &dyn Fn(&Step) -> Option<f64>| {
            let pts = (self.steps.iter())
                .filter_map(|s| f(s).map(|y| (s.twist_deg, y)))
                .collect();
            (name.to_string(), pts)
        };
        let mut series = vec![
            series_of("SAH", &|s| Some(s.refit_sah / s.rebuild_sah)),
            series_of("nodes per ray", &|s| {
                Some(s.refit_nodes_per_ray / s.rebuild_nodes_per_ray)
            }),
            series_of("CPU time per ray", &|s| {
                Some(s.cpu_mrays_per_s[1] / s.cpu_mrays_per_s[0])
            }),
        ];
        if self.gpu_driver.is_some() {
            series.push(series_of("GPU time per ray", &|s| {
                s.gpu_mrays_per_s.map(|g| g[1] / g[0])
            }));
        }
        let title = format!(
            "refit ÷ rebuilt, {} ({}, {})",
            super::file_name(&self.mesh),
            self.builder,
            self.layout
        );
        for path in paths {
            super::chart::xy_chart(
                path,
                &title,
                "twist (degrees end to end)",
                "refit ÷ rebuilt",
                false,
                false,
                &series,
                false,
            )?;
        }
        Ok(paths.to_vec())
    }
}
