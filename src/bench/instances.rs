//! `lancer bench instances`: a mesh placed many times, traced in two levels (a BVH per mesh
//! under a BVH over the instances) against its flattened copy (one BVH over every copy's
//! triangles), side by side in one run: build time, bytes, work per ray and speed for
//! primary and shadow rays on the CPU twin and the GPU kernel; and the two-level build over
//! 10² to 10⁵ instances of one triangle, where the top level is all the work. With the
//! `embree` feature, Embree 3 on the same rays as the reference: its own instances (one
//! scene over the mesh, an instance geometry per copy) and one scene over the flattened copy.

use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::accel::bvh::layouts::{try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions};
use crate::accel::instances::{Affine, GpuTwoLevel, Instance, InstanceSet};
use crate::accel::{GpuForm, Query, RayStats};
use crate::camera::Camera;
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::geometry::{Ray, Robustness, Triangle};
use crate::gpu::BvhMemory;
use crate::mesh::Mesh;
use crate::trace::{Tracer, TracerOptions};

use super::markdown::Table;
use super::memory::{fresh_memory, FRESH_MEMORY_NOTE};
use super::rays::primary_and_shadow;
use super::timing::{median, TimeRun};
use super::{BenchReport, Progress, Ticker};

/// Instance counts of the top-level build rows.
pub const TOP_LEVEL_COUNTS: [usize; 4] = [100, 1_000, 10_000, 100_000];

/// What `bench instances` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// The mesh placed.
    pub mesh: Mesh,
    /// The mesh's name in the report (its file).
    pub name: String,
    /// Copies placed, on a square grid in x and z, each turned about y.
    pub copies: usize,
    /// Image size of the primary rays (the default view of all the copies).
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Where to run beside the CPU (auto and gpu: any adapter, software included).
    pub device: DeviceChoice,
    /// GPU: where the kernels read the arrays from.
    pub bvh_memory: BvhMemory,
    /// The bottom levels' layout (and the flattened copy's); None: the device's default.
    pub layout: Option<LayoutKind>,
    /// Timed runs per variant and ray set (the median is reported), at least 1.
    pub repeat: usize,
    /// How the BVHs are built.
    pub build: BuildOptions,
}

/// One variant's build and memory (a JSON `variants` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Size {
    /// instanced or flattened.
    pub variant: &'static str,
    /// Wall-clock time to build and flatten (all threads).
    pub build_ms: f64,
    /// Bytes of the GPU arrays (nodes and triangles; for instanced, every mesh's and the
    /// top level's).
    pub bytes: u64,
    /// Triangles stored (instanced: the mesh's, once).
    pub triangles: u64,
}

/// One variant × ray set (a JSON `runs` entry).
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// instanced or flattened.
    pub variant: &'static str,
    /// primary (closest hit) or shadow (any hit).
    pub rays: &'static str,
    /// Rays in the set.
    pub count: usize,
    /// Mean nodes visited per ray (both levels).
    pub nodes_per_ray: f64,
    /// Mean triangles tested per ray.
    pub triangles_per_ray: f64,
    /// CPU twin, all threads, median of `repeat` runs.
    pub cpu_mrays_per_s: f64,
    /// GPU kernel, median of `repeat` runs; null without a GPU.
    pub gpu_mrays_per_s: Option<f64>,
}

/// Time per ray, instanced ÷ flattened, of one ray set (a JSON `ratios` entry): the
/// median over timed pairs (the two variants run in turns), >1 where instanced is slower.
#[derive(Clone, Debug, Serialize)]
pub struct Ratio {
    /// primary or shadow.
    pub rays: &'static str,
    /// CPU twins.
    pub cpu: f64,
    /// GPU kernels; null without a GPU.
    pub gpu: Option<f64>,
}

/// Embree 3's rows (the `embree` feature; the JSON `embree` object): its own instances and
/// its scene over the flattened copy, traced on the CPU on the same rays in turns with
/// lancer's variants.
#[derive(Clone, Debug, Serialize)]
pub struct EmbreeRows {
    /// Embree's version ("3.13.5").
    pub version: String,
    /// Build time of each variant (instanced, flattened).
    pub builds: Vec<EmbreeBuild>,
    /// Each variant × ray set.
    pub runs: Vec<EmbreeRun>,
    /// Time per ray, Embree's instanced ÷ its flattened, by ray set (`gpu` null).
    pub ratios: Vec<Ratio>,
}

/// One of Embree's builds (a JSON `embree.builds` entry).
#[derive(Clone, Debug, Serialize)]
pub struct EmbreeBuild {
    /// instanced (Embree's instances) or flattened (one scene over the flattened copy).
    pub variant: &'static str,
    /// Wall-clock time of Embree's commits, which build its scenes (all threads; filling its
    /// buffers and placing the instances before them is not timed).
    pub build_ms: f64,
}

/// One of Embree's variants × ray set (a JSON `embree.runs` entry).
#[derive(Clone, Debug, Serialize)]
pub struct EmbreeRun {
    /// instanced or flattened.
    pub variant: &'static str,
    /// primary (`rtcIntersect1`) or shadow (`rtcOccluded1`).
    pub rays: &'static str,
    /// Rays in the set.
    pub count: usize,
    /// One ray per call on the CPU twin's threads, median of `repeat` runs.
    pub cpu_mrays_per_s: f64,
}

/// One top-level build (a JSON `top_level` entry).
#[derive(Clone, Debug, Serialize)]
pub struct TopLevelBuild {
    /// Instances (of one triangle each).
    pub instances: usize,
    /// Median wall-clock time of `repeat` builds of the two-level structure, ms.
    pub build_ms: f64,
}

/// `bench instances`' results (`--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The mesh file.
    pub mesh: String,
    /// Triangles of the mesh.
    pub mesh_triangles: usize,
    /// Copies placed.
    pub copies: usize,
    /// The layout of every BVH.
    pub layout: &'static str,
    /// Width of the primary rays' image.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// The GPU adapter, or "none (CPU only)".
    pub adapter: String,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed runs per measurement.
    pub repeat: u64,
    /// instanced and flattened.
    pub variants: Vec<Size>,
    /// Each variant × ray set.
    pub runs: Vec<Run>,
    /// Time per ray, instanced ÷ flattened, by ray set.
    pub ratios: Vec<Ratio>,
    /// The two-level build at [`TOP_LEVEL_COUNTS`] instances.
    pub top_level: Vec<TopLevelBuild>,
    /// Embree 3's rows; null without the `embree` feature.
    pub embree: Option<EmbreeRows>,
    /// The GPU's driver (None without a GPU).
    #[serde(skip)]
    pub gpu_driver: Option<String>,
}

/// `n` copies of a mesh with bounds `extent` (its largest side) on a square grid in x and
/// z, 1.25 sides apart, copy i turned by 0.7·i radians about y.
fn placements(n: usize, extent: f32) -> Vec<Instance> {
    let side = (n as f64).sqrt().ceil().max(1.0) as usize;
    let step = 1.25 * extent.max(f32::MIN_POSITIVE);
    (0..n)
        .map(|i| {
            let at = glam::Vec3::new((i % side) as f32 * step, 0.0, (i / side) as f32 * step);
            let m = glam::Mat4::from_rotation_translation(
                glam::Quat::from_rotation_y(0.7 * i as f32),
                at,
            );
            Instance {
                mesh: 0,
                to_world: Affine::from_mat4(&m),
            }
        })
        .collect()
}

/// The variants' names, in the order of every array of two.
const VARIANTS: [&str; 2] = ["instanced", "flattened"];

/// Embree's two variants (the `embree` feature), the bench's reference.
#[cfg_attr(not(feature = "embree"), allow(dead_code))]
struct Reference {
    /// Its version ("3.13.5").
    version: String,
    /// Build ms of each variant.
    build_ms: [f64; 2],
    /// One timed run of each variant.
    time: [TimeRun; 2],
}

/// Embree's instances over `set` and its scene over the flattened copy `flat`, built on
/// rayon's thread count after an untimed build over `set`'s first mesh (which starts
/// Embree's threads, as lancer's are running already when its builds are timed):
/// `rtcIntersect1` for closest hits, `rtcOccluded1` for any hit, one ray per call on
/// rayon's threads, each run timed on the wall clock.
#[cfg(feature = "embree")]
fn reference(set: &InstanceSet, flat: &Mesh) -> Result<Option<Reference>> {
    use crate::embree::{EmbreeInstances, EmbreeTracer};
    let threads = rayon::current_num_threads();
    if let Some(mesh) = set.meshes.first() {
        EmbreeTracer::new(mesh, threads)?;
    }
    let instanced = EmbreeInstances::new(set, threads)?;
    let flattened = EmbreeTracer::new(flat, threads)?;
    let build_ms = [instanced.build_ms(), flattened.build_ms()];
    let version = instanced.version().to_string();
    let time_instanced = move |rays: &[Ray], query: Query| {
        let start = Instant::now();
        match query {
            Query::Closest => drop(instanced.closest(rays)),
            Query::Any => drop(instanced.occluded(rays)),
        }
        start.elapsed().as_secs_f64()
    };
    let time_flattened = move |rays: &[Ray], query: Query| {
        let start = Instant::now();
        match query {
            Query::Closest => drop(flattened.closest(rays)),
            Query::Any => drop(flattened.occluded(rays)),
        }
        start.elapsed().as_secs_f64()
    };
    Ok(Some(Reference {
        version,
        build_ms,
        time: [Box::new(time_instanced), Box::new(time_flattened)],
    }))
}

/// Without the `embree` feature: no reference.
#[cfg(not(feature = "embree"))]
fn reference(_: &InstanceSet, _: &Mesh) -> Result<Option<Reference>> {
    Ok(None)
}

/// Median seconds of `repeat` runs of `f`.
fn timed(repeat: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        let t0 = Instant::now();
        f()?;
        times.push(t0.elapsed().as_secs_f64());
    }
    Ok(median(times))
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    let (width, height) = (config.width, config.height);
    crate::limits::check_image(width, height, 200, "use a smaller --width/--height")?;
    let repeat = config.repeat.max(1);
    let mesh = Arc::new(config.mesh.clone());
    let extent = mesh.bounds().extent().max_element();
    let set = InstanceSet::new(vec![mesh.clone()], placements(config.copies, extent))?;
    crate::limits::check_memory(
        &format!("the flattened copy ({} triangles)", set.triangle_count()),
        set.triangle_count() as u128 * 200,
        "place fewer --copies",
    )?;
    let device = super::open_device(config.device)?;
    let gpu = !device.is_cpu();
    let layout = (config.layout).unwrap_or_else(|| crate::trace::default_layout(&device));
    let sets = 2;
    let total = 2 + 2 * sets * repeat * (1 + gpu as usize) + TOP_LEVEL_COUNTS.len() * repeat;
    let ticker = Ticker::new(progress, total as u64);

    // Every build timed here, lancer's and Embree's, starts on fresh memory (as a command
    // run once does): each would otherwise reuse, or not, the pages the one before freed.
    ticker.say("building the flattened copy");
    let flat_mesh = set.flatten()?;
    let (flat, flat_ms) = fresh_memory(|| -> Result<_> {
        let t0 = Instant::now();
        let flat: Arc<dyn GpuForm> =
            try_flatten(layout, &build(&flat_mesh, &config.build), &flat_mesh)?.into();
        Ok((flat, t0.elapsed().as_secs_f64() * 1e3))
    })?;
    ticker.inc(1);
    ticker.say("building the two levels");
    let (two, two_ms) = fresh_memory(|| -> Result<_> {
        let t0 = Instant::now();
        let two: Arc<dyn GpuForm> = Arc::new(GpuTwoLevel::build(layout, &set, &config.build)?);
        Ok((two, t0.elapsed().as_secs_f64() * 1e3))
    })?;
    ticker.inc(1);
    ticker.say("building Embree's instances and flattened copy");
    let reference = fresh_memory(|| reference(&set, &flat_mesh))?;
    if reference.is_some() {
        ticker.grow((2 * sets * repeat) as u64);
    }

    let camera = Camera::default_view(&flat_mesh.bounds(), width, height);
    let (primary, shadow) = primary_and_shadow(&flat_mesh, flat.as_ref(), &camera);
    let ray_sets: [(&'static str, Query, &[Ray]); 2] = [
        ("primary", Query::Closest, &primary),
        ("shadow", Query::Any, &shadow),
    ];
    let options = TracerOptions {
        memory: config.bvh_memory,
        ..TracerOptions::default()
    };
    let rob = Robustness::default();
    let forms = [&two, &flat];
    let mut tracers = Vec::new();
    for form in forms {
        if gpu {
            tracers.push(Tracer::with_layout(&device, form.clone(), &options)?);
        }
    }
    let (mut runs, mut ratios) = (Vec::new(), Vec::new());
    let (mut embree_runs, mut embree_ratios) = (Vec::new(), Vec::new());
    for (name, query, rays) in ray_sets {
        ticker.say(format!("{name} rays"));
        // Work per ray, untimed.
        let work = forms.map(|f| RayStats::means(&f.trace_batch(rays, query, &rob).1));
        // Each timed run right after an untimed one of the same variant, the two variants
        // in turns: a slow or fast minute of the machine moves both sides of a pair.
        // Embree's variants take their turns after lancer's, in the same way.
        let mut cpu_times = [Vec::new(), Vec::new()];
        let mut embree_times = [Vec::new(), Vec::new()];
        for _ in 0..repeat {
            for (k, form) in forms.iter().enumerate() {
                form.trace_hits(rays, query, &rob);
                let t0 = Instant::now();
                form.trace_hits(rays, query, &rob);
                cpu_times[k].push(t0.elapsed().as_secs_f64());
                ticker.inc(1);
            }
            for (k, time) in reference.iter().flat_map(|r| &r.time).enumerate() {
                time(rays, query);
                embree_times[k].push(time(rays, query));
                ticker.inc(1);
            }
        }
        let mut gpu_times = [Vec::new(), Vec::new()];
        if gpu {
            for _ in 0..repeat {
                for (k, t) in tracers.iter_mut().enumerate() {
                    t.trace(rays, query)?; // compiles the kernel on the first
                    gpu_times[k].push(super::timing::seconds(t, rays, query)?);
                    ticker.inc(1);
                }
            }
        }
        let pair_ratio = |times: &[Vec<f64>; 2]| {
            (!times[0].is_empty())
                .then(|| median(times[0].iter().zip(&times[1]).map(|(a, b)| a / b).collect()))
        };
        ratios.push(Ratio {
            rays: name,
            cpu: pair_ratio(&cpu_times).unwrap_or(f64::NAN),
            gpu: pair_ratio(&gpu_times),
        });
        let n = rays.len() as f64;
        if let Some(cpu) = pair_ratio(&embree_times) {
            embree_ratios.push(Ratio {
                rays: name,
                cpu,
                gpu: None,
            });
            for (k, variant) in VARIANTS.into_iter().enumerate() {
                embree_runs.push(EmbreeRun {
                    variant,
                    rays: name,
                    count: rays.len(),
                    cpu_mrays_per_s: n / median(embree_times[k].clone()) / 1e6,
                });
            }
        }
        for (k, variant) in VARIANTS.into_iter().enumerate() {
            runs.push(Run {
                variant,
                rays: name,
                count: rays.len(),
                nodes_per_ray: work[k].0,
                triangles_per_ray: work[k].1,
                cpu_mrays_per_s: n / median(cpu_times[k].clone()) / 1e6,
                gpu_mrays_per_s: gpu.then(|| n / median(gpu_times[k].clone()) / 1e6),
            });
        }
    }

    let one = Arc::new(Mesh::from_triangles(vec![Triangle::new(
        glam::Vec3::ZERO,
        glam::Vec3::X,
        glam::Vec3::Y,
    )]));
    let mut top_level = Vec::new();
    for n in TOP_LEVEL_COUNTS {
        ticker.say(format!("the two levels over {n} instances"));
        let many = InstanceSet::new(vec![one.clone()], placements(n, 1.0))?;
        let s = fresh_memory(|| {
            timed(repeat, || {
                GpuTwoLevel::build(layout, &many, &config.build)?;
                ticker.inc(1);
                Ok(())
            })
        })?;
        top_level.push(TopLevelBuild {
            instances: n,
            build_ms: s * 1e3,
        });
    }
    let variants = vec![
        Size {
            variant: "instanced",
            build_ms: two_ms,
            bytes: two.bytes() as u64,
            triangles: two.triangles() as u64,
        },
        Size {
            variant: "flattened",
            build_ms: flat_ms,
            bytes: flat.bytes() as u64,
            triangles: flat.triangles() as u64,
        },
    ];
    Ok(Report {
        mesh: config.name.clone(),
        mesh_triangles: config.mesh.len(),
        copies: config.copies,
        layout: layout.name(),
        width,
        height,
        adapter: super::adapter_of(&device).unwrap_or_else(|| "none (CPU only)".into()),
        cpu_threads: super::cpu_threads(),
        repeat: repeat as u64,
        variants,
        runs,
        ratios,
        top_level,
        embree: reference.map(|r| EmbreeRows {
            version: r.version,
            builds: (VARIANTS.iter().zip(r.build_ms))
                .map(|(&variant, build_ms)| EmbreeBuild { variant, build_ms })
                .collect(),
            runs: embree_runs,
            ratios: embree_ratios,
        }),
        gpu_driver: device.gpu_context().map(|c| c.adapter.driver.clone()),
    })
}

impl Report {
    /// Instanced ÷ flattened time per ray of one ray set on one device (>1: instanced is
    /// slower), or None where it was not measured.
    pub fn cost_ratio(&self, rays: &str, gpu: bool) -> Option<f64> {
        let r = self.ratios.iter().find(|r| r.rays == rays)?;
        match gpu {
            true => r.gpu,
            false => Some(r.cpu),
        }
    }

    /// Embree's instanced ÷ flattened time per ray of one ray set (>1: its instances are
    /// slower), or None without the `embree` feature.
    pub fn embree_cost_ratio(&self, rays: &str) -> Option<f64> {
        let e = self.embree.as_ref()?;
        Some(e.ratios.iter().find(|r| r.rays == rays)?.cpu)
    }
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!(
            "bench instances: {} × {}",
            self.copies,
            super::file_name(&self.mesh)
        )
    }

    fn adapter(&self) -> Option<String> {
        self.gpu_driver.as_ref().map(|_| self.adapter.clone())
    }

    fn text(&self) -> String {
        let mut out = format!(
            "mesh {}  {} triangles × {} copies  layout {}  {}x{} primary rays  {} CPU threads\n",
            self.mesh,
            self.mesh_triangles,
            self.copies,
            self.layout,
            self.width,
            self.height,
            self.cpu_threads
        );
        out += &format!("adapter {}\n\n", self.adapter);
        let mut sizes = Table::new(&["variant", "build ms", "bytes", "triangles stored"]);
        for s in &self.variants {
            sizes.row(vec![
                s.variant.to_string(),
                format!("{:.1}", s.build_ms),
                s.bytes.to_string(),
                s.triangles.to_string(),
            ]);
        }
        for b in self.embree.iter().flat_map(|e| &e.builds) {
            sizes.row(vec![
                format!("embree {}", b.variant),
                format!("{:.1}", b.build_ms),
                "–".into(),
                "–".into(),
            ]);
        }
        out += &sizes.text();
        out += &format!(
            "\nbuild ms: one build of each variant (tree and layout; Embree's scene commits), \
             on fresh memory: {FRESH_MEMORY_NOTE}\n\n"
        );
        let mut runs = Table::new(&[
            "variant",
            "rays",
            "count",
            "nodes/ray",
            "triangles/ray",
            "CPU Mrays/s",
            "GPU Mrays/s",
        ]);
        for r in &self.runs {
            runs.row(vec![
                r.variant.to_string(),
                r.rays.to_string(),
                r.count.to_string(),
                format!("{:.1}", r.nodes_per_ray),
                format!("{:.1}", r.triangles_per_ray),
                format!("{:.2}", r.cpu_mrays_per_s),
                super::markdown::dash(r.gpu_mrays_per_s, 2),
            ]);
        }
        for r in self.embree.iter().flat_map(|e| &e.runs) {
            runs.row(vec![
                format!("embree {}", r.variant),
                r.rays.to_string(),
                r.count.to_string(),
                "–".into(),
                "–".into(),
                format!("{:.2}", r.cpu_mrays_per_s),
                "–".into(),
            ]);
        }
        out += &runs.text();
        out += "\n";
        let mut head = vec![
            "rays",
            "CPU instanced ÷ flattened",
            "GPU instanced ÷ flattened",
        ];
        if self.embree.is_some() {
            head.push("Embree instanced ÷ flattened");
        }
        let mut ratios = Table::new(&head);
        for rays in ["primary", "shadow"] {
            let mut cells = vec![
                rays.to_string(),
                super::markdown::dash(self.cost_ratio(rays, false), 2),
                super::markdown::dash(self.cost_ratio(rays, true), 2),
            ];
            if self.embree.is_some() {
                cells.push(super::markdown::dash(self.embree_cost_ratio(rays), 2));
            }
            ratios.row(cells);
        }
        out += "Time per ray, instanced ÷ flattened (median of the timed pairs):\n\n";
        out += &ratios.text();
        out += "\n";
        let mut top = Table::new(&["instances (one triangle each)", "two-level build ms"]);
        for t in &self.top_level {
            top.row(vec![t.instances.to_string(), format!("{:.2}", t.build_ms)]);
        }
        out += &top.text();
        if let Some(e) = &self.embree {
            out += &format!(
                "\nembree rows: Embree {}, build quality medium (Embree's default), on {} \
                 threads after an untimed build that starts them: instanced is its own \
                 instances (one scene over the mesh, one instance geometry per copy in a \
                 top-level scene), flattened one scene over the flattened copy's triangles. \
                 One ray per call (rtcIntersect1 for primary, rtcOccluded1 for shadow rays) \
                 on the CPU twin's threads, each run right after an untimed one and in turns \
                 with lancer's variants; it reports no work counts or bytes.\n",
                e.version, self.cpu_threads
            );
        }
        out
    }

    /// Mrays/s, one group per ray set and device, one bar per variant (Embree's rows: CPU
    /// bars only).
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let gpu = self.gpu_driver.is_some();
        let mut series: Vec<(String, Vec<f64>)> = VARIANTS
            .iter()
            .map(|v| {
                let mut values = Vec::new();
                for r in self.runs.iter().filter(|r| r.variant == *v) {
                    values.push(r.cpu_mrays_per_s);
                    if gpu {
                        values.push(r.gpu_mrays_per_s.unwrap_or(f64::NAN));
                    }
                }
                (v.to_string(), values)
            })
            .collect();
        // Embree's bars: CPU only.
        if let Some(e) = &self.embree {
            for v in VARIANTS {
                let mut values = Vec::new();
                for r in e.runs.iter().filter(|r| r.variant == v) {
                    values.push(r.cpu_mrays_per_s);
                    if gpu {
                        values.push(f64::NAN);
                    }
                }
                series.push((format!("embree {v}"), values));
            }
        }
        let title = format!(
            "{} × {}, {}: GPU {}",
            self.copies,
            super::file_name(&self.mesh),
            self.layout,
            self.gpu_driver.as_deref().unwrap_or("none")
        );
        let categories = super::chart::device_categories(&["primary", "shadow"], gpu);
        for path in paths {
            super::chart::bar_chart(path, &title, "Mrays/s", &categories, &series)?;
        }
        Ok(paths.to_vec())
    }
}
