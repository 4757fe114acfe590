//! `lancer bench structures`: every acceleration structure on one mesh or scene, side by
//! side in one run: build time, memory, duplicated references and depth; work per ray
//! (nodes or cells visited, triangles tested) and speed for primary, shadow and random
//! rays, on the CPU and, for the structures with a GPU kernel (BVH, kd-tree, BIH), on the
//! GPU.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::accel::bih::Bih;
use crate::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions, BvhStats};
use crate::accel::grid::{GridStats, HashedGrid, TwoLevelGrid, UniformGrid};
use crate::accel::kdtree::KdTree;
use crate::accel::octree::Octree;
use crate::accel::{Accel, AccelKind, GpuForm, Query, RayStats};
use crate::camera::Camera;
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::geometry::{Ray, Robustness};
use crate::gpu::BvhMemory;
use crate::mesh::{load_mesh, Mesh};
use crate::render::RenderScene;
use crate::trace::{Tracer, TracerOptions};

use super::markdown::Table;
use super::rays::{primary_and_shadow, random_rays, BENCH_SEED};
use super::timing::median;
use super::{BenchReport, Progress, Ticker};

/// What `bench structures` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// The triangles traced.
    pub mesh: Mesh,
    /// The camera of the primary rays (a scene's own; its size is replaced by `width` ×
    /// `height`), or None for the mesh's default view.
    pub camera: Option<Camera>,
    /// The mesh's name in the report (its file).
    pub name: String,
    /// Image width of the primary rays.
    pub width: u32,
    /// Image height of the primary rays.
    pub height: u32,
    /// Random rays (origins uniform in the bounds, directions uniform); None: as many as
    /// primary rays.
    pub random: Option<u32>,
    /// Where to run beside the CPU: auto and gpu time the GPU kernels of the BVH, the
    /// kd-tree and the BIH on any adapter (a software one included); cpu: the CPU alone.
    pub device: DeviceChoice,
    /// GPU: where the kernels read the structure from.
    pub bvh_memory: BvhMemory,
    /// Timed runs per structure and ray set (the median is reported), at least 1.
    pub repeat: usize,
    /// How the BVH is built (`--builder`, `--optimize`, …).
    pub build: BuildOptions,
}

/// The triangles of a mesh file or of a scene (.toml: all its objects), and the scene's
/// camera (None for a mesh: its default view).
pub fn load(path: &Path) -> Result<(Mesh, Option<Camera>)> {
    let is_toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if !is_toml {
        return Ok((load_mesh(path)?, None));
    }
    let scene = RenderScene::from_file(path)?;
    crate::mesh::check_usable(path, &scene.mesh)?;
    Ok((scene.mesh, Some(scene.camera)))
}

/// One structure's build and memory (a JSON `structures` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Size {
    /// The structure's name (`--accel`).
    pub structure: &'static str,
    /// Wall-clock build time (all threads).
    pub build_ms: f64,
    /// Memory of the built structure: nodes or cells, references, triangles.
    pub bytes: u64,
    /// Triangle references beyond one per triangle (0 for the object partitions).
    pub duplicated_references: u64,
    /// Depth of the deepest leaf (null for the grids).
    pub max_depth: Option<usize>,
    /// Whether it has a GPU kernel.
    pub gpu: bool,
}

/// One structure × ray set (a JSON `runs` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// The structure's name (`--accel`).
    pub structure: &'static str,
    /// primary (closest hit), shadow (any hit) or random (closest hit).
    pub rays: &'static str,
    /// Rays in the set.
    pub count: usize,
    /// Mean nodes (trees) or cells (grids) visited per ray.
    pub nodes_per_ray: f64,
    /// Mean triangles tested per ray.
    pub triangles_per_ray: f64,
    /// CPU, all threads, median of `repeat` runs.
    pub cpu_mrays_per_s: f64,
    /// GPU kernel, median of `repeat` runs (GPU time where the adapter reports it);
    /// null without a GPU kernel or a GPU.
    pub gpu_mrays_per_s: Option<f64>,
}

/// `bench structures`' results (`--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The mesh or scene file.
    pub mesh: String,
    /// Triangles traced.
    pub triangles: usize,
    /// Width of the primary rays' image.
    pub width: u32,
    /// Height of the primary rays' image.
    pub height: u32,
    /// The GPU adapter, or "none (CPU only)".
    pub adapter: String,
    /// Where the GPU kernels read the structures from.
    pub bvh_memory: String,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per structure and ray set.
    pub repeat: u64,
    /// One object per structure.
    pub structures: Vec<Size>,
    /// One object per structure and ray set.
    pub runs: Vec<Run>,
    /// The GPU's driver (name and version; None without a GPU).
    #[serde(skip)]
    pub gpu_driver: Option<String>,
}

/// A built structure: its CPU form, its GPU form where it has one, and its size.
struct Built {
    accel: Arc<dyn Accel>,
    layout: Option<Arc<dyn GpuForm>>,
    size: Size,
}

fn build_one(kind: AccelKind, mesh: &Mesh, opts: &BuildOptions) -> Result<Built> {
    let start = Instant::now();
    let grid = |s: GridStats| (s.bytes, s.duplicated, None);
    let (accel, layout, (bytes, duplicated, max_depth)): (
        Arc<dyn Accel>,
        Option<Arc<dyn GpuForm>>,
        _,
    ) = match kind {
        AccelKind::Bvh(layout) => {
            let tree = build(mesh, opts);
            let depth = BvhStats::of(&tree, opts).max_depth;
            let flat: Arc<dyn GpuForm> = try_flatten(layout, &tree, mesh)?.into();
            let info = (flat.bytes() as u64, 0, Some(depth));
            (flat.clone(), Some(flat), info)
        }
        AccelKind::KdTree => {
            let t = Arc::new(KdTree::build(mesh, &Default::default())?);
            let s = t.stats();
            let info = (
                s.bytes as u64,
                s.duplicated_references as u64,
                Some(s.max_depth),
            );
            (t.clone(), Some(t), info)
        }
        AccelKind::UniformGrid => {
            let g = UniformGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Arc::new(g), None, info)
        }
        AccelKind::TwoLevelGrid => {
            let g = TwoLevelGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Arc::new(g), None, info)
        }
        AccelKind::HashedGrid => {
            let g = HashedGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Arc::new(g), None, info)
        }
        AccelKind::Bih => {
            let t = Arc::new(Bih::build(mesh, &Default::default())?);
            let s = t.stats();
            let info = (s.bytes as u64, 0, Some(s.max_depth));
            (t.clone(), Some(t), info)
        }
        AccelKind::Octree => {
            let t = Octree::build(mesh, &Default::default())?;
            let s = t.stats();
            let info = (
                s.bytes as u64,
                s.duplicated_references as u64,
                Some(s.max_depth),
            );
            (Arc::new(t), None, info)
        }
    };
    let size = Size {
        structure: kind.name(),
        build_ms: start.elapsed().as_secs_f64() * 1e3,
        bytes,
        duplicated_references: duplicated,
        max_depth,
        gpu: layout.is_some(),
    };
    Ok(Built {
        accel,
        layout,
        size,
    })
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    let (width, height) = (config.width, config.height);
    let n_primary = width as u64 * height as u64;
    let n_random = config.random.map_or(n_primary, u64::from);
    // Three ray sets and their hits in memory: ~200 bytes a pixel.
    crate::limits::check_image(width, height, 200, "use a smaller --width/--height")?;
    crate::limits::check_memory(
        &format!("{n_random} random rays"),
        n_random as u128 * 200,
        "use fewer --random",
    )?;
    let mesh = &config.mesh;
    let camera = match config.camera {
        Some(c) => Camera { width, height, ..c },
        None => Camera::default_view(&mesh.bounds(), width, height),
    };
    let bvh = flatten(
        LayoutKind::DfsSign,
        &build(mesh, &BuildOptions::default()),
        mesh,
    );
    let (primary, shadow) = primary_and_shadow(mesh, bvh.as_ref(), &camera);
    let random = random_rays(mesh, n_random as usize, BENCH_SEED);
    let sets: [(&'static str, Query, &[Ray]); 3] = [
        ("primary", Query::Closest, &primary),
        ("shadow", Query::Any, &shadow),
        ("random", Query::Closest, &random),
    ];
    let device = super::open_device(config.device)?;
    let kinds = AccelKind::ALL;
    let repeat = config.repeat.max(1);
    let gpu_kinds = match device.is_cpu() {
        true => 0,
        false => kinds.len(), // those without a GPU kernel step over their share
    };
    let total = kinds.len() * (1 + sets.len() * repeat) + gpu_kinds * sets.len() * repeat;
    let ticker = Ticker::new(progress, total as u64);
    let options = TracerOptions {
        memory: config.bvh_memory,
        ..TracerOptions::default()
    };
    let rob = Robustness::default();
    let (mut sizes, mut runs) = (Vec::new(), Vec::new());
    for &kind in kinds {
        ticker.say(format!("building {kind}"));
        let b = build_one(kind, mesh, &config.build)?;
        ticker.inc(1);
        let mut gpu = match (&b.layout, device.is_cpu()) {
            (Some(layout), false) => Some(Tracer::with_layout(&device, layout.clone(), &options)?),
            _ => None,
        };
        for (name, query, rays) in sets {
            ticker.say(format!("{kind}, {name} rays"));
            let n = rays.len() as f64;
            let (mut times, mut stats) = (Vec::new(), Vec::<RayStats>::new());
            for _ in 0..repeat {
                let t0 = Instant::now();
                let (_, s) = b.accel.trace_batch(rays, query, &rob);
                times.push(t0.elapsed().as_secs_f64());
                stats = s;
                ticker.inc(1);
            }
            let (nodes, tris) = RayStats::means(&stats);
            let gpu_mrays = match gpu.as_mut() {
                None => {
                    ticker.inc(gpu_kinds.min(1) as u64 * repeat as u64);
                    None
                }
                Some(g) => {
                    g.trace(&rays[..rays.len().min(1024)], query)?; // compile outside the timing
                    let mut times = Vec::new();
                    for _ in 0..repeat {
                        times.push(super::timing::seconds(g, rays, query)?);
                        ticker.inc(1);
                    }
                    Some(n / median(times) / 1e6)
                }
            };
            runs.push(Run {
                structure: kind.name(),
                rays: name,
                count: rays.len(),
                nodes_per_ray: nodes,
                triangles_per_ray: tris,
                cpu_mrays_per_s: n / median(times) / 1e6,
                gpu_mrays_per_s: gpu_mrays,
            });
        }
        sizes.push(b.size);
    }
    Ok(Report {
        mesh: config.name.clone(),
        triangles: mesh.included().len(),
        width,
        height,
        adapter: super::adapter_of(&device).unwrap_or_else(|| "none (CPU only)".into()),
        bvh_memory: super::kebab(config.bvh_memory),
        cpu_threads: super::cpu_threads(),
        repeat: repeat as u64,
        structures: sizes,
        runs,
        gpu_driver: device.gpu_context().map(|c| c.adapter.driver.clone()),
    })
}

impl Report {
    /// Rays in one set (the first structure's run of it), or 0.
    fn count(&self, rays: &str) -> usize {
        (self.runs.iter())
            .find(|r| r.rays == rays)
            .map_or(0, |r| r.count)
    }
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!("bench structures: {}", super::file_name(&self.mesh))
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = format!(
            "mesh {}  {} triangles  {}x{} primary, {} shadow, {} random rays  {} CPU threads\n",
            self.mesh,
            self.triangles,
            self.width,
            self.height,
            self.count("shadow"),
            self.count("random"),
            self.cpu_threads
        );
        out += &format!(
            "adapter {}  (structures in {})\n\n",
            self.adapter, self.bvh_memory
        );
        let mut sizes = Table::new(&[
            "structure",
            "build ms",
            "bytes",
            "bytes/triangle",
            "duplicated refs",
            "max depth",
            "GPU kernel",
        ]);
        let tris = self.triangles.max(1) as f64;
        for s in &self.structures {
            sizes.row(vec![
                s.structure.to_string(),
                format!("{:.1}", s.build_ms),
                s.bytes.to_string(),
                format!("{:.1}", s.bytes as f64 / tris),
                s.duplicated_references.to_string(),
                s.max_depth.map_or("–".to_string(), |d| d.to_string()),
                (if s.gpu { "yes" } else { "no" }).to_string(),
            ]);
        }
        out += &sizes.text();
        out += "\n";
        let mut runs = Table::new(&[
            "structure",
            "rays",
            "count",
            "nodes or cells/ray",
            "triangles/ray",
            "CPU Mrays/s",
            "GPU Mrays/s",
        ]);
        for r in &self.runs {
            runs.row(vec![
                r.structure.to_string(),
                r.rays.to_string(),
                r.count.to_string(),
                format!("{:.1}", r.nodes_per_ray),
                format!("{:.1}", r.triangles_per_ray),
                format!("{:.2}", r.cpu_mrays_per_s),
                super::markdown::dash(r.gpu_mrays_per_s, 2),
            ]);
        }
        out + &runs.text()
    }

    /// Mrays/s, one group per ray set and device, one bar per structure (none where a
    /// structure has no GPU kernel).
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let gpu = self.gpu_driver.is_some();
        let mut sets: Vec<&str> = Vec::new();
        for r in &self.runs {
            if !sets.contains(&r.rays) {
                sets.push(r.rays);
            }
        }
        let series: Vec<(String, Vec<f64>)> = (self.structures.iter())
            .map(|s| {
                let mut values = Vec::new();
                for r in self.runs.iter().filter(|r| r.structure == s.structure) {
                    values.push(r.cpu_mrays_per_s);
                    if gpu {
                        values.push(r.gpu_mrays_per_s.unwrap_or(f64::NAN));
                    }
                }
                (s.structure.to_string(), values)
            })
            .collect();
        // The driver string names the adapter too (e.g. "llvmpipe Mesa 22.3.6 (LLVM …)").
        let title = format!(
            "{} {}x{}: CPU {} threads, GPU {}",
            super::file_name(&self.mesh),
            self.width,
            self.height,
            self.cpu_threads,
            self.gpu_driver.as_deref().unwrap_or("none")
        );
        let categories = super::chart::device_categories(&sets, gpu);
        for path in paths {
            super::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)?;
        }
        Ok(paths.to_vec())
    }
}
