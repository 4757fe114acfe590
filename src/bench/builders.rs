//! `lancer bench builders`: the lecture's closing question — how to choose the best
//! hierarchy a priori? — asked of data. Every builder on every mesh, side by side in one
//! run: build time, peak memory, the a-priori costs of the tree (SAH and end-point overlap),
//! the measured cost of tracing it (nodes and triangles per ray, Mrays/s of the CPU twin and
//! of the GPU kernel, for primary, shadow, diffuse bounce and random rays), and how well each
//! a-priori cost ranks the trees as their measured time does (Spearman's ρ over the builders,
//! per mesh, ray set and device). With the `embree` feature, Embree 3's medium-quality build
//! of the same triangles is timed in the same run.

use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use crate::accel::bvh::{build, epo_cost, BuildOptions, Builder, Bvh, BvhStats};
use crate::accel::{GpuForm, Query, RayStats};
use crate::device::{Device, DeviceChoice};
use crate::error::Result;
use crate::geometry::Robustness;
use crate::gpu::BvhMemory;
use crate::mesh::Mesh;
use crate::trace::{defaults, Tracer, TracerOptions};

use super::markdown::{dash, Table};
use super::memory::{fresh_memory, peak_during, FRESH_MEMORY_NOTE};
use super::rank::spearman;
use super::rays::{random_rays, view_ray_sets, RaySet, BENCH_SEED};
use super::timing::{median, time_tracer};
use super::{BenchReport, Progress, Ticker};

/// What `bench builders` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// The meshes, each with its name in the report (its file).
    pub meshes: Vec<(String, Mesh)>,
    /// The builders compared, in the report's order.
    pub builders: Vec<Builder>,
    /// Also each builder's tree optimised by reinsertion (a row named `BUILDER+reinsert`).
    pub optimize: bool,
    /// The other build options (SAH constants, leaf size, bins), the same for every builder.
    pub build: BuildOptions,
    /// Width of the default view (primary rays; shadow and bounce rays start at their hits;
    /// as many random rays).
    pub width: u32,
    /// Height of the default view.
    pub height: u32,
    /// Where to run beside the CPU (as in `bench layouts`).
    pub device: DeviceChoice,
    /// GPU: where the kernel reads the BVH from.
    pub bvh_memory: BvhMemory,
    /// Timed builds and timed traversals per builder and ray set (medians are reported).
    pub repeat: usize,
}

/// One builder on one mesh (a JSON `builds` entry); Embree's row has only its build time.
#[derive(Clone, Debug, Serialize)]
pub struct BuildRow {
    /// The mesh's name.
    pub mesh: String,
    /// The builder (`--builder`; `+reinsert` when optimised), or "embree-medium".
    pub builder: String,
    /// Wall time of the tree's build, median of `repeat` (Embree: its scene's commit, the
    /// buffers filled before it untimed, median of all its builds on the mesh).
    pub build_ms: f64,
    /// The fastest and the slowest of those builds, in ms: how much the median can move.
    pub build_ms_range: [f64; 2],
    /// Wall time to flatten the tree into the CPU layout traced, median of `repeat`.
    pub flatten_ms: Option<f64>,
    /// (build + flatten) ÷ Embree's build: the medians, Embree's over all its builds on the
    /// mesh (one right after each timed build of every builder; its times are bimodal on a
    /// 2-core machine, a pair alone says little). None without Embree.
    pub vs_embree: Option<f64>,
    /// Most heap bytes the build held at once, in MiB (None where not measured).
    pub peak_mib: Option<f64>,
    /// SAH cost of the tree (T_cube = T_obj = 1 unless set; root area normalised).
    pub sah: Option<f64>,
    /// End-point overlap cost, in the SAH's units.
    pub epo: Option<f64>,
    /// Nodes of the binary tree.
    pub nodes: Option<usize>,
    /// Deepest leaf.
    pub max_depth: Option<usize>,
}

/// One builder × mesh × ray set (a JSON `runs` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// The mesh's name.
    pub mesh: String,
    /// The builder.
    pub builder: String,
    /// primary, shadow (any hit), bounce or random.
    pub rays: String,
    /// Rays in the set.
    pub count: usize,
    /// Mean nodes visited per ray by the CPU twin of the CPU layout.
    pub nodes_per_ray: f64,
    /// Mean triangles tested per ray.
    pub tris_per_ray: f64,
    /// CPU twin, all threads, median of `repeat` runs.
    pub cpu_mrays: f64,
    /// GPU kernel of the GPU layout, median of `repeat` runs (GPU time where reported).
    pub gpu_mrays: Option<f64>,
}

/// How well one predictor ranks the builders' trees as their measured time per ray does, on
/// one ray set and device (a JSON `correlations` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Correlation {
    /// "SAH", "EPO" (a priori), or "measured work" (nodes + triangles per ray, for scale).
    pub predictor: &'static str,
    /// The ray set.
    pub rays: String,
    /// "CPU" or "GPU".
    pub device: &'static str,
    /// Spearman's ρ per mesh (None with fewer than three builders or no spread).
    pub rho: Vec<Option<f64>>,
    /// The mean of the meshes' ρ.
    pub mean_rho: Option<f64>,
    /// Meshes on which the tree this predictor ranks best is the fastest one.
    pub picks_fastest: usize,
}

/// `bench builders`' results (`--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The meshes and their triangle counts.
    pub meshes: Vec<(String, usize)>,
    /// The CPU layout traced by the twin.
    pub cpu_layout: &'static str,
    /// The GPU layout traced by the kernel (None on the CPU alone).
    pub gpu_layout: Option<&'static str>,
    /// Width and height of the default view.
    pub view: (u32, u32),
    /// The GPU adapter, or "none (CPU only)".
    pub adapter: String,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per measurement.
    pub repeat: usize,
    /// Embree's version where its build was timed.
    pub embree_version: Option<String>,
    /// One row per mesh and builder (and Embree).
    pub builds: Vec<BuildRow>,
    /// One row per mesh, builder and ray set.
    pub runs: Vec<Run>,
    /// One row per predictor, ray set and device.
    pub correlations: Vec<Correlation>,
    /// The GPU's driver (None without a GPU).
    #[serde(skip)]
    pub gpu_driver: Option<String>,
}

/// The ray sets of a mesh: the default view's primary, shadow and bounce rays (found with a
/// sweep-built tree; every builder traces the same rays) and as many random rays.
fn ray_sets(mesh: &Mesh, config: &Config) -> Result<Vec<RaySet>> {
    let tree = build(mesh, &config.build);
    let layout = flatten(LayoutKind::DfsSign, &tree, mesh);
    let rob = Robustness::default();
    let mut sets = view_ray_sets(mesh, layout.as_ref(), config.width, config.height, &rob)?;
    let n = sets.first().map_or(0, |s| s.2.len());
    sets.push((
        "random".into(),
        Query::Closest,
        random_rays(mesh, n, BENCH_SEED),
    ));
    Ok(sets)
}

/// Embree's builds beside lancer's: one timed right after each timed lancer build (the
/// `embree` feature; a stand-in that times nothing without it).
struct EmbreePair<'m> {
    #[cfg(feature = "embree")]
    builds: crate::embree::EmbreeBuilds<'m>,
    #[cfg(not(feature = "embree"))]
    builds: std::marker::PhantomData<&'m Mesh>,
    /// Every Embree build time on this mesh, ms.
    times: Vec<f64>,
}

impl<'m> EmbreePair<'m> {
    #[cfg(feature = "embree")]
    fn new(mesh: &'m Mesh) -> Result<Option<Self>> {
        let builds = crate::embree::EmbreeBuilds::new(mesh, rayon::current_num_threads())?;
        Ok(Some(EmbreePair {
            builds,
            times: Vec::new(),
        }))
    }

    #[cfg(not(feature = "embree"))]
    fn new(_: &'m Mesh) -> Result<Option<Self>> {
        Ok(None)
    }

    /// Times one more Embree build.
    #[cfg(feature = "embree")]
    fn time(&mut self) -> Result<()> {
        self.times.push(self.builds.time()?);
        Ok(())
    }

    #[cfg(not(feature = "embree"))]
    fn time(&mut self) -> Result<()> {
        Ok(())
    }

    #[cfg(feature = "embree")]
    fn version(&self) -> String {
        self.builds.version().to_string()
    }

    #[cfg(not(feature = "embree"))]
    fn version(&self) -> String {
        String::new()
    }
}

/// A pause before each timed build, so that the other side's worker threads (rayon's, or
/// Embree's) have stopped spinning: on a machine of few cores they would take turns with the
/// build being timed.
fn settle() {
    std::thread::sleep(std::time::Duration::from_millis(20));
}

/// A builder's timed builds on one mesh.
struct Timed {
    /// The tree (of the last, untimed build).
    bvh: Bvh,
    /// Each timed build, ms.
    ms: Vec<f64>,
    /// Peak heap bytes of the untimed build.
    peak: Option<u64>,
}

/// `repeat` timed builds, each followed by a timed Embree build where there is one (into
/// `embree`'s times), on fresh memory (as a one-shot command's, and as Embree's builds
/// allocate theirs anew); then one more under the peak-memory count.
fn timed_build(
    mesh: &Mesh,
    opts: &BuildOptions,
    repeat: usize,
    mut embree: Option<&mut EmbreePair>,
) -> Result<Timed> {
    let mut times = Vec::new();
    fresh_memory(|| -> Result<()> {
        for _ in 0..repeat {
            settle();
            let start = Instant::now();
            let bvh = build(mesh, opts);
            times.push(start.elapsed().as_secs_f64() * 1e3);
            drop(bvh);
            if let Some(e) = embree.as_deref_mut() {
                settle();
                e.time()?;
            }
        }
        Ok(())
    })?;
    let (bvh, peak) = peak_during(|| build(mesh, opts));
    Ok(Timed {
        bvh,
        ms: times,
        peak,
    })
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    let device = super::open_device(config.device)?;
    let cpu = Device::cpu();
    let gpu_layout = (!device.is_cpu()).then(|| defaults::default_layout(&device));
    let repeat = config.repeat.max(1);
    let sets_per_mesh = 4;
    let per_builder = 1 + sets_per_mesh * repeat * (1 + gpu_layout.is_some() as usize);
    let variants: Vec<(Builder, bool)> = (config.builders.iter())
        .flat_map(|&b| [(b, false), (b, true)])
        .filter(|&(_, o)| !o || config.optimize)
        .collect();
    let gpu_builds = gpu_lbvh_builds(config, &device);
    let ticker = Ticker::new(
        progress,
        (config.meshes.len() * (variants.len() * per_builder + gpu_builds)) as u64,
    );
    let (mut builds, mut runs) = (Vec::new(), Vec::new());
    let mut embree_version = None;
    for (name, mesh) in &config.meshes {
        ticker.say(format!("{name}: rays"));
        let sets = ray_sets(mesh, config)?;
        let mut embree = EmbreePair::new(mesh)?;
        for &(builder, optimize) in &variants {
            let opts = BuildOptions {
                builder,
                optimize,
                ..config.build
            };
            let label = variant_name(&opts);
            ticker.say(format!("{name}: {label}"));
            let Timed {
                bvh,
                ms: times,
                peak,
            } = timed_build(mesh, &opts, repeat, embree.as_mut())?;
            let stats = BvhStats::of(&bvh, &opts);
            // Flattened `repeat` times: the median time, the last layout.
            let mut flatten_times = Vec::new();
            let mut layout = None;
            fresh_memory(|| -> Result<()> {
                for _ in 0..repeat {
                    drop(layout.take());
                    settle();
                    let start = Instant::now();
                    layout = Some(try_flatten(defaults::CPU_LAYOUT, &bvh, mesh)?);
                    flatten_times.push(start.elapsed().as_secs_f64() * 1e3);
                }
                Ok(())
            })?;
            let flatten_ms = median(flatten_times);
            let layout: Arc<dyn GpuForm> = match layout {
                Some(l) => l.into(),
                None => try_flatten(defaults::CPU_LAYOUT, &bvh, mesh)?.into(),
            };
            builds.push(BuildRow {
                mesh: name.clone(),
                builder: label.clone(),
                build_ms_range: range(&times),
                build_ms: median(times),
                flatten_ms: Some(flatten_ms),
                vs_embree: None,
                peak_mib: peak.map(|b| b as f64 / (1u64 << 20) as f64),
                sah: Some(stats.sah_cost),
                epo: Some(epo_cost(&bvh, mesh, &opts)?),
                nodes: Some(stats.nodes),
                max_depth: Some(stats.max_depth),
            });
            ticker.inc(1);
            let options = TracerOptions {
                memory: config.bvh_memory,
                stats: true,
                ..TracerOptions::default()
            };
            let mut twin = Tracer::with_layout(&cpu, layout, &options)?;
            let mut gpu = match gpu_layout {
                Some(kind) => {
                    let layout: Arc<dyn GpuForm> = try_flatten(kind, &bvh, mesh)?.into();
                    Some(Tracer::with_layout(&device, layout, &options)?)
                }
                None => None,
            };
            for (set, query, rays) in &sets {
                let stats = twin.trace(rays, *query)?.stats.unwrap_or_default();
                let (nodes, tris) = RayStats::means(&stats);
                let cpu_runs = time_tracer(&mut twin, None, rays, *query, repeat, &ticker)?;
                let gpu_runs = (gpu.as_mut())
                    .map(|g| time_tracer(g, None, rays, *query, repeat, &ticker))
                    .transpose()?;
                runs.push(Run {
                    mesh: name.clone(),
                    builder: label.clone(),
                    rays: set.clone(),
                    count: rays.len(),
                    nodes_per_ray: nodes,
                    tris_per_ray: tris,
                    cpu_mrays: cpu_runs.mrays(rays.len()),
                    gpu_mrays: gpu_runs.map(|g| g.mrays(rays.len())),
                });
            }
        }
        if let Some(row) = gpu_lbvh_row(config, &device, name, mesh, &builds, &ticker)? {
            builds.push(row);
        }
        if let Some(e) = embree {
            let theirs = median(e.times.clone());
            for b in builds.iter_mut().filter(|b| &b.mesh == name) {
                b.vs_embree = Some((b.build_ms + b.flatten_ms.unwrap_or(0.0)) / theirs);
            }
            embree_version = Some(e.version());
            builds.push(BuildRow {
                mesh: name.clone(),
                builder: EMBREE_MEDIUM.into(),
                build_ms_range: range(&e.times),
                build_ms: median(e.times),
                flatten_ms: None,
                vs_embree: None,
                peak_mib: None,
                sah: None,
                epo: None,
                nodes: None,
                max_depth: None,
            });
        }
    }
    let correlations = correlations(config, &builds, &runs, gpu_layout.is_some());
    let ctx = device.gpu_context();
    Ok(Report {
        meshes: (config.meshes.iter())
            .map(|(n, m)| (n.clone(), m.len()))
            .collect(),
        cpu_layout: defaults::CPU_LAYOUT.name(),
        gpu_layout: gpu_layout.map(LayoutKind::name),
        view: (config.width, config.height),
        adapter: super::adapter_of(&device).unwrap_or_else(|| "none (CPU only)".into()),
        cpu_threads: super::cpu_threads(),
        repeat,
        embree_version,
        builds,
        runs,
        correlations,
        gpu_driver: ctx.map(|c| c.adapter.driver.clone()),
    })
}

/// The name of the row of the LBVH built on the GPU.
pub const LBVH_ON_GPU: &str = "lbvh@gpu";

/// Timed GPU builds per mesh: `repeat` where the bench has a GPU and the LBVH among its
/// builders, else none.
fn gpu_lbvh_builds(config: &Config, device: &Device) -> usize {
    match device.gpu_context().is_some() && config.builders.contains(&Builder::Lbvh) {
        true => config.repeat.max(1),
        false => 0,
    }
}

/// The LBVH built on the GPU (`gpu::build_lbvh`: the tree built there, read back and made
/// lancer's tree): its median build time beside the CPU's `lbvh` row, whose tree it must
/// equal (so the CPU row's costs and runs are its own).
fn gpu_lbvh_row(
    config: &Config,
    device: &Device,
    name: &str,
    mesh: &Mesh,
    builds: &[BuildRow],
    ticker: &Ticker,
) -> Result<Option<BuildRow>> {
    let (Some(ctx), true) = (device.gpu_context(), gpu_lbvh_builds(config, device) > 0) else {
        return Ok(None);
    };
    let Some(cpu_row) = builds
        .iter()
        .find(|b| b.mesh == name && b.builder == Builder::Lbvh.name())
    else {
        return Ok(None);
    };
    let opts = BuildOptions {
        builder: Builder::Lbvh,
        optimize: false,
        ..config.build
    };
    ticker.say(format!("{name}: {LBVH_ON_GPU}"));
    let cpu_tree = build(mesh, &opts);
    let mut times = Vec::new();
    for _ in 0..config.repeat.max(1) {
        settle();
        let start = Instant::now();
        let tree = crate::gpu::build_lbvh(ctx, mesh, &opts)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        if tree != cpu_tree {
            return Err(crate::Error::Gpu(format!(
                "{name}: the LBVH built on {} differs from the CPU's (a bug: please report it)",
                ctx.adapter.name
            )));
        }
        ticker.inc(1);
    }
    Ok(Some(BuildRow {
        builder: LBVH_ON_GPU.into(),
        build_ms_range: range(&times),
        build_ms: median(times),
        flatten_ms: None,
        vs_embree: None,
        peak_mib: None,
        ..cpu_row.clone()
    }))
}

/// The fastest and the slowest of some timings.
fn range(times: &[f64]) -> [f64; 2] {
    let (lo, hi) = super::timing::min_max(times);
    [lo, hi]
}

/// A tree's name in the report: the builder's, `+reinsert` when optimised.
pub fn variant_name(opts: &BuildOptions) -> String {
    match opts.optimize {
        true => format!("{}+reinsert", opts.builder.name()),
        false => opts.builder.name().to_string(),
    }
}

/// The name of Embree's row.
pub const EMBREE_MEDIUM: &str = "embree-medium";

/// For each predictor, ray set and device: Spearman's ρ over the builders between the
/// predictor and the seconds per ray, per mesh; and on how many meshes the predictor's best
/// tree is the fastest.
fn correlations(config: &Config, builds: &[BuildRow], runs: &[Run], gpu: bool) -> Vec<Correlation> {
    let mut out = Vec::new();
    let sets: Vec<String> = runs
        .iter()
        .map(|r| r.rays.clone())
        .fold(Vec::new(), |mut v, s| {
            if !v.contains(&s) {
                v.push(s);
            }
            v
        });
    let devices: &[&'static str] = if gpu { &["CPU", "GPU"] } else { &["CPU"] };
    for predictor in ["SAH", "EPO", "measured work"] {
        for set in &sets {
            for &device in devices {
                let (mut rho, mut picks) = (Vec::new(), 0);
                for (mesh, _) in &config.meshes {
                    let mut pairs = Vec::new();
                    for r in runs.iter().filter(|r| &r.mesh == mesh && &r.rays == set) {
                        let b = builds
                            .iter()
                            .find(|b| b.mesh == r.mesh && b.builder == r.builder);
                        let x = match predictor {
                            "SAH" => b.and_then(|b| b.sah),
                            "EPO" => b.and_then(|b| b.epo),
                            _ => Some(r.nodes_per_ray + r.tris_per_ray),
                        };
                        let mrays = if device == "CPU" {
                            Some(r.cpu_mrays)
                        } else {
                            r.gpu_mrays
                        };
                        if let (Some(x), Some(m)) = (x, mrays) {
                            pairs.push((x, 1.0 / m));
                        }
                    }
                    let (x, y): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
                    rho.push(spearman(&x, &y));
                    let best = |v: &[f64]| (0..v.len()).min_by(|&a, &b| v[a].total_cmp(&v[b]));
                    if !x.is_empty() && best(&x) == best(&y) {
                        picks += 1;
                    }
                }
                let known: Vec<f64> = rho.iter().flatten().copied().collect();
                let mean_rho =
                    (!known.is_empty()).then(|| known.iter().sum::<f64>() / known.len() as f64);
                out.push(Correlation {
                    predictor,
                    rays: set.clone(),
                    device,
                    rho,
                    mean_rho,
                    picks_fastest: picks,
                });
            }
        }
    }
    out
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &["", "sah"];

    fn title(&self) -> String {
        let names: Vec<String> = self.meshes.iter().map(|m| super::file_name(&m.0)).collect();
        format!("bench builders: {}", names.join(", "))
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = String::new();
        for (name, tris) in &self.meshes {
            out += &format!("mesh {name}  {tris} triangles\n");
        }
        out += &format!(
            "view {}x{}  CPU twin of {}  {} CPU threads  GPU {} ({})  median of {}\n\n",
            self.view.0,
            self.view.1,
            self.cpu_layout,
            self.cpu_threads,
            self.gpu_layout.unwrap_or("–"),
            self.adapter,
            self.repeat
        );
        let mut t = Table::new(&[
            "mesh",
            "builder",
            "build ms (range)",
            "flatten ms",
            "(build + flatten) ÷ Embree",
            "peak MiB",
            "SAH",
            "EPO",
            "nodes",
            "depth",
        ]);
        for b in &self.builds {
            t.row(vec![
                super::file_name(&b.mesh),
                b.builder.clone(),
                format!(
                    "{:.1} ({:.1}–{:.1})",
                    b.build_ms, b.build_ms_range[0], b.build_ms_range[1]
                ),
                dash(b.flatten_ms, 1),
                dash(b.vs_embree, 2),
                dash(b.peak_mib, 1),
                dash(b.sah, 2),
                dash(b.epo, 2),
                b.nodes.map_or("–".into(), |n| n.to_string()),
                b.max_depth.map_or("–".into(), |n| n.to_string()),
            ]);
        }
        out += &t.text();
        out += "\n";
        let mut t = Table::new(&[
            "mesh",
            "builder",
            "rays",
            "nodes/ray",
            "triangles/ray",
            "CPU Mrays/s",
            "GPU Mrays/s",
        ]);
        for r in &self.runs {
            t.row(vec![
                super::file_name(&r.mesh),
                r.builder.clone(),
                r.rays.clone(),
                format!("{:.1}", r.nodes_per_ray),
                format!("{:.1}", r.tris_per_ray),
                format!("{:.2}", r.cpu_mrays),
                dash(r.gpu_mrays, 2),
            ]);
        }
        out += &t.text();
        out += "\n";
        let mut head = vec!["predictor".to_string(), "rays".into(), "device".into()];
        head.extend(
            self.meshes
                .iter()
                .map(|m| format!("ρ {}", super::file_name(&m.0))),
        );
        head.extend(["mean ρ".into(), "picks the fastest".into()]);
        let mut t = Table::new(&head);
        for c in &self.correlations {
            let mut cells = vec![
                c.predictor.to_string(),
                c.rays.clone(),
                c.device.to_string(),
            ];
            cells.extend(c.rho.iter().map(|r| dash(*r, 2)));
            cells.push(dash(c.mean_rho, 2));
            cells.push(format!("{} of {}", c.picks_fastest, self.meshes.len()));
            t.row(cells);
        }
        out += &t.text();
        out += "\nbuild ms (range): the median build, and the fastest and slowest of the \
                builds it is the median of.\n";
        out += "(build + flatten) ÷ Embree: lancer's tree built and flattened into the CPU \
                layout it traces, against Embree 3's medium-quality scene build (its commit, \
                which leaves the BVH ready to trace; the copy of the triangles into its \
                buffers before it is not timed) of the same triangles on the same threads, \
                timed right after each build; the medians (Embree's over all its builds on the mesh). Both start \
                on fresh memory: ";
        out += FRESH_MEMORY_NOTE;
        out += "\n";
        out += "ρ: Spearman's rank correlation over the builders between the predictor and the \
                time per ray (1 = it orders the trees exactly as their speed does). SAH and \
                EPO are known before tracing; measured work (nodes + triangles per ray) is \
                shown for scale.\n";
        out
    }

    /// Build time per mesh (one bar per builder and Embree); and, where a second path is
    /// given, each tree's SAH against its CPU time per ray, both relative to the first
    /// builder's on the same mesh.
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let Some(build_chart) = paths.first() else {
            return Ok(Vec::new());
        };
        let meshes: Vec<String> = self.meshes.iter().map(|m| super::file_name(&m.0)).collect();
        let mut names: Vec<String> = Vec::new();
        for b in &self.builds {
            if !names.contains(&b.builder) {
                names.push(b.builder.clone());
            }
        }
        // Each builder's row on each mesh (None where it has none): its bar and whisker.
        let rows: Vec<Vec<Option<&BuildRow>>> = (names.iter())
            .map(|n| {
                (self.meshes.iter())
                    .map(|(m, _)| (self.builds.iter()).find(|b| &b.mesh == m && &b.builder == n))
                    .collect()
            })
            .collect();
        let series: Vec<(String, Vec<f64>)> = (names.iter().zip(&rows))
            .map(|(n, r)| {
                (
                    n.clone(),
                    r.iter()
                        .map(|b| b.map_or(f64::NAN, |b| b.build_ms))
                        .collect(),
                )
            })
            .collect();
        let ranges: Vec<Vec<[f64; 2]>> = (rows.iter())
            .map(|r| {
                r.iter()
                    .map(|b| b.map_or([f64::NAN; 2], |b| b.build_ms_range))
                    .collect()
            })
            .collect();
        let title = format!(
            "BVH build, {} CPU threads (median; whiskers: fastest to slowest)",
            self.cpu_threads
        );
        super::chart::bar_chart_with_ranges(
            build_chart,
            &title,
            "build time (ms)",
            &meshes,
            &series,
            &ranges,
        )?;
        let Some(sah_chart) = paths.get(1) else {
            return Ok(vec![build_chart.clone()]);
        };
        let mut sets: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for r in &self.runs {
            let first = self
                .runs
                .iter()
                .find(|f| f.mesh == r.mesh && f.rays == r.rays);
            let sah = |builder: &str| {
                (self.builds.iter())
                    .find(|b| b.mesh == r.mesh && b.builder == builder)
                    .and_then(|b| b.sah)
            };
            let (Some(first), Some(s)) = (first, sah(&r.builder)) else {
                continue;
            };
            let Some(s0) = sah(&first.builder) else {
                continue;
            };
            let point = (s / s0, first.cpu_mrays / r.cpu_mrays);
            match sets.iter_mut().find(|(n, _)| n == &r.rays) {
                Some((_, pts)) => pts.push(point),
                None => sets.push((r.rays.clone(), vec![point])),
            }
        }
        let title = "SAH vs CPU time per ray, relative to the first builder";
        super::chart::xy_chart(
            sah_chart,
            title,
            "SAH ÷ first builder's",
            "time per ray ÷ first builder's",
            false,
            false,
            &sets,
            true,
        )?;
        Ok(vec![build_chart.clone(), sah_chart.clone()])
    }
}
