//! `lancer bench accuracy`: what each robustness knob costs in time and what error it
//! leaves, on the CPU and the GPU in one run. Trace knobs are timed on the scene's primary
//! and shadow rays and judged on the hard cases of `lancer::accuracy` (leaks on a closed
//! icosphere, false misses on the constructed cases, self-hits of secondary rays); BVH
//! builders by SAH cost and work per ray; samples per pixel and bounces by RMSE and bias
//! against a high-spp, deep reference render. Prints a markdown table, writes JSON and PNG
//! charts.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::Args;
use indicatif::ProgressStyle;
use lancer::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions, Builder, BvhStats};
use lancer::accel::GpuForm;
use lancer::accuracy::{cases, closed, false_misses, secondary};
use lancer::geometry::{Precision, RayOffset, SlabTest, TriangleTest};
use lancer::mesh::Mesh;
use lancer::render::Rng;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{
    Device, DeviceChoice, Error, Query, Ray, RayStats, RenderOptions, RenderScene, Renderer,
    Result, Robustness, Tracer, TracerOptions, Vec3,
};
use serde::Serialize;

use super::open_bench_device;
use super::out::{json_to, say, JsonTo, Say};
use super::render::load_scene;
use lancer::bench::chart::xy_chart;
use lancer::bench::timing::median;

#[derive(Args)]
pub struct BenchAccuracy {
    /// Scene: a .toml scene file or a mesh (.obj, .ply, .gltf, .glb; traced from the scene's
    /// camera, and rendered for the spp and bounce rows); the built-in Cornell box (the one
    /// in scenes/cornell.toml) when none is given.
    scene: Option<PathBuf>,
    /// Width of the timed primary rays' image.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=4096))]
    width: u32,
    /// Height of the timed primary rays' image.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=4096))]
    height: u32,
    /// Side of the rendered image for the spp and bounce rows (square).
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(4..=512))]
    render_size: u32,
    /// Samples per pixel of the reference render (on the CPU).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..))]
    reference_spp: u32,
    /// The spp rows: 1, 4, 16, … up to this.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    max_spp: u32,
    /// Bounces of the reference render.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=64))]
    reference_bounces: u32,
    /// Timed runs per setting (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    /// auto, gpu or cpu. auto and gpu measure the GPU and the CPU side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    /// Error-vs-time charts: NAME-cpu.png and NAME-gpu.png, and the spp convergence curve
    /// NAME-spp.png, from this path's stem.
    #[arg(long, value_name = "NAME.png", default_value = "bench-accuracy.png")]
    chart: PathBuf,
    /// The results as one JSON object: on stdout with --json alone or --json - (the table
    /// then goes to stderr), or in FILE.json (default: the --chart path with .json; keys:
    /// the book's JSON page, docs/src/reference/json.md).
    #[arg(long, value_name = "FILE.json", num_args = 0..=1, default_missing_value = "-", value_parser = json_to)]
    json: Option<JsonTo>,
}

/// Rays aimed at the closed icosphere's vertices and edges (leaks).
const LEAK_RAYS: usize = 100_000;
/// Rays per constructed hard case (false misses).
const CASE_RAYS: usize = 2_000;
/// Surface points the secondary rays leave from (self-hits).
const SECONDARY_POINTS: usize = 2_000;
/// Samples per pixel of the bounce rows.
const BOUNCE_SPP: u32 = 16;
/// The robust defaults' row, the baseline of the trace rows.
const DEFAULTS: &str = "robust (all defaults)";
/// Every fast setting at once.
const FASTEST: &str = "MT + plain + no offset + trusted";
/// The three accuracy knobs at their fast settings, the shader checks left at the default:
/// what the robust defaults (watertight, robust slab, error-bound offset) are priced against.
const FAST_ACCURACY: &str = "MT + plain + no offset";

/// One setting of the trace knobs: robustness and builder.
struct Setting {
    knob: &'static str,
    name: String,
    rob: Robustness,
    build: BuildOptions,
    cpu: bool,
    gpu: bool,
    /// Judge leaks, false misses and self-hits (the builders are judged by SAH cost).
    errors: bool,
}

fn settings() -> Vec<Setting> {
    let d = Robustness::default();
    // The three accuracy knobs at their fast settings.
    let fast = Robustness {
        triangle_test: TriangleTest::MollerTrumbore,
        slab_test: SlabTest::Plain,
        ray_offset: RayOffset::None,
        ..d
    };
    let rob = |knob, name: &str, rob: Robustness, cpu, gpu| Setting {
        knob,
        name: name.into(),
        rob,
        build: BuildOptions::default(),
        cpu,
        gpu,
        errors: true,
    };
    let builder = |name: String, builder, bins| Setting {
        knob: "BVH builder",
        name,
        rob: d,
        build: BuildOptions {
            builder,
            bins,
            ..BuildOptions::default()
        },
        cpu: true,
        gpu: true,
        errors: false,
    };
    let mut s = vec![
        rob("defaults", DEFAULTS, d, true, true),
        rob(
            "triangle test",
            "Möller–Trumbore",
            Robustness {
                triangle_test: TriangleTest::MollerTrumbore,
                ..d
            },
            true,
            true,
        ),
        rob(
            "slab test",
            "plain",
            Robustness {
                slab_test: SlabTest::Plain,
                ..d
            },
            true,
            true,
        ),
        rob(
            "ray offset",
            "fixed epsilon",
            Robustness {
                ray_offset: RayOffset::Fixed,
                ..d
            },
            true,
            true,
        ),
        rob(
            "ray offset",
            "none",
            Robustness {
                ray_offset: RayOffset::None,
                ..d
            },
            true,
            true,
        ),
        rob(
            "shader checks",
            "trusted",
            Robustness {
                checked_module: false,
                ..d
            },
            false,
            true,
        ),
        rob(
            "CPU precision",
            "f64",
            Robustness {
                precision: Precision::F64,
                ..d
            },
            true,
            false,
        ),
        rob("fastest", FAST_ACCURACY, fast, true, true),
        rob(
            "fastest",
            FASTEST,
            Robustness {
                checked_module: false,
                ..fast
            },
            true,
            true,
        ),
    ];
    for bins in [8, 16, 32] {
        s.push(builder(format!("binned {bins}"), Builder::Binned, bins));
    }
    s.push(builder("median".into(), Builder::Median, 16));
    s
}

/// One row of the table (a JSON `rows` entry); null where a row does not measure it.
#[derive(Default, Serialize)]
struct Row {
    /// What is varied: defaults, triangle test, slab test, ray offset, shader checks, CPU
    /// precision, fastest, BVH builder, spp or max bounces.
    knob: String,
    /// The setting of the knob.
    setting: String,
    /// "cpu" or "gpu".
    device: &'static str,
    /// Median ms of the scene's primary and shadow rays (trace rows) or of the render.
    ms: f64,
    /// Million rays (render rows: camera samples) per second.
    #[serde(rename = "mrays_per_s")]
    mrays: f64,
    /// ms relative to the defaults on the same device.
    #[serde(rename = "relative_to_default")]
    relative: Option<f64>,
    /// Rays that leak through the closed icosphere.
    leaks: Option<usize>,
    /// Rays of the constructed hard cases that miss a triangle they hit.
    false_misses: Option<usize>,
    /// Secondary rays that hit the surface they leave, in %.
    self_hits_pct: Option<f64>,
    /// Leaks, false misses and self-hits in % of the rays they are counted on.
    error_pct: Option<f64>,
    /// SAH cost of the BVH.
    #[serde(rename = "sah_cost")]
    sah: Option<f64>,
    /// Mean nodes visited per primary ray.
    #[serde(rename = "nodes_per_ray")]
    nodes: Option<f64>,
    /// Mean triangles tested per primary ray.
    #[serde(rename = "tris_per_ray")]
    tris: Option<f64>,
    /// RMSE against the reference render (linear radiance).
    rmse: Option<f64>,
    /// Bias of the mean against the reference's, in % of it.
    bias_pct: Option<f64>,
    /// Samples per pixel of the render rows.
    spp: Option<u32>,
}

/// The whole run (the JSON).
#[derive(Serialize)]
struct Report<'a> {
    /// The scene file.
    scene: String,
    /// The GPU adapter, or null.
    adapter: Option<String>,
    /// CPU threads.
    cpu_threads: usize,
    /// One object per knob setting and device.
    rows: &'a [Row],
}

/// What the trace settings are measured on.
struct Work {
    mesh: Mesh,
    primary: Vec<Ray>,
    shadow: Vec<Ray>,
    sphere: Mesh,
    aimed: Vec<Ray>,
    cases: Vec<cases::HardCase>,
}

impl Work {
    fn new(scene: &RenderScene, width: u32, height: u32) -> Result<Work> {
        let mesh = scene.mesh.clone();
        if mesh.included().is_empty() {
            return Err(Error::Usage("the scene has no triangle to trace".into()));
        }
        let mut camera = scene.camera;
        (camera.width, camera.height) = (width, height);
        let primary = camera.primary_rays();
        let layout = flatten(
            LayoutKind::DfsSign,
            &build(&mesh, &BuildOptions::default()),
            &mesh,
        );
        let (hits, _) = layout.trace_batch(&primary, Query::Closest, &Robustness::default());
        let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
        let shape = closed::icosphere(5);
        let (sphere, v) = closed::placed(&shape, 1.0, Vec3::ZERO);
        let mut rng = Rng::new(12, 0, 0);
        let aimed = closed::aimed_rays(&v, &shape.1, Vec3::ZERO, 1.0, LEAK_RAYS, &mut rng);
        Ok(Work {
            mesh,
            primary,
            shadow,
            sphere,
            aimed,
            cases: cases::all(CASE_RAYS, 7),
        })
    }

    fn case_rays(&self) -> usize {
        self.cases.iter().map(|c| c.rays.len()).sum()
    }
}

/// Milliseconds of one trace: GPU time where the device measures it, else wall time.
fn trace_ms(tracer: &mut Tracer, rays: &[Ray], query: Query) -> Result<f64> {
    let t = tracer.trace(rays, query)?.timings;
    Ok(t.gpu_ms.unwrap_or(t.wall_ms))
}

/// Tracers of one builder on one device: the scene's BVH, and (for the judged settings)
/// the icosphere's and every hard case's.
struct Tracers<'d> {
    scene: Tracer<'d>,
    sah: f64,
    judged: Vec<Tracer<'d>>,
}

impl<'d> Tracers<'d> {
    fn new(
        device: &'d Device,
        work: &Work,
        build_opts: &BuildOptions,
        judged: bool,
    ) -> Result<Self> {
        let opts = TracerOptions {
            build: *build_opts,
            ..TracerOptions::default()
        };
        let tree = build(&work.mesh, build_opts);
        let sah = BvhStats::of(&tree, build_opts).sah_cost;
        let layout: Arc<dyn GpuForm> = try_flatten(
            (opts.layout).unwrap_or_else(|| lancer::trace::default_layout(device)),
            &tree,
            &work.mesh,
        )?
        .into();
        let scene = Tracer::with_layout(device, layout, &opts)?;
        let mut tracers = Vec::new();
        if judged {
            tracers.push(Tracer::new(device, &work.sphere, &opts)?);
            for c in &work.cases {
                tracers.push(Tracer::new(device, &c.mesh, &opts)?);
            }
        }
        Ok(Tracers {
            scene,
            sah,
            judged: tracers,
        })
    }
}

/// Compiles (GPU) and warms up one setting's kernels, outside the timing.
fn warm_up(t: &mut Tracers, s: &Setting, work: &Work) -> Result<()> {
    t.scene.set_kernel(s.rob, 64, false);
    t.scene.trace(
        &work.primary[..work.primary.len().min(1024)],
        Query::Closest,
    )?;
    t.scene
        .trace(&work.shadow[..work.shadow.len().min(1024)], Query::Any)?;
    Ok(())
}

/// Milliseconds of one setting's primary and shadow rays.
fn time_once(t: &mut Tracers, s: &Setting, work: &Work) -> Result<f64> {
    t.scene.set_kernel(s.rob, 64, false);
    Ok(trace_ms(&mut t.scene, &work.primary, Query::Closest)?
        + trace_ms(&mut t.scene, &work.shadow, Query::Any)?)
}

/// The work per ray and (for judged settings) the errors one setting leaves on one device.
fn judge(t: &mut Tracers, s: &Setting, device: &'static str, work: &Work, ms: f64) -> Result<Row> {
    t.scene.set_kernel(s.rob, 64, true);
    let stats = t.scene.trace(&work.primary, Query::Closest)?.stats;
    let (nodes, tris) = RayStats::means(&stats.unwrap_or_default());
    let n = (work.primary.len() + work.shadow.len()) as f64;
    let mut row = Row {
        knob: s.knob.into(),
        setting: s.name.clone(),
        device,
        ms,
        mrays: n / ms * 1e-3,
        sah: Some(t.sah),
        nodes: Some(nodes),
        tris: Some(tris),
        ..Row::default()
    };
    if s.errors {
        let mut judged = t.judged.iter_mut();
        if let Some(sphere) = judged.next() {
            sphere.set_kernel(s.rob, 64, false);
            row.leaks = Some(closed::leaks(
                &sphere.trace(&work.aimed, Query::Closest)?.hits,
            ));
        }
        let mut lost = 0;
        for (tracer, case) in judged.zip(&work.cases) {
            tracer.set_kernel(s.rob, 64, false);
            let hits = tracer.trace(&case.rays, Query::Closest)?.hits;
            lost += false_misses(&case.mesh, &case.rays, &hits, &s.rob);
        }
        row.false_misses = Some(lost);
        let (rays, own) =
            secondary::secondary_rays(&work.mesh, SECONDARY_POINTS, s.rob.ray_offset, 3);
        t.scene.set_kernel(s.rob, 64, false);
        let hits = t.scene.trace(&rays, Query::Closest)?.hits;
        let selfs = secondary::self_hits(&hits, &own);
        let judged = work.aimed.len() + work.case_rays() + rays.len();
        let errors = row.leaks.unwrap_or(0) + lost + selfs;
        row.self_hits_pct = Some(100.0 * selfs as f64 / rays.len().max(1) as f64);
        row.error_pct = Some(100.0 * errors as f64 / judged as f64);
    }
    Ok(row)
}

/// Mean over pixels and channels.
fn mean(px: &[Vec3]) -> f64 {
    px.iter().map(|c| (c.x + c.y + c.z) as f64).sum::<f64>() / (3 * px.len().max(1)) as f64
}

/// RMSE over pixels and channels, and the bias of the mean in % of the reference's mean.
fn error_against(px: &[Vec3], reference: &[Vec3]) -> (f64, f64) {
    let se: f64 = px
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            let d = *a - *b;
            (d.x * d.x + d.y * d.y + d.z * d.z) as f64
        })
        .sum();
    let rmse = (se / (3 * px.len().max(1)) as f64).sqrt();
    let m = mean(reference);
    let bias = if m > 0.0 {
        100.0 * (mean(px) - m) / m
    } else {
        0.0
    };
    (rmse, bias)
}

/// One render of `scene` with `spp` samples and seed `seed`: (pixels, milliseconds).
fn render(scene: &RenderScene, device: &Device, spp: u32, seed: u32) -> Result<(Vec<Vec3>, f64)> {
    let options = RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        ..RenderOptions::default()
    };
    let r = Renderer::new(scene, device, &options)?.render(&options)?;
    Ok((r.image.pixels, r.seconds * 1e3))
}

impl BenchAccuracy {
    /// The scene as reports name it.
    fn scene_name(&self) -> String {
        self.scene
            .as_ref()
            .map_or(lancer::render::builtin::CORNELL_NAME.to_string(), |p| {
                p.display().to_string()
            })
    }

    pub fn run(self) -> Result<()> {
        let json =
            (self.json.clone()).unwrap_or_else(|| JsonTo::File(self.chart.with_extension("json")));
        let say = Say::new(json.is_stdout());
        let charts = ["cpu", "gpu", "spp"].map(|k| chart_path(&self.chart, k));
        let mut inputs: Vec<PathBuf> = self.scene.iter().cloned().collect();
        let scene = match &self.scene {
            Some(path) => load_scene(path, None, None)?,
            None => lancer::render::builtin::cornell_box()?,
        };
        inputs.extend(scene.mesh.sources.iter().cloned());
        for out in &charts {
            lancer::output::check_output(out, &inputs)?;
        }
        json.check(&inputs)?;
        let device = open_bench_device(self.device)?;
        let cpu = Device::cpu();
        let mut devices: Vec<(&'static str, &Device)> = vec![("cpu", &cpu)];
        if !device.is_cpu() {
            devices.push(("gpu", &device));
        }
        let work = Work::new(&scene, self.width, self.height)?;
        let settings = settings();
        let spps: Vec<u32> = std::iter::successors(Some(1u32), |s| s.checked_mul(4))
            .take_while(|&s| s <= self.max_spp)
            .collect();
        let bounces: Vec<u32> = [1, 2, 4, 8, 16].into();
        let jobs = devices.len() * (settings.len() + spps.len() + bounces.len()) + 1;
        let bar = super::out::progress_bar(jobs as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} settings {msg}")
                .map_err(|e| Error::Usage(e.to_string()))?,
        );
        let repeat = self.repeat as usize;
        let mut rows = Vec::new();
        for &(dev_name, dev) in &devices {
            let runs = |s: &&Setting| if dev.is_cpu() { s.cpu } else { s.gpu };
            let mut groups: Vec<(Tracers, Vec<&Setting>)> = Vec::new();
            for s in settings.iter().filter(runs) {
                match groups.iter_mut().find(|g| g.1[0].build == s.build) {
                    Some(g) => g.1.push(s),
                    None => {
                        let judged = settings.iter().any(|o| o.build == s.build && o.errors);
                        groups.push((Tracers::new(dev, &work, &s.build, judged)?, vec![s]));
                    }
                }
            }
            // Rounds over every setting in turn, so that a change in the machine's load
            // (other work on the same cores) falls on all settings alike.
            let mut ms: Vec<Vec<Vec<f64>>> =
                groups.iter().map(|g| vec![Vec::new(); g.1.len()]).collect();
            for round in 0..=repeat {
                bar.set_message(format!("{dev_name}: timing, round {round} of {repeat}"));
                for (gi, (tracers, group)) in groups.iter_mut().enumerate() {
                    for (si, s) in group.iter().enumerate() {
                        if round == 0 {
                            warm_up(tracers, s, &work)?;
                        } else {
                            ms[gi][si].push(time_once(tracers, s, &work)?);
                        }
                    }
                }
            }
            for (gi, (tracers, group)) in groups.iter_mut().enumerate() {
                for (si, s) in group.iter().enumerate() {
                    bar.set_message(format!("{dev_name}: judging {} {}", s.knob, s.name));
                    let t = median(std::mem::take(&mut ms[gi][si]));
                    rows.push(judge(tracers, s, dev_name, &work, t)?);
                    bar.inc(1);
                }
            }
            bar.inc((settings.len() - settings.iter().filter(runs).count()) as u64);
        }
        // Renders: a reference on the CPU (the reference renderer), then spp and bounces on
        // each device.
        let mut small = scene.clone();
        (small.camera.width, small.camera.height) = (self.render_size, self.render_size);
        let mut deep = small.clone();
        deep.settings.max_bounces = self.reference_bounces;
        bar.set_message("reference render");
        let seed = scene.settings.seed;
        let (reference, ref_ms) = render(&deep, &cpu, self.reference_spp, seed ^ 0x5eed)?;
        bar.inc(1);
        let pixels = (self.render_size * self.render_size) as f64;
        for &(dev_name, dev) in &devices {
            let mut add = |knob: &str, name: String, scene: &RenderScene, spp: u32| {
                bar.set_message(format!("{dev_name}: {name}"));
                let (px, ms) = render(scene, dev, spp, seed)?;
                let (rmse, bias) = error_against(&px, &reference);
                rows.push(Row {
                    knob: knob.into(),
                    setting: name,
                    device: dev_name,
                    ms,
                    mrays: pixels * spp as f64 / ms * 1e-3,
                    rmse: Some(rmse),
                    bias_pct: Some(bias),
                    spp: Some(spp),
                    ..Row::default()
                });
                bar.inc(1);
                Ok::<(), Error>(())
            };
            for &spp in &spps {
                add("spp", format!("{spp} spp"), &small, spp)?;
            }
            for &b in &bounces {
                let mut s = small.clone();
                s.settings.max_bounces = b;
                add("max bounces", format!("{b} bounces"), &s, BOUNCE_SPP)?;
            }
        }
        bar.finish_and_clear();
        relative_to_defaults(&mut rows, &scene);

        // The report.
        let (w, h) = (self.width, self.height);
        say!(
            say,
            "scene {}  {} triangles  primary {w}x{h} + shadow rays ({} rays)  {} CPU threads",
            self.scene_name(),
            work.mesh.included().len(),
            work.primary.len() + work.shadow.len(),
            rayon::current_num_threads()
        );
        if let Some(ctx) = device.gpu_context() {
            let timing = if ctx.timestamps {
                "GPU timestamps"
            } else {
                "wall time"
            };
            say!(say, "adapter {} (GPU times: {timing})", ctx.adapter);
        }
        say!(
            say,
            "leaks: of {LEAK_RAYS} rays aimed at the vertices and edges of a closed icosphere \
             ({} triangles); false misses: of {} constructed hard-case rays; self-hits: % of \
             the secondary rays from {SECONDARY_POINTS} surface points",
            work.sphere.len(),
            work.case_rays()
        );
        say!(
            say,
            "renders: {0}x{0} px; reference {1} spp, {2} bounces on the CPU ({3:.0} ms); bounce \
             rows at {BOUNCE_SPP} spp; bias in % of the reference's mean",
            self.render_size,
            self.reference_spp,
            self.reference_bounces,
            ref_ms
        );
        say!(say, "| knob | setting | device | ms | Mrays/s | × default | leaks | false misses | self-hits % | SAH cost | nodes/ray | tris/ray | RMSE | bias % |");
        say!(
            say,
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for r in &rows {
            say!(say, "{}", table_row(r));
        }
        for &(dev_name, _) in &devices {
            let ms = |name: &str| {
                rows.iter()
                    .find(|r| r.device == dev_name && r.setting == name)
                    .map(|r| r.ms)
            };
            if let (Some(robust), Some(fast), Some(fastest)) =
                (ms(DEFAULTS), ms(FAST_ACCURACY), ms(FASTEST))
            {
                say!(
                    say,
                    "{dev_name}: the robust defaults take {robust:.2} ms; the fast accuracy \
                     settings ({FAST_ACCURACY}) {fast:.2} ms: robust costs {:+.1}%; with \
                     trusted modules too ({FASTEST}) {fastest:.2} ms: {:+.1}%",
                    100.0 * (robust / fast - 1.0),
                    100.0 * (robust / fastest - 1.0)
                );
            }
        }
        draw_charts(&charts, &rows, &devices)?;
        say!(
            say,
            "charts -> {}, {}, {}",
            charts[0].display(),
            charts[1].display(),
            charts[2].display()
        );
        let report = Report {
            scene: self.scene_name(),
            adapter: device.gpu_context().map(|c| c.adapter.to_string()),
            cpu_threads: rayon::current_num_threads(),
            rows: &rows,
        };
        json.write(&report, say)?;
        Ok(())
    }
}

/// NAME-kind.png beside the chart path.
fn chart_path(chart: &Path, kind: &str) -> PathBuf {
    let stem = chart
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bench-accuracy".into());
    chart.with_file_name(format!("{stem}-{kind}.png"))
}

/// Times relative to the defaults on the same device: the robust trace settings for the
/// trace rows, the scene's own spp (or bounces, at the bounce rows' spp) for the render rows.
fn relative_to_defaults(rows: &mut [Row], scene: &RenderScene) {
    let base_of = |knob: &str| match knob {
        "spp" => format!("{} spp", scene.settings.spp),
        "max bounces" => format!("{} bounces", scene.settings.max_bounces),
        _ => DEFAULTS.to_string(),
    };
    let ms: Vec<(&'static str, String, f64)> = (rows.iter())
        .map(|r| (r.device, r.setting.clone(), r.ms))
        .collect();
    for r in rows.iter_mut() {
        let base = base_of(&r.knob);
        r.relative = (ms.iter())
            .find(|m| m.0 == r.device && m.1 == base)
            .map(|m| r.ms / m.2);
    }
}

fn opt<T>(v: Option<T>, f: impl Fn(T) -> String) -> String {
    v.map_or("–".into(), f)
}

fn table_row(r: &Row) -> String {
    format!(
        "| {} | {} | {} | {:.2} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
        r.knob,
        r.setting,
        r.device,
        r.ms,
        r.mrays,
        opt(r.relative, |x| format!("{x:.2}")),
        opt(r.leaks, |x| x.to_string()),
        opt(r.false_misses, |x| x.to_string()),
        opt(r.self_hits_pct, |x| format!("{x:.2}")),
        opt(r.sah, |x| format!("{x:.1}")),
        opt(r.nodes, |x| format!("{x:.1}")),
        opt(r.tris, |x| format!("{x:.1}")),
        opt(r.rmse, |x| format!("{x:.4}")),
        opt(r.bias_pct, |x| format!("{x:+.2}")),
    )
}

/// Error vs time per device (one point per setting), and RMSE vs spp.
fn draw_charts(
    paths: &[PathBuf; 3],
    rows: &[Row],
    devices: &[(&'static str, &Device)],
) -> Result<()> {
    for (i, dev) in ["cpu", "gpu"].iter().enumerate() {
        if !devices.iter().any(|d| d.0 == *dev) {
            continue;
        }
        let series: Vec<(String, Vec<(f64, f64)>)> = rows
            .iter()
            .filter(|r| r.device == *dev && r.rmse.is_none())
            .filter_map(|r| {
                Some((
                    format!("{}: {}", r.knob, r.setting),
                    vec![(r.ms, r.error_pct?)],
                ))
            })
            .collect();
        xy_chart(
            &paths[i],
            &format!("error left vs trace time ({dev})"),
            "primary + shadow rays (ms)",
            "leaks + false misses + self-hits (% of judged rays)",
            false,
            false,
            &series,
            true,
        )?;
    }
    let mut curves = Vec::new();
    for &(dev, _) in devices {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.device == dev && r.knob == "spp")
            .filter_map(|r| Some((r.spp? as f64, r.rmse?)))
            .collect();
        curves.push((format!("RMSE {dev}"), pts));
    }
    // What unbiased Monte Carlo noise alone would give: RMSE(1 spp) / √spp.
    if let Some(&(_, first)) = curves.first().and_then(|c| c.1.first()) {
        let ideal = (curves[0].1.iter())
            .map(|&(spp, _)| (spp, first / spp.sqrt()))
            .collect();
        curves.push(("RMSE(1 spp) / √spp".into(), ideal));
    }
    xy_chart(
        &paths[2],
        "convergence against the reference",
        "samples per pixel",
        "RMSE (linear radiance)",
        true,
        true,
        &curves,
        false,
    )
}
