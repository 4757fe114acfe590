//! `lancer bench structures`: every acceleration structure on one mesh or scene, side by side
//! in one run: build time, memory, duplicated references and depth; work per ray (nodes or
//! cells visited, triangles tested) and speed for primary, shadow and random rays, on the
//! CPU and, for the structures with a GPU kernel (BVH, kd-tree, BIH), on the GPU. Markdown on
//! stdout, optionally JSON (`--json`) and a PNG bar chart (`--chart`).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use indicatif::ProgressStyle;
use lancer::accel::bih::Bih;
use lancer::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions, BvhStats};
use lancer::accel::grid::{GridStats, HashedGrid, TwoLevelGrid, UniformGrid};
use lancer::accel::kdtree::KdTree;
use lancer::accel::octree::Octree;
use lancer::accuracy::random_dir;
use lancer::camera::Camera;
use lancer::gpu::BvhMemory;
use lancer::mesh::load_mesh;
use lancer::render::{RenderScene, Rng};
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{
    Accel, AccelKind, Device, DeviceChoice, GpuForm, Mesh, Query, Ray, RayStats, Result,
    Robustness, Tracer, TracerOptions,
};
use serde::Serialize;

use super::bench::JsonArg;
use super::out::{check_output, say};
use super::{open_bench_device, spelled};
use lancer::bench::timing::median;

#[derive(Args)]
pub struct BenchStructures {
    /// Mesh (.obj, .ply, .gltf, .glb; primary rays from its default view) or TOML scene (all its objects, primary
    /// rays from its camera), e.g. scenes/teapot-in-stadium.toml.
    mesh: PathBuf,
    /// Image width of the primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height of the primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// Random rays: origins uniform in the bounds, directions uniform (default: as many as
    /// primary rays).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    random: Option<u32>,
    /// auto, gpu or cpu. auto and gpu measure the GPU kernels of the BVH, the kd-tree and the BIH and the CPU side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    /// GPU: where the kernels read the structure from.
    #[arg(long, value_enum, default_value_t = BvhMemory::default())]
    bvh_memory: BvhMemory,
    /// Timed runs per structure and ray set (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    json: JsonArg,
    /// Also draw Mrays/s per structure and ray set (CPU, GPU) as a PNG bar chart here (none
    /// by default).
    #[arg(long, value_name = "FILE.png")]
    chart: Option<PathBuf>,
}

/// A built structure: its CPU form, its GPU form where it has one, and its size.
struct Built {
    accel: Arc<dyn Accel>,
    layout: Option<Arc<dyn GpuForm>>,
    size: Size,
}

/// One structure's build and memory (a JSON `structures` entry).
#[derive(Serialize)]
struct Size {
    /// `--accel` name.
    structure: &'static str,
    /// Wall-clock build time (all threads).
    build_ms: f64,
    /// Memory of the built structure: nodes or cells, references, triangles.
    bytes: u64,
    /// Triangle references beyond one per triangle (0 for the object partitions).
    duplicated_references: u64,
    /// Depth of the deepest leaf (null for the grids).
    max_depth: Option<usize>,
    /// Whether it has a GPU kernel.
    gpu: bool,
}

/// One structure × ray set (a JSON `runs` entry).
#[derive(Serialize)]
struct Run {
    /// `--accel` name.
    structure: &'static str,
    /// primary (closest hit), shadow (any hit) or random (closest hit).
    rays: &'static str,
    /// Rays in the set.
    count: usize,
    /// Mean nodes (trees) or cells (grids) visited per ray.
    nodes_per_ray: f64,
    /// Mean triangles tested per ray.
    triangles_per_ray: f64,
    /// CPU, all threads, median of `repeat` runs.
    cpu_mrays_per_s: f64,
    /// GPU kernel, median of `repeat` runs (GPU time where the adapter reports it);
    /// null without a GPU kernel or a GPU.
    gpu_mrays_per_s: Option<f64>,
}

/// The whole run (the JSON file).
#[derive(Serialize)]
struct Report<'a> {
    /// The mesh or scene file.
    mesh: String,
    /// Triangles traced.
    triangles: usize,
    /// Width of the primary rays' image.
    width: u32,
    /// Height of the primary rays' image.
    height: u32,
    /// The GPU adapter, or "none (CPU only)".
    adapter: String,
    /// `--bvh-memory`.
    bvh_memory: String,
    /// CPU threads.
    cpu_threads: usize,
    /// Timed runs per structure and ray set.
    repeat: u64,
    /// One object per structure.
    structures: &'a [Size],
    /// One object per structure and ray set.
    runs: &'a [Run],
}

fn build_one(kind: AccelKind, mesh: &Mesh) -> Result<Built> {
    let start = Instant::now();
    let grid = |s: GridStats| (s.bytes, s.duplicated, None);
    let (accel, layout, (bytes, duplicated, max_depth)): (
        Arc<dyn Accel>,
        Option<Arc<dyn GpuForm>>,
        _,
    ) = match kind {
        AccelKind::Bvh(layout) => {
            let opts = BuildOptions::default();
            let tree = build(mesh, &opts);
            let depth = BvhStats::of(&tree, &opts).max_depth;
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

/// The mesh and the camera of the primary rays: a scene's own, or an OBJ's default view.
fn load(path: &Path, width: u32, height: u32) -> Result<(Mesh, Camera)> {
    let is_toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if !is_toml {
        let mesh = load_mesh(path)?;
        let camera = Camera::default_view(&mesh.bounds(), width, height);
        return Ok((mesh, camera));
    }
    let scene = RenderScene::from_file(path)?;
    lancer::mesh::check_usable(path, &scene.mesh)?;
    let camera = Camera {
        width,
        height,
        ..scene.camera
    };
    Ok((scene.mesh, camera))
}

/// `n` rays from origins uniform in the mesh's bounds, directions uniform on the sphere
/// (the same rays every run).
pub fn random_rays(mesh: &Mesh, n: u32) -> Vec<Ray> {
    let b = mesh.bounds();
    (0..n)
        .map(|i| {
            let mut rng = Rng::new(0x5eed, i, 0);
            let f = glam::Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let o = b.lo + (b.hi - b.lo) * f;
            Ray::new(o, random_dir(&mut rng), 0.0, f32::MAX)
        })
        .collect()
}

impl BenchStructures {
    pub fn run(self) -> Result<()> {
        let say = self.json.say();
        self.json.check(std::slice::from_ref(&self.mesh))?;
        if let Some(chart) = &self.chart {
            check_output(chart, std::slice::from_ref(&self.mesh))?;
        }
        let n_primary = self.width as u64 * self.height as u64;
        let n_random = self.random.map_or(n_primary, u64::from);
        // Three ray sets and their hits in memory: ~200 bytes a pixel.
        lancer::limits::check_image(
            self.width,
            self.height,
            200,
            "use a smaller --width/--height",
        )?;
        lancer::limits::check_memory(
            &format!("{n_random} random rays"),
            n_random as u128 * 200,
            "use fewer --random",
        )?;
        let (mesh, camera) = load(&self.mesh, self.width, self.height)?;
        let primary = camera.primary_rays();
        let rob = Robustness::default();
        let bvh = flatten(
            LayoutKind::DfsSign,
            &build(&mesh, &BuildOptions::default()),
            &mesh,
        );
        let (hits, _) = bvh.trace_batch(&primary, Query::Closest, &rob);
        let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
        let random = random_rays(&mesh, n_random as u32);
        let sets: [(&'static str, Query, &[Ray]); 3] = [
            ("primary", Query::Closest, &primary),
            ("shadow", Query::Any, &shadow),
            ("random", Query::Closest, &random),
        ];
        let device = open_bench_device(self.device)?;
        let kinds = AccelKind::ALL;
        let repeat = self.repeat as usize;
        let gpu_kinds = match device.is_cpu() {
            true => 0,
            false => kinds.len(), // those without a GPU kernel step over their share
        };
        let runs_total = kinds.len() * (1 + sets.len() * repeat) + gpu_kinds * sets.len() * repeat;
        let bar = super::out::progress_bar(runs_total as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let options = TracerOptions {
            memory: self.bvh_memory,
            ..TracerOptions::default()
        };
        let (mut sizes, mut runs) = (Vec::new(), Vec::new());
        for &kind in kinds {
            bar.set_message(format!("building {kind}"));
            let b = build_one(kind, &mesh)?;
            bar.inc(1);
            let mut gpu = match (&b.layout, device.is_cpu()) {
                (Some(layout), false) => {
                    Some(Tracer::with_layout(&device, layout.clone(), &options)?)
                }
                _ => None,
            };
            for (name, query, rays) in sets {
                bar.set_message(format!("{kind}, {name} rays"));
                let n = rays.len() as f64;
                let (mut times, mut stats) = (Vec::new(), Vec::<RayStats>::new());
                for _ in 0..repeat {
                    let t0 = Instant::now();
                    let (_, s) = b.accel.trace_batch(rays, query, &rob);
                    times.push(t0.elapsed().as_secs_f64());
                    stats = s;
                    bar.inc(1);
                }
                let (nodes, tris) = RayStats::means(&stats);
                let gpu_mrays = match gpu.as_mut() {
                    None => {
                        bar.inc(gpu_kinds.min(1) as u64 * repeat as u64);
                        None
                    }
                    Some(g) => {
                        g.trace(&rays[..rays.len().min(1024)], query)?; // compile outside the timing
                        let mut times = Vec::new();
                        for _ in 0..repeat {
                            let t = g.trace(rays, query)?.timings;
                            times.push(t.gpu_ms.unwrap_or(t.wall_ms) * 1e-3);
                            bar.inc(1);
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
        bar.finish_and_clear();
        let adapter = device
            .gpu_context()
            .map_or("none (CPU only)".to_string(), |c| c.adapter.to_string());
        say!(
            say,
            "mesh {}  {} triangles  {}x{} primary, {} shadow, {} random rays  {} CPU threads",
            self.mesh.display(),
            mesh.included().len(),
            self.width,
            self.height,
            shadow.len(),
            random.len(),
            rayon::current_num_threads()
        );
        say!(
            say,
            "adapter {adapter}  (structures in {})",
            spelled(self.bvh_memory)
        );
        say!(say);
        say!(say, "| structure | build ms | bytes | bytes/triangle | duplicated refs | max depth | GPU kernel |");
        say!(say, "|---|---|---|---|---|---|---|");
        let tris = mesh.included().len().max(1) as f64;
        for s in &sizes {
            let depth = s.max_depth.map_or("–".to_string(), |d| d.to_string());
            say!(
                say,
                "| {} | {:.1} | {} | {:.1} | {} | {depth} | {} |",
                s.structure,
                s.build_ms,
                s.bytes,
                s.bytes as f64 / tris,
                s.duplicated_references,
                if s.gpu { "yes" } else { "no" }
            );
        }
        say!(say);
        say!(say, "| structure | rays | count | nodes or cells/ray | triangles/ray | CPU Mrays/s | GPU Mrays/s |");
        say!(say, "|---|---|---|---|---|---|---|");
        for r in &runs {
            let gpu = r
                .gpu_mrays_per_s
                .map_or("–".to_string(), |g| format!("{g:.2}"));
            say!(
                say,
                "| {} | {} | {} | {:.1} | {:.1} | {:.2} | {gpu} |",
                r.structure,
                r.rays,
                r.count,
                r.nodes_per_ray,
                r.triangles_per_ray,
                r.cpu_mrays_per_s
            );
        }
        if let Some(path) = &self.chart {
            self.draw_chart(path, &device, &sets.map(|s| s.0), &runs)?;
            say!(say, "\nchart -> {}", path.display());
        }
        {
            let report = Report {
                mesh: self.mesh.display().to_string(),
                triangles: mesh.included().len(),
                width: self.width,
                height: self.height,
                adapter,
                bvh_memory: spelled(self.bvh_memory),
                cpu_threads: rayon::current_num_threads(),
                repeat: self.repeat,
                structures: &sizes,
                runs: &runs,
            };
            self.json.write(&report, say)?;
        }
        Ok(())
    }

    /// Mrays/s, one group per ray set and device, one bar per structure (none where a
    /// structure has no GPU kernel).
    fn draw_chart(&self, path: &Path, device: &Device, sets: &[&str], runs: &[Run]) -> Result<()> {
        let gpu = !device.is_cpu();
        let mut categories = Vec::new();
        for name in sets {
            categories.push(format!("{name} CPU"));
            if gpu {
                categories.push(format!("{name} GPU"));
            }
        }
        let mut series: Vec<(String, Vec<f64>)> = Vec::new();
        for &kind in AccelKind::ALL {
            let mut values = Vec::new();
            for r in runs.iter().filter(|r| r.structure == kind.name()) {
                values.push(r.cpu_mrays_per_s);
                if gpu {
                    values.push(r.gpu_mrays_per_s.unwrap_or(f64::NAN));
                }
            }
            series.push((kind.name().to_string(), values));
        }
        // The driver string names the adapter too (e.g. "llvmpipe Mesa 22.3.6 (LLVM …)").
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
        lancer::bench::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)
    }
}
