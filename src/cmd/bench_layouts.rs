//! `lancer bench layouts`: every flattened layout on one mesh, side by side in one run:
//! flatten time, bytes, work per ray (nodes, triangles, bytes loaded), and speed of the CPU
//! twin and of the GPU kernel for primary, shadow, diffuse bounce and random rays; with the
//! `embree` feature, Embree 3 on the same rays as the reference CPU tracer, run beside every
//! timed run so that each row is also a paired ratio to it.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bvh::build;
use lancer::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use lancer::accel::{GpuForm, LeafTri};
use lancer::gpu::{BvhMemory, DriverTracer};
use lancer::{
    Device, DeviceChoice, Query, Ray, RayStats, Result, Robustness, Tracer, TracerOptions,
    TraversalMode,
};

use serde::{Serialize, Serializer};

use super::bench::{median, JsonArg};
use super::bench_structures::random_rays;
use super::check::{layout_choice, LayoutChoice};
use super::input::load_geometry;
use super::out::{check_output, say};
use super::{open_bench_device, spelled, view_ray_sets, BuilderArgs};

#[derive(Args)]
pub struct BenchLayouts {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Width of the default view (primary rays; shadow and bounce rays start at their hits).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the default view.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// auto, gpu or cpu. auto and gpu measure the GPU kernels and the CPU twins side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    /// GPU: where the kernels read the layout from.
    #[arg(long, value_enum, default_value_t = BvhMemory::default())]
    bvh_memory: BvhMemory,
    /// Layouts to measure: a name or all.
    #[arg(long = "layout", value_name = "NAME|all", default_value = "all", value_parser = layout_choice)]
    layouts: LayoutChoice,
    /// Timed runs per layout and ray set (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    json: JsonArg,
    /// Also draw Mrays/s per layout and ray set as a PNG bar chart here (none by default).
    #[arg(long, value_name = "FILE.png")]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: BuilderArgs,
}

/// One layout × mode × ray set (a JSON `runs` entry).
#[derive(Clone, Serialize)]
pub(super) struct Row {
    /// `--layout` name, "driver" (the driver's own traversal through ray queries) or
    /// "embree" (Embree 3, the `embree` feature).
    pub(super) layout: &'static str,
    /// Traversal mode: per-ray or subgroup ("ray-query" on the driver row, "single-ray" on
    /// the embree row).
    pub(super) mode: &'static str,
    /// primary (closest hit), shadow (any hit), bounce (closest hit) or random (closest hit).
    pub(super) rays: String,
    /// Rays in the set.
    pub(super) count: usize,
    /// Mean nodes visited per ray (subgroup rows: loaded by the ray's subgroup); null on
    /// the driver and embree rows (they do not say).
    #[serde(rename = "nodes_per_ray")]
    pub(super) nodes: Option<f64>,
    /// Mean triangles tested per ray (null on the driver and embree rows).
    #[serde(rename = "triangles_per_ray")]
    pub(super) tris: Option<f64>,
    /// Nodes × node size + triangles × 48 bytes (null on the driver and embree rows).
    #[serde(rename = "bytes_loaded_per_ray")]
    pub(super) bytes_loaded: Option<f64>,
    /// CPU twin (or Embree), median of --repeat runs; null on subgroup rows (the twin traces
    /// per ray) and driver rows.
    #[serde(rename = "cpu_mrays_per_s")]
    pub(super) cpu_mrays: Option<f64>,
    /// GPU kernel, median of --repeat runs (GPU time where the adapter reports it); null
    /// without a GPU and on embree rows.
    #[serde(rename = "gpu_mrays_per_s")]
    pub(super) gpu_mrays: Option<f64>,
    /// The CPU twin's rays/s ÷ Embree's in the run right after each timed run (the median of
    /// the --repeat paired ratios); null without the `embree` feature and where
    /// `cpu_mrays_per_s` is.
    pub(super) cpu_vs_embree: Option<f64>,
    /// The GPU kernel's rays/s ÷ Embree's, paired the same way; null without the `embree`
    /// feature and where `gpu_mrays_per_s` is.
    pub(super) gpu_vs_embree: Option<f64>,
}

/// Wall seconds of one run of a tracer on these rays.
pub(super) type TimeRun = Box<dyn Fn(&[Ray], Query) -> f64>;

/// The reference tracer every timed run is paired with (Embree 3, the `embree` feature).
pub(super) struct Reference {
    /// One timed run.
    pub(super) time: TimeRun,
    /// Wall time of its scene build.
    pub(super) build_ms: f64,
    /// Its version ("3.13.5").
    pub(super) version: String,
}

/// The runs of one row: seconds of each timed run of the measured tracer and of the
/// reference right after it (empty without one).
#[derive(Default)]
struct Paired {
    runs: Vec<f64>,
    reference: Vec<f64>,
}

impl Paired {
    /// Mrays/s of the measured tracer on `n` rays: the median run.
    fn mrays(&self, n: usize) -> f64 {
        n as f64 / median(self.runs.clone()) / 1e6
    }

    /// The median of the paired ratios of rays/s (reference seconds ÷ measured seconds),
    /// where there is a reference.
    fn ratio(&self) -> Option<f64> {
        (!self.reference.is_empty()).then(|| {
            median(
                self.runs
                    .iter()
                    .zip(&self.reference)
                    .map(|(t, r)| r / t)
                    .collect(),
            )
        })
    }
}

/// One layout's size (a JSON `layouts` entry).
#[derive(Serialize)]
struct Size {
    /// `--layout` name.
    #[serde(serialize_with = "layout_name")]
    layout: LayoutKind,
    /// Wall time to flatten the BVH into the layout.
    flatten_ms: f64,
    /// Bytes of the layout (nodes and leaf triangles).
    bytes: usize,
    /// Bytes per triangle of the mesh.
    #[serde(rename = "bytes_per_triangle")]
    per_tri: f64,
}

/// The whole run (`--json`).
#[derive(Serialize)]
struct Report<'a> {
    /// The mesh file.
    mesh: String,
    /// Triangles in the mesh.
    triangles: usize,
    /// Width of the default view.
    width: u32,
    /// Height of the default view.
    height: u32,
    /// The GPU adapter, or "none (CPU only)".
    adapter: String,
    /// `--bvh-memory`.
    bvh_memory: String,
    /// CPU threads.
    cpu_threads: usize,
    /// One object per layout.
    layouts: &'a [Size],
    /// Wall time of the driver's build of its own acceleration structure (the driver rows);
    /// null where the adapter has no ray queries or one layout was asked for.
    driver_build_ms: Option<f64>,
    /// Wall time of Embree's scene build (the embree rows); null without the `embree`
    /// feature.
    embree_build_ms: Option<f64>,
    /// Embree's version ("3.13.5"); null without the `embree` feature.
    embree_version: Option<String>,
    /// One object per layout, mode and ray set.
    runs: &'a [Row],
}

fn layout_name<S: Serializer>(k: &LayoutKind, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(k.name())
}

/// Seconds of one run of `tracer`: GPU time where the adapter reports it, else wall time.
fn seconds(tracer: &mut Tracer, rays: &[Ray], query: Query) -> Result<f64> {
    let t = tracer.trace(rays, query)?.timings;
    Ok(t.gpu_ms.unwrap_or(t.wall_ms) * 1e-3)
}

/// `repeat` timed runs (`run` gives one's seconds), each followed by a timed run of the
/// reference on the same rays. Each timed run comes right after an untimed run of the same
/// tracer on the same rays (the first also compiles a GPU kernel), so that both sides of a
/// pair run with their own data in the caches: without it, Embree timed right after
/// lavapipe ran up to 4% slower than right after a CPU twin on the bunny's primary rays.
fn time_paired(
    mut run: impl FnMut() -> Result<f64>,
    reference: Option<&Reference>,
    rays: &[Ray],
    query: Query,
    repeat: usize,
    bar: &ProgressBar,
) -> Result<Paired> {
    let mut paired = Paired::default();
    for _ in 0..repeat {
        run()?;
        paired.runs.push(run()?);
        bar.inc(1);
        if let Some(r) = reference {
            (r.time)(rays, query);
            paired.reference.push((r.time)(rays, query));
            bar.inc(1);
        }
    }
    Ok(paired)
}

/// [`time_paired`] for a tracer, its statistics off while timed.
fn time_tracer(
    tracer: &mut Tracer,
    reference: Option<&Reference>,
    rays: &[Ray],
    query: Query,
    repeat: usize,
    bar: &ProgressBar,
) -> Result<Paired> {
    let o = *tracer.options();
    tracer.set_kernel(o.robustness, o.workgroup_size, false);
    let paired = time_paired(
        || seconds(tracer, rays, query),
        reference,
        rays,
        query,
        repeat,
        bar,
    );
    tracer.set_kernel(o.robustness, o.workgroup_size, o.stats);
    paired
}

/// Runs a timed repetition takes: the measured one, and the reference's beside it.
fn runs_per_repeat(reference: Option<&Reference>) -> usize {
    1 + reference.is_some() as usize
}

/// The driver row's layout and mode names.
const DRIVER: &str = "driver";
const RAY_QUERY: &str = "ray-query";

/// The Embree rows' layout and mode names (the `embree` feature).
pub(super) const EMBREE: &str = "embree";
pub(super) const SINGLE_RAY: &str = "single-ray";

impl BenchLayouts {
    /// The driver's own traversal on each ray set, where the adapter offers ray queries and
    /// every layout is measured: its build time (ms) and one row per set.
    fn time_driver(
        &self,
        device: &Device,
        leaf_order: &dyn GpuForm,
        sets: &[(String, Query, Vec<Ray>)],
        reference: Option<&Reference>,
        bar: &ProgressBar,
    ) -> Result<Option<(f64, Vec<Row>)>> {
        let Some(ctx) = device.gpu_context().filter(|c| c.ray_query) else {
            return Ok(None);
        };
        if !matches!(self.layouts, LayoutChoice::All) {
            return Ok(None);
        }
        let repeat = self.repeat as usize;
        bar.inc_length((sets.len() * repeat * runs_per_repeat(reference)) as u64);
        bar.set_message(DRIVER);
        let mut driver = DriverTracer::new(ctx, leaf_order)?;
        let mut rows = Vec::new();
        for (name, query, rays) in sets {
            let run = || {
                let t = driver.trace(rays, *query)?.1;
                Ok(t.gpu_ms.unwrap_or(t.wall_ms) * 1e-3)
            };
            let paired = time_paired(run, reference, rays, *query, repeat, bar)?;
            rows.push(Row {
                layout: DRIVER,
                mode: RAY_QUERY,
                rays: name.clone(),
                count: rays.len(),
                nodes: None,
                tris: None,
                bytes_loaded: None,
                cpu_mrays: None,
                gpu_mrays: Some(paired.mrays(rays.len())),
                cpu_vs_embree: None,
                gpu_vs_embree: paired.ratio(),
            });
        }
        Ok(Some((driver.build_ms(), rows)))
    }

    /// The reference every timed run is paired with: Embree 3's scene over `mesh` (the
    /// `embree` feature).
    #[cfg(feature = "embree")]
    fn reference(&self, mesh: &lancer::Mesh) -> Result<Option<Reference>> {
        super::embree_row::reference(mesh).map(Some)
    }

    /// Without the `embree` feature: no reference.
    #[cfg(not(feature = "embree"))]
    fn reference(&self, _: &lancer::Mesh) -> Result<Option<Reference>> {
        Ok(None)
    }

    pub fn run(self) -> Result<()> {
        let say = self.json.say();
        self.json.check(std::slice::from_ref(&self.mesh))?;
        if let Some(chart) = &self.chart {
            check_output(chart, std::slice::from_ref(&self.mesh))?;
        }
        let mesh = load_geometry(&self.mesh)?;
        let tree = build(&mesh, &self.build.options());
        let reference_layout = flatten(LayoutKind::DfsSign, &tree, &mesh);
        let rob = Robustness::default();
        let mut sets = view_ray_sets(
            &mesh,
            reference_layout.as_ref(),
            self.width,
            self.height,
            &rob,
        )?;
        // Incoherent rays, as many as primary rays (view_ray_sets checked the count).
        let n_random = sets.first().map_or(0, |s| s.2.len()) as u32;
        sets.push((
            "random".into(),
            Query::Closest,
            random_rays(&mesh, n_random),
        ));
        let device = open_bench_device(self.device)?;
        let reference = self.reference(&mesh)?;
        let kinds = self.layouts.kinds();
        let repeat = self.repeat as usize;
        let per_set =
            repeat * runs_per_repeat(reference.as_ref()) * (1 + !device.is_cpu() as usize);
        let bar = super::out::progress_bar((kinds.len() * sets.len() * per_set) as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let cpu = Device::cpu();
        let (mut sizes, mut rows) = (Vec::new(), Vec::new());
        // Seconds of the reference's runs on each set, beside every layout's.
        let mut reference_runs = vec![Vec::new(); sets.len()];
        for &kind in &kinds {
            bar.set_message(kind.name());
            let start = Instant::now();
            let layout: Arc<dyn GpuForm> = try_flatten(kind, &tree, &mesh)?.into();
            let flatten_ms = start.elapsed().as_secs_f64() * 1e3;
            sizes.push(Size {
                layout: kind,
                flatten_ms,
                bytes: layout.bytes(),
                per_tri: layout.bytes() as f64 / mesh.len().max(1) as f64,
            });
            let options = TracerOptions {
                layout: Some(kind),
                memory: self.bvh_memory,
                stats: true,
                ..TracerOptions::default()
            };
            let mut twin = Tracer::with_layout(&cpu, layout.clone(), &options)?;
            let mut gpu = match device.is_cpu() {
                true => None,
                false => Some(Tracer::with_layout(&device, layout.clone(), &options)?),
            };
            // The subgroup rows, where the layout has the mode and the adapter can run it
            // (else the library's warning says why).
            let mut subgroup = match (&gpu, layout.subgroup_wgsl()) {
                (Some(_), Some(_)) => {
                    let o = TracerOptions {
                        mode: TraversalMode::Subgroup,
                        ..options
                    };
                    let t = Tracer::with_layout(&device, layout.clone(), &o)?;
                    (t.mode() == TraversalMode::Subgroup).then_some(t)
                }
                _ => None,
            };
            if subgroup.is_some() {
                bar.inc_length((sets.len() * repeat * runs_per_repeat(reference.as_ref())) as u64);
            }
            for (set, (name, query, rays)) in sets.iter().enumerate() {
                let stats = twin.trace(rays, *query)?.stats.unwrap_or_default();
                let (nodes, tris) = RayStats::means(&stats);
                let timed =
                    |t: &mut Tracer| time_tracer(t, reference.as_ref(), rays, *query, repeat, &bar);
                let cpu_runs = timed(&mut twin)?;
                let gpu_runs = gpu.as_mut().map(timed).transpose()?;
                for runs in std::iter::once(&cpu_runs).chain(&gpu_runs) {
                    reference_runs[set].extend(&runs.reference);
                }
                let bytes_loaded = |nodes: f64, tris: f64| {
                    nodes * layout.node_bytes() as f64
                        + tris * std::mem::size_of::<LeafTri>() as f64
                };
                rows.push(Row {
                    layout: kind.name(),
                    mode: TraversalMode::PerRay.name(),
                    rays: name.clone(),
                    count: rays.len(),
                    nodes: Some(nodes),
                    tris: Some(tris),
                    bytes_loaded: Some(bytes_loaded(nodes, tris)),
                    cpu_mrays: Some(cpu_runs.mrays(rays.len())),
                    gpu_mrays: gpu_runs.as_ref().map(|g| g.mrays(rays.len())),
                    cpu_vs_embree: cpu_runs.ratio(),
                    gpu_vs_embree: gpu_runs.as_ref().and_then(Paired::ratio),
                });
                if let Some(g) = subgroup.as_mut() {
                    // Work per ray as the subgroup kernel counts it (the union of its lanes').
                    let stats = g.trace(rays, *query)?.stats.unwrap_or_default();
                    let (nodes, tris) = RayStats::means(&stats);
                    let runs = timed(g)?;
                    reference_runs[set].extend(&runs.reference);
                    rows.push(Row {
                        layout: kind.name(),
                        mode: TraversalMode::Subgroup.name(),
                        rays: name.clone(),
                        count: rays.len(),
                        nodes: Some(nodes),
                        tris: Some(tris),
                        bytes_loaded: Some(bytes_loaded(nodes, tris)),
                        cpu_mrays: None,
                        gpu_mrays: Some(runs.mrays(rays.len())),
                        cpu_vs_embree: None,
                        gpu_vs_embree: runs.ratio(),
                    });
                }
            }
        }
        // The leaf order the driver's structure is built in (dfs-sign's).
        let leaf_order = reference_layout.as_ref();
        let driver = self.time_driver(&device, leaf_order, &sets, reference.as_ref(), &bar)?;
        if let Some((_, driver_rows)) = &driver {
            rows.extend(driver_rows.iter().cloned());
        }
        // Embree's rows: the median of all its runs on each set (one beside every timed run).
        let embree_rows: Vec<Row> = match &reference {
            None => Vec::new(),
            Some(_) => sets
                .iter()
                .zip(reference_runs)
                .map(|((name, _, rays), runs)| Row {
                    layout: EMBREE,
                    mode: SINGLE_RAY,
                    rays: name.clone(),
                    count: rays.len(),
                    nodes: None,
                    tris: None,
                    bytes_loaded: None,
                    cpu_mrays: Some(
                        Paired {
                            runs,
                            reference: Vec::new(),
                        }
                        .mrays(rays.len()),
                    ),
                    gpu_mrays: None,
                    cpu_vs_embree: None,
                    gpu_vs_embree: None,
                })
                .collect(),
        };
        rows.extend(embree_rows.iter().cloned());
        bar.finish_and_clear();
        let adapter = device
            .gpu_context()
            .map_or("none (CPU only)".to_string(), |c| c.adapter.to_string());
        say!(
            say,
            "mesh {}  {} triangles  view {}x{}  builder {}  {} CPU threads",
            self.mesh.display(),
            mesh.len(),
            self.width,
            self.height,
            spelled(self.build.options().builder),
            rayon::current_num_threads()
        );
        say!(
            say,
            "adapter {adapter}  (BVH in {})",
            spelled(self.bvh_memory)
        );
        say!(say);
        say!(say, "| layout | flatten ms | bytes | bytes/triangle |");
        say!(say, "|---|---|---|---|");
        for s in &sizes {
            say!(
                say,
                "| {} | {:.1} | {} | {:.1} |",
                s.layout,
                s.flatten_ms,
                s.bytes,
                s.per_tri
            );
        }
        say!(say);
        // The paired ratios' columns, with a reference only.
        let (ratio_head, ratio_rule) = match reference {
            Some(_) => (" CPU ÷ Embree | GPU ÷ Embree |", "---|---|"),
            None => ("", ""),
        };
        say!(say, "| layout | mode | rays | count | nodes/ray | triangles/ray | bytes loaded/ray | CPU twin Mrays/s | GPU Mrays/s |{ratio_head}");
        say!(say, "|---|---|---|---|---|---|---|---|---|{ratio_rule}");
        let or_dash = |x: Option<f64>, digits: usize| {
            x.map_or("–".to_string(), |g| format!("{g:.digits$}"))
        };
        for r in &rows {
            let ratios = match reference {
                Some(_) => format!(
                    " {} | {} |",
                    or_dash(r.cpu_vs_embree, 2),
                    or_dash(r.gpu_vs_embree, 2)
                ),
                None => String::new(),
            };
            say!(
                say,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |{ratios}",
                r.layout,
                r.mode,
                r.rays,
                r.count,
                or_dash(r.nodes, 1),
                or_dash(r.tris, 1),
                or_dash(r.bytes_loaded, 0),
                or_dash(r.cpu_mrays, 2),
                or_dash(r.gpu_mrays, 2)
            );
        }
        match (&driver, device.gpu_context()) {
            (Some((build_ms, _)), _) => say!(
                say,
                "\ndriver rows: the driver's own traversal through ray queries, its acceleration \
                 structure built by the driver in {build_ms:.1} ms over the {} leaf triangles \
                 (in their order); it reports no work counts.",
                LayoutKind::DfsSign
            ),
            (None, Some(c)) if !c.ray_query => say!(
                say,
                "\nno driver rows: {} offers no ray queries (lavapipe from Mesa 25 does)",
                c.adapter
            ),
            _ => {}
        }
        if let Some(r) = &reference {
            say!(
                say,
                "\nembree rows: Embree {}, its scene (build quality medium, Embree's \
                 default) built in {:.1} ms over the mesh's triangles on {} threads; \
                 one ray per call (rtcIntersect1 for closest hits, rtcOccluded1 for any hit) \
                 on the CPU twin's threads, run right after every timed run above (its rows: \
                 the median of those runs); it reports no work counts. ÷ Embree: a row's \
                 rays/s over Embree's in the run right after, the median of the {} pairs.",
                r.version,
                r.build_ms,
                rayon::current_num_threads(),
                repeat
            );
        }
        if rows
            .iter()
            .any(|r| r.mode == TraversalMode::Subgroup.name())
        {
            say!(say);
            say!(
                say,
                "subgroup rows: nodes and triangles its subgroup loaded while a ray was live \
                 (the union of the lanes' traversals; the lanes share each load); the CPU twin \
                 traces per ray."
            );
        }
        if let Some(path) = &self.chart {
            let mut categories = Vec::new();
            for (name, _, _) in &sets {
                categories.push(format!("{name} CPU"));
                if !device.is_cpu() {
                    categories.push(format!("{name} GPU"));
                }
            }
            // One series per layout and mode (subgroup and driver rows have no CPU bar).
            let mut series: Vec<(String, Vec<f64>)> = Vec::new();
            for &kind in &kinds {
                for &mode in TraversalMode::ALL {
                    let mut values = Vec::new();
                    let same = |r: &&Row| r.layout == kind.name() && r.mode == mode.name();
                    for r in rows.iter().filter(same) {
                        values.push(r.cpu_mrays.unwrap_or(f64::NAN));
                        if !device.is_cpu() {
                            values.push(r.gpu_mrays.unwrap_or(f64::NAN));
                        }
                    }
                    if !values.is_empty() {
                        series.push((format!("{kind} ({mode})"), values));
                    }
                }
            }
            if let Some((_, driver_rows)) = &driver {
                let values = driver_rows
                    .iter()
                    .flat_map(|r| [f64::NAN, r.gpu_mrays.unwrap_or(f64::NAN)])
                    .collect();
                series.push((format!("{DRIVER} ({RAY_QUERY})"), values));
            }
            if !embree_rows.is_empty() {
                let mut values = Vec::new();
                for r in &embree_rows {
                    values.push(r.cpu_mrays.unwrap_or(f64::NAN));
                    if !device.is_cpu() {
                        values.push(f64::NAN);
                    }
                }
                series.push((format!("{EMBREE} ({SINGLE_RAY})"), values));
            }
            let gpu_name = device
                .gpu_context()
                .map_or("none".into(), |c| c.adapter.driver.clone());
            let title = format!(
                "{} {}x{}: CPU {} threads, GPU {gpu_name}",
                self.mesh.file_name().unwrap_or_default().to_string_lossy(),
                self.width,
                self.height,
                rayon::current_num_threads()
            );
            super::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)?;
            say!(say, "\nchart -> {}", path.display());
        }
        let report = Report {
            mesh: self.mesh.display().to_string(),
            triangles: mesh.len(),
            width: self.width,
            height: self.height,
            adapter,
            bvh_memory: spelled(self.bvh_memory),
            cpu_threads: rayon::current_num_threads(),
            layouts: &sizes,
            driver_build_ms: driver.as_ref().map(|d| d.0),
            embree_build_ms: reference.as_ref().map(|r| r.build_ms),
            embree_version: reference.as_ref().map(|r| r.version.clone()),
            runs: &rows,
        };
        self.json.write(&report, say)?;
        Ok(())
    }
}
