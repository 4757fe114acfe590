//! `lancer bench scale`: from a mesh file to its first traced rays, step by step, on each
//! mesh given — read and checked, BVH built, flattened into the layout, put on the device
//! (checked, packed, uploaded, kernel made), first trace of the default view's primary rays —
//! with the peak memory the process held from the read to the trace, as `lancer trace` runs
//! them. Its ratios say where the time goes as meshes grow: the file read per second, and
//! flattening plus the device's share against the build.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::markdown::{dash, Table};
use super::memory::{fresh_memory, peak_resident, reset_peak_resident, resident};
use super::timing::{median, mrays};
use super::{BenchReport, Progress, Ticker};
use crate::accel::bvh::layouts::try_flatten_owned;
use crate::accel::bvh::{build, BuildOptions};
use crate::accel::{GpuForm, Query};
use crate::camera::Camera;
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::gpu::BvhMemory;
use crate::mesh::FileKind;
use crate::trace::{Tracer, TracerOptions};
use crate::LayoutKind;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Config {
    /// The mesh files (.obj, .ply, .gltf, .glb; a scene .toml: its flattened mesh), each
    /// read anew for every timed run. A file that places meshes more than once is measured
    /// flattened, as `lancer trace --flatten` takes it.
    pub meshes: Vec<PathBuf>,
    /// Width of the default view whose primary rays are traced.
    pub width: u32,
    /// Its height.
    pub height: u32,
    /// Where the rays are traced: auto (any adapter that opens, a software one included,
    /// else the CPU), gpu or cpu.
    pub device: DeviceChoice,
    /// GPU: where the kernel reads the layout from.
    pub bvh_memory: BvhMemory,
    /// Flattened layout (None: the device's default, as `lancer trace` takes it).
    pub layout: Option<LayoutKind>,
    /// Timed runs of the whole pipeline per mesh (medians are reported), at least 1.
    pub repeat: usize,
    /// The builder and its options.
    pub build: BuildOptions,
}

/// One mesh's pipeline: each step's median time, and the ratios they make.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// The mesh file as given.
    pub mesh: String,
    /// Its triangles (as read, left-out ones included).
    pub triangles: usize,
    /// Bytes of every file the read opened (an OBJ's materials, a glTF's buffers).
    pub file_bytes: u64,
    /// Reading and checking the mesh.
    pub read_ms: f64,
    /// `file_bytes` over `read_ms`, in MB (10⁶ bytes) per second.
    pub read_mb_per_s: f64,
    /// Building the BVH.
    pub build_ms: f64,
    /// Flattening it into the layout.
    pub flatten_ms: f64,
    /// Checking, packing and uploading the layout and making the kernel (None on the CPU,
    /// which traces the flattened layout where it is).
    pub to_device_ms: Option<f64>,
    /// Of `to_device_ms`: the layout's check alone ([`GpuForm::validate`], which every
    /// upload runs first), timed again after the trace on the same arrays (None on the CPU).
    pub checked_ms: Option<f64>,
    /// (flatten + to the device) ÷ build.
    pub flatten_and_device_per_build: f64,
    /// The first trace of the default view's primary rays (a GPU's pipeline compiled on
    /// the way).
    pub first_trace_ms: f64,
    /// Primary rays traced.
    pub rays: usize,
    /// Millions of those rays a second, in the first trace.
    pub first_trace_mrays_per_s: f64,
    /// The most memory the process held resident from the read to the trace (Linux's
    /// `VmHWM`, reset before each run; a software GPU's memory included), median of the
    /// runs; None where the system does not say.
    pub peak_bytes: Option<u64>,
    /// What the process held resident when the run started (the device, its driver and
    /// the program), median of the runs; None where the system does not say.
    pub start_bytes: Option<u64>,
    /// (`peak_bytes` − `start_bytes`) per triangle: what the mesh's pipeline added (the
    /// rays and their hits included: a small mesh's figure is mostly theirs).
    pub added_bytes_per_triangle: Option<f64>,
}

/// The whole bench.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The builder.
    pub builder: &'static str,
    /// The layout flattened into.
    pub layout: &'static str,
    /// Where the rays were traced (the adapter, or the CPU).
    pub adapter: String,
    /// The GPU driver (None on the CPU alone).
    pub gpu_driver: Option<String>,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per mesh.
    pub repeat: usize,
    /// One row per mesh, in the order given.
    pub rows: Vec<Row>,
}

/// One timed run of the pipeline.
struct Run {
    triangles: usize,
    file_bytes: u64,
    read: f64,
    build: f64,
    flatten: f64,
    to_device: Option<f64>,
    checked: Option<f64>,
    trace: f64,
    rays: usize,
    peak: Option<u64>,
    start: Option<u64>,
}

/// Milliseconds since `start`.
fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The pipeline once on `path`, each step timed: what `lancer trace` does with a mesh,
/// the rays made from the default view in between (not timed).
fn run_once(path: &Path, config: &Config, device: &crate::Device, kind: LayoutKind) -> Result<Run> {
    let peak_known = reset_peak_resident();
    let held = resident().filter(|_| peak_known);
    let start = Instant::now();
    let mesh = crate::render::load_geometry(path)?;
    if matches!(FileKind::of(path)?, FileKind::Scene) {
        crate::mesh::check_usable(path, &mesh)?;
    }
    let read = ms(start);
    let file_bytes = (mesh.sources.iter())
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    let triangles = mesh.len();
    let camera = Camera::default_view(&mesh.bounds(), config.width, config.height);
    let rays = camera.primary_rays();
    let start = Instant::now();
    let tree = build(&mesh, &config.build);
    let built = ms(start);
    let start = Instant::now();
    let layout: Arc<dyn GpuForm> = try_flatten_owned(kind, tree, &mesh)?.into();
    let flatten = ms(start);
    // The layout holds the triangles: `lancer trace` lets the mesh go before the upload.
    drop(mesh);
    let options = TracerOptions {
        layout: Some(kind),
        memory: config.bvh_memory,
        build: config.build,
        ..TracerOptions::default()
    };
    let start = Instant::now();
    let mut tracer = Tracer::with_layout(device, layout, &options)?;
    let to_device = (!device.is_cpu()).then(|| ms(start));
    let start = Instant::now();
    tracer.trace(&rays, Query::Closest)?;
    let trace = ms(start);
    let peak = peak_resident().filter(|_| peak_known);
    // The device step's check once more, alone (it passed there: its answer is known).
    let checked = (!device.is_cpu()).then(|| {
        let start = Instant::now();
        let _ = tracer.layout().map(|l| l.validate());
        ms(start)
    });
    Ok(Run {
        triangles,
        file_bytes,
        read,
        build: built,
        flatten,
        to_device,
        checked,
        trace,
        rays: rays.len(),
        peak,
        start: held,
    })
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
    let kind = (config.layout).unwrap_or_else(|| crate::trace::default_layout(&device));
    let ticker = Ticker::new(progress, (config.meshes.len() * repeat) as u64);
    let mut rows = Vec::new();
    for path in &config.meshes {
        let name = path.display().to_string();
        let mut runs = Vec::new();
        for r in 0..repeat {
            ticker.say(format!(
                "{} ({} of {repeat})",
                super::file_name(&name),
                r + 1
            ));
            // Each run on memory fresh from the system, as a command run once finds it.
            runs.push(fresh_memory(|| run_once(path, config, &device, kind))?);
            ticker.inc(1);
        }
        rows.push(row(name, &runs));
    }
    Ok(Report {
        builder: config.build.builder.name(),
        layout: kind.name(),
        adapter: device.to_string(),
        gpu_driver: super::adapter_of(&device),
        cpu_threads: super::cpu_threads(),
        repeat,
        rows,
    })
}

/// A mesh's row: the median of each step over the runs.
fn row(mesh: String, runs: &[Run]) -> Row {
    let of = |f: &dyn Fn(&Run) -> f64| median(runs.iter().map(f).collect());
    let first = &runs[0];
    let (read, build, flatten, trace) = (
        of(&|r| r.read),
        of(&|r| r.build),
        of(&|r| r.flatten),
        of(&|r| r.trace),
    );
    let to_device = first.to_device.map(|_| of(&|r| r.to_device.unwrap_or(0.0)));
    let checked = first.checked.map(|_| of(&|r| r.checked.unwrap_or(0.0)));
    let median_of = |f: &dyn Fn(&Run) -> Option<u64>| {
        let all: Option<Vec<f64>> = runs.iter().map(|r| f(r).map(|b| b as f64)).collect();
        all.map(|v| median(v) as u64)
    };
    let (peak, start) = (median_of(&|r| r.peak), median_of(&|r| r.start));
    Row {
        mesh,
        triangles: first.triangles,
        file_bytes: first.file_bytes,
        read_ms: read,
        read_mb_per_s: first.file_bytes as f64 / 1e3 / read.max(1e-6),
        build_ms: build,
        flatten_ms: flatten,
        to_device_ms: to_device,
        checked_ms: checked,
        flatten_and_device_per_build: (flatten + to_device.unwrap_or(0.0)) / build.max(1e-6),
        first_trace_ms: trace,
        rays: first.rays,
        first_trace_mrays_per_s: mrays(first.rays, trace / 1e3),
        peak_bytes: peak,
        start_bytes: start,
        added_bytes_per_triangle: peak
            .zip(start)
            .map(|(p, s)| p.saturating_sub(s) as f64 / first.triangles.max(1) as f64),
    }
}

/// A triangle count in few characters, for a chart's labels: 69k, 4.0M.
fn count(n: usize) -> String {
    match n {
        0..1_000 => n.to_string(),
        1_000..1_000_000 => format!("{:.0}k", n as f64 / 1e3),
        _ => format!("{:.1}M", n as f64 / 1e6),
    }
}

/// Bytes in MiB.
fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64
}

/// The steps whose work grows with the mesh, in the order they run, with each row's time
/// for it (None: not run here). The trace's grows with the rays instead.
type Step = (&'static str, fn(&Row) -> Option<f64>);
const STEPS: [Step; 4] = [
    ("read and checked", |r| Some(r.read_ms)),
    ("build", |r| Some(r.build_ms)),
    ("flatten", |r| Some(r.flatten_ms)),
    ("to the device", |r| r.to_device_ms),
];

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        let names: Vec<String> = self
            .rows
            .iter()
            .map(|r| super::file_name(&r.mesh))
            .collect();
        format!("bench scale: {}", names.join(", "))
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = format!(
            "builder {}  layout {}  traced on {}  {} CPU threads  median of {}\n\n",
            self.builder, self.layout, self.adapter, self.cpu_threads, self.repeat
        );
        let mut t = Table::new(&[
            "mesh",
            "triangles",
            "MB",
            "read ms",
            "MB/s",
            "build ms",
            "flatten ms",
            "to device ms",
            "of which checked ms",
            "(flatten + device) ÷ build",
            "first trace ms",
            "rays",
            "peak MiB",
            "at start MiB",
            "added bytes/triangle",
        ]);
        for r in &self.rows {
            t.row(vec![
                super::file_name(&r.mesh),
                r.triangles.to_string(),
                format!("{:.1}", r.file_bytes as f64 / 1e6),
                format!("{:.0}", r.read_ms),
                format!("{:.0}", r.read_mb_per_s),
                format!("{:.0}", r.build_ms),
                format!("{:.0}", r.flatten_ms),
                dash(r.to_device_ms, 0),
                dash(r.checked_ms, 0),
                format!("{:.2}", r.flatten_and_device_per_build),
                format!("{:.0}", r.first_trace_ms),
                r.rays.to_string(),
                dash(r.peak_bytes.map(mib), 0),
                dash(r.start_bytes.map(mib), 0),
                dash(r.added_bytes_per_triangle, 0),
            ]);
        }
        out += &t.text();
        out += "\nEach run reads the file anew and goes on as `lancer trace` does: read and \
                checked (every file the read opens counted in MB), build, flatten, to the \
                device (checked, packed, uploaded — or, where the device's memory is the \
                host's, imported where the flatten wrote it — kernel made; none on the CPU, \
                which traces the flattened layout where it is; the check, which every upload runs first, \
                timed once more alone after the trace), and the first trace of the default view's \
                primary rays (a GPU's pipeline compiled on the way). Peak: the most memory the \
                process held resident from the read to the trace (VmHWM, reset before each \
                run; a software GPU's memory included), what it held at the start (the device, \
                its driver, the program), and what the run added per triangle (the rays and hits \
                included). Medians of the runs, each on memory \
                fresh from the system.\n";
        out
    }

    /// Each step's time per million triangles, one group of bars per mesh (the first
    /// trace, whose work grows with the rays, is in the table only).
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
        let categories: Vec<String> = (self.rows.iter())
            .map(|r| format!("{} ({})", super::file_name(&r.mesh), count(r.triangles)))
            .collect();
        let series: Vec<(String, Vec<f64>)> = (STEPS.iter())
            .filter(|(_, f)| self.rows.iter().any(|r| f(r).is_some()))
            .map(|(name, f)| {
                let per_million =
                    |r: &Row| f(r).map_or(f64::NAN, |ms| ms * 1e6 / r.triangles.max(1) as f64);
                (
                    name.to_string(),
                    self.rows.iter().map(per_million).collect(),
                )
            })
            .collect();
        let title = format!(
            "from file to first rays: {} build, {} layout",
            self.builder, self.layout
        );
        for path in paths {
            super::chart::bar_chart(
                path,
                &title,
                "ms per million triangles",
                &categories,
                &series,
            )?;
        }
        Ok(paths.to_vec())
    }
}
