//! `lancer bench layouts`: every flattened layout on one mesh, side by side in one run:
//! flatten time, bytes, work per ray (nodes, triangles, bytes loaded), and speed of the CPU
//! twin and of the GPU kernel for primary, shadow, diffuse bounce and random rays; the
//! driver's own traversal where the adapter has ray queries; with the `embree` feature,
//! Embree 3 on the same rays as the reference CPU tracer, run beside every timed run so that
//! each row is also a paired ratio to it.

use std::sync::Arc;
use std::time::Instant;

use serde::{Serialize, Serializer};

use crate::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions};
use crate::accel::{GpuForm, LeafTri, Query, RayStats, TraversalMode};
use crate::device::{Device, DeviceChoice};
use crate::error::Result;
use crate::geometry::Robustness;
use crate::gpu::{BvhMemory, DriverTracer};
use crate::mesh::Mesh;
use crate::trace::{Tracer, TracerOptions};

use super::markdown::{dash, Table};
use super::rays::{random_rays, view_ray_sets, RaySet, BENCH_SEED};
use super::timing::{runs_per_repeat, time_paired, time_tracer, Paired, Reference};
use super::{BenchReport, Progress, Ticker};

/// What `bench layouts` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// The mesh.
    pub mesh: Mesh,
    /// The mesh's name in the report (its file).
    pub name: String,
    /// Width of the default view (primary rays; shadow and bounce rays start at their hits).
    pub width: u32,
    /// Height of the default view.
    pub height: u32,
    /// Where to run beside the CPU twins: auto and gpu time the GPU kernels on any adapter
    /// (a software one included); cpu measures the CPU alone.
    pub device: DeviceChoice,
    /// GPU: where the kernels read the layout from.
    pub bvh_memory: BvhMemory,
    /// The layouts to measure, in this order.
    pub layouts: Vec<LayoutKind>,
    /// Also time the driver's own traversal (ray queries), where the adapter offers them.
    pub driver: bool,
    /// Timed runs per layout and ray set (the median is reported), at least 1.
    pub repeat: usize,
    /// How the BVH is built (once, then flattened into every layout).
    pub build: BuildOptions,
}

/// One layout × mode × ray set (a JSON `runs` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// The layout's name, "driver" (the driver's own traversal through ray queries) or
    /// "embree" (Embree 3, the `embree` feature).
    pub layout: &'static str,
    /// Traversal mode: per-ray or subgroup ("ray-query" on the driver row, "single-ray" on
    /// the embree row).
    pub mode: &'static str,
    /// primary (closest hit), shadow (any hit), bounce (closest hit) or random (closest hit).
    pub rays: String,
    /// Rays in the set.
    pub count: usize,
    /// Mean nodes visited per ray (subgroup rows: loaded by the ray's subgroup); null on
    /// the driver and embree rows (they do not say).
    #[serde(rename = "nodes_per_ray")]
    pub nodes: Option<f64>,
    /// Mean triangles tested per ray (null on the driver and embree rows).
    #[serde(rename = "triangles_per_ray")]
    pub tris: Option<f64>,
    /// Nodes × node size + triangles × 48 bytes (null on the driver and embree rows).
    #[serde(rename = "bytes_loaded_per_ray")]
    pub bytes_loaded: Option<f64>,
    /// CPU twin (or Embree), median of `repeat` runs; null on subgroup rows (the twin traces
    /// per ray) and driver rows.
    #[serde(rename = "cpu_mrays_per_s")]
    pub cpu_mrays: Option<f64>,
    /// GPU kernel, median of `repeat` runs (GPU time where the adapter reports it); null
    /// without a GPU and on embree rows.
    #[serde(rename = "gpu_mrays_per_s")]
    pub gpu_mrays: Option<f64>,
    /// The CPU twin's rays/s ÷ Embree's in the run right after each timed run (the median of
    /// the `repeat` paired ratios); null without the `embree` feature and where
    /// `cpu_mrays_per_s` is.
    pub cpu_vs_embree: Option<f64>,
    /// The GPU kernel's rays/s ÷ Embree's, paired the same way; null without the `embree`
    /// feature and where `gpu_mrays_per_s` is.
    pub gpu_vs_embree: Option<f64>,
}

/// One layout's size (a JSON `layouts` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Size {
    /// The layout.
    #[serde(serialize_with = "layout_name")]
    pub layout: LayoutKind,
    /// Wall time to flatten the BVH into the layout.
    pub flatten_ms: f64,
    /// Bytes of the layout (nodes and leaf triangles).
    pub bytes: usize,
    /// Bytes per triangle of the mesh.
    #[serde(rename = "bytes_per_triangle")]
    pub per_tri: f64,
}

/// `bench layouts`' results (`--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The mesh file.
    pub mesh: String,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Width of the default view.
    pub width: u32,
    /// Height of the default view.
    pub height: u32,
    /// The GPU adapter, or "none (CPU only)".
    pub adapter: String,
    /// Where the GPU kernels read the layouts from.
    pub bvh_memory: String,
    /// CPU threads.
    pub cpu_threads: usize,
    /// One object per layout.
    pub layouts: Vec<Size>,
    /// Wall time of the driver's build of its own acceleration structure (the driver rows);
    /// null where the adapter has no ray queries or the driver was not asked for.
    pub driver_build_ms: Option<f64>,
    /// Wall time of Embree's scene build (the embree rows); null without the `embree`
    /// feature.
    pub embree_build_ms: Option<f64>,
    /// Embree's version ("3.13.5"); null without the `embree` feature.
    pub embree_version: Option<String>,
    /// One object per layout, mode and ray set.
    pub runs: Vec<Row>,
    /// The BVH builder.
    #[serde(skip)]
    pub builder: String,
    /// Timed runs per layout and ray set.
    #[serde(skip)]
    pub repeat: usize,
    /// The GPU's driver (name and version; None without a GPU).
    #[serde(skip)]
    pub gpu_driver: Option<String>,
    /// Whether the GPU offers ray queries (None without a GPU).
    #[serde(skip)]
    pub ray_query: Option<bool>,
}

fn layout_name<S: Serializer>(k: &LayoutKind, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(k.name())
}

/// The driver row's layout and mode names.
pub const DRIVER: &str = "driver";
/// The driver row's mode.
pub const RAY_QUERY: &str = "ray-query";
/// The Embree rows' layout name (the `embree` feature).
pub const EMBREE: &str = "embree";
/// The Embree rows' mode.
pub const SINGLE_RAY: &str = "single-ray";

/// The driver's own traversal on each ray set, where the adapter offers ray queries: its
/// build time (ms) and one row per set.
fn time_driver(
    device: &Device,
    leaf_order: &dyn GpuForm,
    sets: &[RaySet],
    reference: Option<&Reference>,
    repeat: usize,
    ticker: &Ticker,
) -> Result<Option<(f64, Vec<Row>)>> {
    let Some(ctx) = device.gpu_context().filter(|c| c.ray_query) else {
        return Ok(None);
    };
    ticker.grow((sets.len() * repeat * runs_per_repeat(reference)) as u64);
    ticker.say(DRIVER);
    let mut driver = DriverTracer::new(ctx, leaf_order)?;
    let mut rows = Vec::new();
    for (name, query, rays) in sets {
        let run = || {
            let t = driver.trace(rays, *query)?.1;
            Ok(t.gpu_ms.unwrap_or(t.wall_ms) * 1e-3)
        };
        let paired = time_paired(run, reference, rays, *query, repeat, ticker)?;
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

/// Embree's scene over `mesh` (medium build quality, Embree's default), built on rayon's
/// thread count, as the bench's reference: `rtcIntersect1` for closest-hit sets,
/// `rtcOccluded1` for any-hit sets, one ray per call on rayon's threads, each call timed
/// on the wall clock.
#[cfg(feature = "embree")]
fn reference(mesh: &Mesh) -> Result<Option<Reference>> {
    let embree = crate::embree::EmbreeTracer::new(mesh, rayon::current_num_threads())?;
    let (build_ms, version) = (embree.build_ms(), embree.version().to_string());
    let time = move |rays: &[crate::geometry::Ray], query: Query| {
        let start = Instant::now();
        match query {
            Query::Closest => drop(embree.closest(rays)),
            Query::Any => drop(embree.occluded(rays)),
        }
        start.elapsed().as_secs_f64()
    };
    Ok(Some(Reference {
        time: Box::new(time),
        build_ms,
        version,
    }))
}

/// Without the `embree` feature: no reference.
#[cfg(not(feature = "embree"))]
fn reference(_: &Mesh) -> Result<Option<Reference>> {
    Ok(None)
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    let mesh = &config.mesh;
    let tree = build(mesh, &config.build);
    let reference_layout = flatten(LayoutKind::DfsSign, &tree, mesh);
    let rob = Robustness::default();
    let mut sets = view_ray_sets(
        mesh,
        reference_layout.as_ref(),
        config.width,
        config.height,
        &rob,
    )?;
    // Incoherent rays, as many as primary rays (view_ray_sets checked the count).
    let n_random = sets.first().map_or(0, |s| s.2.len());
    sets.push((
        "random".into(),
        Query::Closest,
        random_rays(mesh, n_random, BENCH_SEED),
    ));
    let device = super::open_device(config.device)?;
    let reference = reference(mesh)?;
    let kinds = &config.layouts;
    let repeat = config.repeat.max(1);
    let per_set = repeat * runs_per_repeat(reference.as_ref()) * (1 + !device.is_cpu() as usize);
    let ticker = Ticker::new(progress, (kinds.len() * sets.len() * per_set) as u64);
    let cpu = Device::cpu();
    let (mut sizes, mut rows) = (Vec::new(), Vec::new());
    // Seconds of the reference's runs on each set, beside every layout's.
    let mut reference_runs = vec![Vec::new(); sets.len()];
    for &kind in kinds {
        ticker.say(kind.name());
        let start = Instant::now();
        let layout: Arc<dyn GpuForm> = try_flatten(kind, &tree, mesh)?.into();
        sizes.push(Size {
            layout: kind,
            flatten_ms: start.elapsed().as_secs_f64() * 1e3,
            bytes: layout.bytes(),
            per_tri: layout.bytes() as f64 / mesh.len().max(1) as f64,
        });
        let options = TracerOptions {
            layout: Some(kind),
            memory: config.bvh_memory,
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
            ticker.grow((sets.len() * repeat * runs_per_repeat(reference.as_ref())) as u64);
        }
        let bytes_loaded = |nodes: f64, tris: f64| {
            nodes * layout.node_bytes() as f64 + tris * std::mem::size_of::<LeafTri>() as f64
        };
        for (set, (name, query, rays)) in sets.iter().enumerate() {
            let stats = twin.trace(rays, *query)?.stats.unwrap_or_default();
            let (nodes, tris) = RayStats::means(&stats);
            let timed =
                |t: &mut Tracer| time_tracer(t, reference.as_ref(), rays, *query, repeat, &ticker);
            let cpu_runs = timed(&mut twin)?;
            let gpu_runs = gpu.as_mut().map(timed).transpose()?;
            for runs in std::iter::once(&cpu_runs).chain(&gpu_runs) {
                reference_runs[set].extend(&runs.reference);
            }
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
    let driver = match config.driver {
        true => time_driver(
            &device,
            reference_layout.as_ref(),
            &sets,
            reference.as_ref(),
            repeat,
            &ticker,
        )?,
        false => None,
    };
    if let Some((_, driver_rows)) = &driver {
        rows.extend(driver_rows.iter().cloned());
    }
    // Embree's rows: the median of all its runs on each set (one beside every timed run).
    if reference.is_some() {
        for ((name, _, rays), runs) in sets.iter().zip(reference_runs) {
            let runs = Paired {
                runs,
                reference: Vec::new(),
            };
            rows.push(Row {
                layout: EMBREE,
                mode: SINGLE_RAY,
                rays: name.clone(),
                count: rays.len(),
                nodes: None,
                tris: None,
                bytes_loaded: None,
                cpu_mrays: Some(runs.mrays(rays.len())),
                gpu_mrays: None,
                cpu_vs_embree: None,
                gpu_vs_embree: None,
            });
        }
    }
    let ctx = device.gpu_context();
    Ok(Report {
        mesh: config.name.clone(),
        triangles: mesh.len(),
        width: config.width,
        height: config.height,
        adapter: super::adapter_of(&device).unwrap_or_else(|| "none (CPU only)".into()),
        bvh_memory: super::kebab(config.bvh_memory),
        cpu_threads: super::cpu_threads(),
        layouts: sizes,
        driver_build_ms: driver.as_ref().map(|d| d.0),
        embree_build_ms: reference.as_ref().map(|r| r.build_ms),
        embree_version: reference.as_ref().map(|r| r.version.clone()),
        runs: rows,
        builder: super::kebab(config.build.builder),
        repeat,
        gpu_driver: ctx.map(|c| c.adapter.driver.clone()),
        ray_query: ctx.map(|c| c.ray_query),
    })
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!("bench layouts: {}", super::file_name(&self.mesh))
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = format!(
            "mesh {}  {} triangles  view {}x{}  builder {}  {} CPU threads\n",
            self.mesh, self.triangles, self.width, self.height, self.builder, self.cpu_threads
        );
        out += &format!("adapter {}  (BVH in {})\n\n", self.adapter, self.bvh_memory);
        let mut sizes = Table::new(&["layout", "flatten ms", "bytes", "bytes/triangle"]);
        for s in &self.layouts {
            sizes.row(vec![
                s.layout.to_string(),
                format!("{:.1}", s.flatten_ms),
                s.bytes.to_string(),
                format!("{:.1}", s.per_tri),
            ]);
        }
        out += &sizes.text();
        out += "\n";
        // The paired ratios' columns, with a reference only.
        let embree = self.embree_version.is_some();
        let mut head = vec![
            "layout",
            "mode",
            "rays",
            "count",
            "nodes/ray",
            "triangles/ray",
            "bytes loaded/ray",
            "CPU twin Mrays/s",
            "GPU Mrays/s",
        ];
        if embree {
            head.extend(["CPU ÷ Embree", "GPU ÷ Embree"]);
        }
        let mut runs = Table::new(&head);
        for r in &self.runs {
            let mut cells = vec![
                r.layout.to_string(),
                r.mode.to_string(),
                r.rays.clone(),
                r.count.to_string(),
                dash(r.nodes, 1),
                dash(r.tris, 1),
                dash(r.bytes_loaded, 0),
                dash(r.cpu_mrays, 2),
                dash(r.gpu_mrays, 2),
            ];
            if embree {
                cells.extend([dash(r.cpu_vs_embree, 2), dash(r.gpu_vs_embree, 2)]);
            }
            runs.row(cells);
        }
        out += &runs.text();
        match (self.driver_build_ms, self.ray_query) {
            (Some(build_ms), _) => {
                out += &format!(
                    "\ndriver rows: the driver's own traversal through ray queries, its \
                     acceleration structure built by the driver in {build_ms:.1} ms over the {} \
                     leaf triangles (in their order); it reports no work counts.\n",
                    LayoutKind::DfsSign
                )
            }
            (None, Some(false)) => {
                out += &format!(
                    "\nno driver rows: {} offers no ray queries (lavapipe from Mesa 25 does)\n",
                    self.adapter
                )
            }
            _ => {}
        }
        if let (Some(version), Some(build_ms)) = (&self.embree_version, self.embree_build_ms) {
            out += &format!(
                "\nembree rows: Embree {version}, its scene (build quality medium, Embree's \
                 default) built in {build_ms:.1} ms over the mesh's triangles on {} threads; \
                 one ray per call (rtcIntersect1 for closest hits, rtcOccluded1 for any hit) \
                 on the CPU twin's threads, run right after every timed run above (its rows: \
                 the median of those runs); it reports no work counts. ÷ Embree: a row's \
                 rays/s over Embree's in the run right after, the median of the {} pairs.\n",
                self.cpu_threads, self.repeat
            );
        }
        if (self.runs.iter()).any(|r| r.mode == TraversalMode::Subgroup.name()) {
            out += "\nsubgroup rows: nodes and triangles its subgroup loaded while a ray was live \
                    (the union of the lanes' traversals; the lanes share each load); the CPU \
                    twin traces per ray.\n";
        }
        out
    }

    /// Mrays/s, one group per ray set and device (CPU, GPU), one bar per layout and mode
    /// (subgroup and driver rows have no CPU bar, embree rows no GPU bar).
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let gpu = self.gpu_driver.is_some();
        let mut sets: Vec<&str> = Vec::new();
        let mut series: Vec<(String, Vec<f64>)> = Vec::new();
        for r in &self.runs {
            if !sets.contains(&r.rays.as_str()) {
                sets.push(&r.rays);
            }
            let name = format!("{} ({})", r.layout, r.mode);
            let values = match series.iter_mut().find(|s| s.0 == name) {
                Some(s) => &mut s.1,
                None => {
                    series.push((name, Vec::new()));
                    &mut series.last_mut().expect("just pushed").1
                }
            };
            values.push(r.cpu_mrays.unwrap_or(f64::NAN));
            if gpu {
                values.push(r.gpu_mrays.unwrap_or(f64::NAN));
            }
        }
        let categories = super::chart::device_categories(&sets, gpu);
        let title = format!(
            "{} {}x{}: CPU {} threads, GPU {}",
            super::file_name(&self.mesh),
            self.width,
            self.height,
            self.cpu_threads,
            self.gpu_driver.as_deref().unwrap_or("none")
        );
        for path in paths {
            super::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)?;
        }
        Ok(paths.to_vec())
    }
}
