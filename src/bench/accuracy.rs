//! `lancer bench accuracy`: what each robustness knob costs in time and what error it
//! leaves, on the CPU and the GPU in one run. Trace knobs are timed on the scene's primary
//! and shadow rays and judged on the hard cases of [`crate::accuracy`] (leaks on a closed
//! icosphere, false misses on the constructed cases, self-hits of secondary rays); BVH
//! builders by SAH cost and work per ray; samples per pixel and bounces by RMSE and bias
//! against a high-spp, deep reference render. Every GPU row also counts the answers that
//! are not bit for bit the CPU twin's: what lancer's exact SPIR-V buys against wgpu's own
//! translation of the WGSL (the `GPU arithmetic` row, on adapters that take the former).

use std::sync::Arc;

use serde::Serialize;

use crate::accel::bvh::layouts::{flatten, try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions, Builder, BvhStats};
use crate::accel::{GpuForm, Query, RayStats};
use crate::accuracy::{cases, closed, false_misses, secondary};
use crate::device::{Device, DeviceChoice};
use crate::error::{Error, Result};
use crate::geometry::{Precision, Ray, RayOffset, Robustness, SlabTest, TriangleTest};
use crate::mesh::Mesh;
use crate::render::{compare_images, Image, RenderOptions, RenderScene, Renderer, Rng};
use crate::trace::compare::count_agreement;
use crate::trace::{Tracer, TracerOptions};
use crate::Vec3;

use super::markdown::{dash, Table};
use super::timing::median;
use super::{BenchReport, Progress, Ticker};

/// What `bench accuracy` measures.
#[derive(Clone)]
pub struct Config {
    /// The scene: traced from its camera, and rendered for the spp and bounce rows.
    pub scene: RenderScene,
    /// The scene's name in the report (its file).
    pub name: String,
    /// Width of the timed primary rays' image.
    pub width: u32,
    /// Height of the timed primary rays' image.
    pub height: u32,
    /// Side of the rendered image for the spp and bounce rows (square).
    pub render_size: u32,
    /// Samples per pixel of the reference render (on the CPU).
    pub reference_spp: u32,
    /// The spp rows: 1, 4, 16, … up to this.
    pub max_spp: u32,
    /// Bounces of the reference render.
    pub reference_bounces: u32,
    /// Timed runs per setting (the median is reported), at least 1.
    pub repeat: usize,
    /// Where to run beside the CPU: auto and gpu measure the GPU on any adapter (a software
    /// one included); cpu measures the CPU alone.
    pub device: DeviceChoice,
}

impl Config {
    /// The command line's defaults for `scene`: 256×256 primary rays, 32×32 renders against a
    /// 512-spp, 16-bounce reference, spp rows up to 64, 3 timed runs, any GPU beside the CPU.
    pub fn new(scene: RenderScene, name: impl Into<String>) -> Config {
        Config {
            scene,
            name: name.into(),
            width: 256,
            height: 256,
            render_size: 32,
            reference_spp: 512,
            max_spp: 64,
            reference_bounces: 16,
            repeat: 3,
            device: DeviceChoice::Auto,
        }
    }
}

/// Rays aimed at the closed icosphere's vertices and edges (leaks).
pub const LEAK_RAYS: usize = 100_000;
/// Rays per constructed hard case (false misses).
pub const CASE_RAYS: usize = 2_000;
/// Surface points the secondary rays leave from (self-hits).
pub const SECONDARY_POINTS: usize = 2_000;
/// Samples per pixel of the bounce rows.
pub const BOUNCE_SPP: u32 = 16;
/// The robust defaults' row, the baseline of the trace rows.
pub const DEFAULTS: &str = "robust (all defaults)";
/// Every fast setting at once.
pub const FASTEST: &str = "MT + plain + no offset + trusted";
/// The three accuracy knobs at their fast settings, the shader checks left at the default:
/// what the robust defaults (watertight, robust slab, error-bound offset) are priced against.
pub const FAST_ACCURACY: &str = "MT + plain + no offset";
/// The GPU kernels as wgpu translates the WGSL (a driver may fuse a multiply-add), against
/// the default, lancer's exact SPIR-V (`gpu::exact_spirv`); measured where the adapter
/// takes the latter (elsewhere the defaults' row already is wgpu's translation).
pub const WGPU_ARITHMETIC: &str = "wgpu's translation";

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
    /// GPU: the kernels in lancer's exact SPIR-V where the adapter takes it (false: as wgpu
    /// translates the WGSL).
    exact: bool,
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
        exact: true,
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
        exact: true,
    };
    let with = |f: &dyn Fn(&mut Robustness)| {
        let mut r = d;
        f(&mut r);
        r
    };
    let mut s = vec![
        rob("defaults", DEFAULTS, d, true, true),
        rob(
            "triangle test",
            "Möller–Trumbore",
            with(&|r| r.triangle_test = TriangleTest::MollerTrumbore),
            true,
            true,
        ),
        rob(
            "slab test",
            "plain",
            with(&|r| r.slab_test = SlabTest::Plain),
            true,
            true,
        ),
        rob(
            "ray offset",
            "fixed epsilon",
            with(&|r| r.ray_offset = RayOffset::Fixed),
            true,
            true,
        ),
        rob(
            "ray offset",
            "none",
            with(&|r| r.ray_offset = RayOffset::None),
            true,
            true,
        ),
        rob(
            "shader checks",
            "trusted",
            with(&|r| r.checked_module = false),
            false,
            true,
        ),
        Setting {
            exact: false,
            ..rob("GPU arithmetic", WGPU_ARITHMETIC, d, false, true)
        },
        rob(
            "CPU precision",
            "f64",
            with(&|r| r.precision = Precision::F64),
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
#[derive(Clone, Debug, Default, Serialize)]
pub struct Row {
    /// What is varied: defaults, triangle test, slab test, ray offset, shader checks, CPU
    /// precision, fastest, BVH builder, spp or max bounces.
    pub knob: String,
    /// The setting of the knob.
    pub setting: String,
    /// "cpu" or "gpu".
    pub device: &'static str,
    /// Median ms of the scene's primary and shadow rays (trace rows) or of the render.
    pub ms: f64,
    /// Million rays (render rows: camera samples) per second.
    #[serde(rename = "mrays_per_s")]
    pub mrays: f64,
    /// ms relative to the defaults on the same device.
    #[serde(rename = "relative_to_default")]
    pub relative: Option<f64>,
    /// Rays that leak through the closed icosphere.
    pub leaks: Option<usize>,
    /// Rays of the constructed hard cases that miss a triangle they hit.
    pub false_misses: Option<usize>,
    /// Secondary rays that hit the surface they leave, in %.
    pub self_hits_pct: Option<f64>,
    /// GPU rows: primary and shadow rays whose answer (t, triangle, u, v) is not bit for bit
    /// the CPU twin's, with the same layout and settings (0 wherever the kernels' arithmetic
    /// is the CPU's).
    pub twin_mismatches: Option<usize>,
    /// Leaks, false misses and self-hits in % of the rays they are counted on.
    pub error_pct: Option<f64>,
    /// SAH cost of the BVH.
    #[serde(rename = "sah_cost")]
    pub sah: Option<f64>,
    /// Mean nodes visited per primary ray.
    #[serde(rename = "nodes_per_ray")]
    pub nodes: Option<f64>,
    /// Mean triangles tested per primary ray.
    #[serde(rename = "tris_per_ray")]
    pub tris: Option<f64>,
    /// RMSE against the reference render (linear radiance).
    pub rmse: Option<f64>,
    /// Bias of the mean against the reference's, in % of it.
    pub bias_pct: Option<f64>,
    /// Samples per pixel of the render rows.
    pub spp: Option<u32>,
}

/// `bench accuracy`'s results (`--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The scene file.
    pub scene: String,
    /// The GPU adapter, or null.
    pub adapter: Option<String>,
    /// CPU threads.
    pub cpu_threads: usize,
    /// One object per knob setting and device.
    pub rows: Vec<Row>,
    /// What the run measured on, for the text.
    #[serde(skip)]
    pub setup: Setup,
}

/// What a run measured on (the report's header lines).
#[derive(Clone, Debug, Default)]
pub struct Setup {
    /// Triangles of the scene.
    pub triangles: usize,
    /// Size of the timed primary rays' image.
    pub width: u32,
    /// Height of the timed primary rays' image.
    pub height: u32,
    /// Primary and shadow rays timed.
    pub rays: usize,
    /// Triangles of the closed icosphere (leaks).
    pub sphere_triangles: usize,
    /// Rays of the constructed hard cases (false misses).
    pub case_rays: usize,
    /// Side of the rendered images.
    pub render_size: u32,
    /// Samples per pixel of the reference render.
    pub reference_spp: u32,
    /// Bounces of the reference render.
    pub reference_bounces: u32,
    /// Milliseconds of the reference render.
    pub reference_ms: f64,
    /// Whether the GPU times come from timestamp queries (None without a GPU).
    pub gpu_timestamps: Option<bool>,
    /// The devices measured: "cpu", and "gpu" with a GPU.
    pub devices: Vec<&'static str>,
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
        let layout = flatten(
            LayoutKind::DfsSign,
            &build(&mesh, &BuildOptions::default()),
            &mesh,
        );
        let (primary, shadow) = super::rays::primary_and_shadow(&mesh, layout.as_ref(), &camera);
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
    Ok(super::timing::seconds(tracer, rays, query)? * 1e3)
}

/// Tracers of one builder on one device: the scene's BVH, and (for the judged settings)
/// the icosphere's and every hard case's.
struct Tracers<'d> {
    scene: Tracer<'d>,
    /// The scene's layout and options, for the CPU twin of a GPU row.
    layout: Arc<dyn GpuForm>,
    opts: TracerOptions,
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
            (opts.layout).unwrap_or_else(|| crate::trace::default_layout(device)),
            &tree,
            &work.mesh,
        )?
        .into();
        let scene = Tracer::with_layout(device, layout.clone(), &opts)?;
        let mut tracers = Vec::new();
        if judged {
            tracers.push(Tracer::new(device, &work.sphere, &opts)?);
            for c in &work.cases {
                tracers.push(Tracer::new(device, &c.mesh, &opts)?);
            }
        }
        Ok(Tracers {
            scene,
            layout,
            opts,
            sah,
            judged: tracers,
        })
    }
}

/// Compiles (GPU) and warms up one setting's kernels, outside the timing.
fn warm_up(t: &mut Tracers, s: &Setting, work: &Work) -> Result<()> {
    t.scene.set_kernel(s.rob, 64, false);
    let head = |rays: &[Ray]| rays.len().min(1024);
    t.scene
        .trace(&work.primary[..head(&work.primary)], Query::Closest)?;
    t.scene
        .trace(&work.shadow[..head(&work.shadow)], Query::Any)?;
    Ok(())
}

/// Milliseconds of one setting's primary and shadow rays.
fn time_once(t: &mut Tracers, s: &Setting, work: &Work) -> Result<f64> {
    t.scene.set_kernel(s.rob, 64, false);
    Ok(trace_ms(&mut t.scene, &work.primary, Query::Closest)?
        + trace_ms(&mut t.scene, &work.shadow, Query::Any)?)
}

/// Primary and shadow rays on which the GPU's answers are not bit for bit those of the CPU
/// twin of the same layout and settings (a ray the driver cut short is traced again on the
/// twin, so it matches).
fn twin_mismatches(t: &mut Tracers, s: &Setting, work: &Work) -> Result<usize> {
    let cpu = Device::cpu();
    let mut twin = Tracer::with_layout(&cpu, t.layout.clone(), &t.opts)?;
    twin.set_kernel(s.rob, 64, false);
    t.scene.set_kernel(s.rob, 64, false);
    let mut differ = 0;
    for (rays, query) in [(&work.primary, Query::Closest), (&work.shadow, Query::Any)] {
        let want = twin.trace(rays, query)?.hits;
        let got = t.scene.trace(rays, query)?.hits;
        let counts = count_agreement(&want, &got, 0);
        differ += counts.rays - counts.identical;
    }
    Ok(differ)
}

/// The work per ray and (for judged settings) the errors one setting leaves on one device.
fn judge(t: &mut Tracers, s: &Setting, device: &'static str, work: &Work, ms: f64) -> Result<Row> {
    let twin = match device {
        "gpu" => Some(twin_mismatches(t, s, work)?),
        _ => None,
    };
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
        twin_mismatches: twin,
        ..Row::default()
    };
    if !s.errors {
        return Ok(row);
    }
    let mut judged = t.judged.iter_mut();
    if let Some(sphere) = judged.next() {
        sphere.set_kernel(s.rob, 64, false);
        let hits = sphere.trace(&work.aimed, Query::Closest)?.hits;
        row.leaks = Some(closed::leaks(&hits));
    }
    let mut lost = 0;
    for (tracer, case) in judged.zip(&work.cases) {
        tracer.set_kernel(s.rob, 64, false);
        let hits = tracer.trace(&case.rays, Query::Closest)?.hits;
        lost += false_misses(&case.mesh, &case.rays, &hits, &s.rob);
    }
    row.false_misses = Some(lost);
    let (rays, own) = secondary::secondary_rays(&work.mesh, SECONDARY_POINTS, s.rob.ray_offset, 3);
    t.scene.set_kernel(s.rob, 64, false);
    let hits = t.scene.trace(&rays, Query::Closest)?.hits;
    let selfs = secondary::self_hits(&hits, &own);
    let judged = work.aimed.len() + work.case_rays() + rays.len();
    let errors = row.leaks.unwrap_or(0) + lost + selfs;
    row.self_hits_pct = Some(100.0 * selfs as f64 / rays.len().max(1) as f64);
    row.error_pct = Some(100.0 * errors as f64 / judged as f64);
    Ok(row)
}

/// Mean over pixels and channels.
fn mean(px: &[Vec3]) -> f64 {
    px.iter().map(|c| (c.x + c.y + c.z) as f64).sum::<f64>() / (3 * px.len().max(1)) as f64
}

/// RMSE over pixels and channels ([`compare_images`]), and the bias of the mean in % of
/// the reference's mean.
fn error_against(image: &Image, reference: &Image) -> Result<(f64, f64)> {
    let rmse = compare_images(image, reference, 0.0)?.rmse;
    let m = mean(&reference.pixels);
    let bias = match m > 0.0 {
        true => 100.0 * (mean(&image.pixels) - m) / m,
        false => 0.0,
    };
    Ok((rmse, bias))
}

/// One render of `scene` with `spp` samples and seed `seed`: (image, milliseconds).
fn render(scene: &RenderScene, device: &Device, spp: u32, seed: u32) -> Result<(Image, f64)> {
    let options = RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        ..RenderOptions::default()
    };
    let r = Renderer::new(scene, device, &options)?.render(&options)?;
    Ok((r.image, r.seconds * 1e3))
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    // Primary and shadow rays, their hits and the images, per pixel.
    crate::limits::check_image(
        config.width,
        config.height,
        200,
        "use a smaller --width/--height",
    )?;
    let scene = &config.scene;
    let device = super::open_device(config.device)?;
    let cpu = Device::cpu();
    let mut devices: Vec<(&'static str, &Device)> = vec![("cpu", &cpu)];
    if !device.is_cpu() {
        devices.push(("gpu", &device));
    }
    // The GPU as wgpu translates the WGSL, where the default is lancer's exact SPIR-V.
    let translated = (device.gpu_context())
        .filter(|ctx| ctx.exact_spirv)
        .map(|ctx| {
            let mut ctx = ctx.clone();
            (ctx.exact_spirv, ctx.exact_division) = (false, false);
            Device::gpu(ctx)
        });
    let work = Work::new(scene, config.width, config.height)?;
    let settings = settings();
    let spps: Vec<u32> = std::iter::successors(Some(1u32), |s| s.checked_mul(4))
        .take_while(|&s| s <= config.max_spp)
        .collect();
    let bounces: Vec<u32> = [1, 2, 4, 8, 16].into();
    let jobs = devices.len() * (settings.len() + spps.len() + bounces.len()) + 1;
    let ticker = Ticker::new(progress, jobs as u64);
    let repeat = config.repeat.max(1);
    let mut rows = Vec::new();
    for &(dev_name, dev) in &devices {
        // A setting's device: `dev`, or the GPU as wgpu translates the WGSL.
        let on = |s: &Setting| match s.exact {
            true => Some(dev),
            false => translated.as_ref().filter(|_| !dev.is_cpu()),
        };
        let runs = |s: &&Setting| on(s).is_some() && if dev.is_cpu() { s.cpu } else { s.gpu };
        // One set of tracers per build and arithmetic.
        let same = |a: &Setting, b: &Setting| a.build == b.build && a.exact == b.exact;
        let mut groups: Vec<(Tracers, Vec<&Setting>)> = Vec::new();
        for s in settings.iter().filter(runs) {
            match groups.iter_mut().find(|g| same(g.1[0], s)) {
                Some(g) => g.1.push(s),
                None => {
                    let judged = settings.iter().any(|o| same(o, s) && o.errors);
                    let tracers = Tracers::new(on(s).unwrap_or(dev), &work, &s.build, judged)?;
                    groups.push((tracers, vec![s]));
                }
            }
        }
        // Rounds over every setting in turn, so that a change in the machine's load (other
        // work on the same cores) falls on all settings alike.
        let mut ms: Vec<Vec<Vec<f64>>> =
            groups.iter().map(|g| vec![Vec::new(); g.1.len()]).collect();
        for round in 0..=repeat {
            ticker.say(format!("{dev_name}: timing, round {round} of {repeat}"));
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
                ticker.say(format!("{dev_name}: judging {} {}", s.knob, s.name));
                let t = median(std::mem::take(&mut ms[gi][si]));
                rows.push(judge(tracers, s, dev_name, &work, t)?);
                ticker.inc(1);
            }
        }
        ticker.inc((settings.len() - settings.iter().filter(runs).count()) as u64);
    }
    // Renders: a reference on the CPU (the reference renderer), then spp and bounces on each
    // device.
    let mut small = scene.clone();
    (small.camera.width, small.camera.height) = (config.render_size, config.render_size);
    let mut deep = small.clone();
    deep.settings.max_bounces = config.reference_bounces;
    ticker.say("reference render");
    let seed = scene.settings.seed;
    let (reference, reference_ms) = render(&deep, &cpu, config.reference_spp, seed ^ 0x5eed)?;
    ticker.inc(1);
    let pixels = (config.render_size * config.render_size) as f64;
    for &(dev_name, dev) in &devices {
        let mut add = |knob: &str, name: String, scene: &RenderScene, spp: u32| {
            ticker.say(format!("{dev_name}: {name}"));
            let (image, ms) = render(scene, dev, spp, seed)?;
            let (rmse, bias) = error_against(&image, &reference)?;
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
            ticker.inc(1);
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
    relative_to_defaults(&mut rows, scene);
    Ok(Report {
        scene: config.name.clone(),
        adapter: super::adapter_of(&device),
        cpu_threads: super::cpu_threads(),
        rows,
        setup: Setup {
            triangles: work.mesh.included().len(),
            width: config.width,
            height: config.height,
            rays: work.primary.len() + work.shadow.len(),
            sphere_triangles: work.sphere.len(),
            case_rays: work.case_rays(),
            render_size: config.render_size,
            reference_spp: config.reference_spp,
            reference_bounces: config.reference_bounces,
            reference_ms,
            gpu_timestamps: device.gpu_context().map(|c| c.timestamps),
            devices: devices.iter().map(|d| d.0).collect(),
        },
    })
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

impl Report {
    /// The median ms of one device's setting.
    pub fn ms(&self, device: &str, setting: &str) -> Option<f64> {
        (self.rows.iter())
            .find(|r| r.device == device && r.setting == setting)
            .map(|r| r.ms)
    }
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &["cpu", "gpu", "spp"];

    fn title(&self) -> String {
        format!("bench accuracy: {}", super::file_name(&self.scene))
    }

    fn adapter(&self) -> Option<String> {
        self.adapter.clone()
    }

    fn text(&self) -> String {
        let s = &self.setup;
        let mut out = format!(
            "scene {}  {} triangles  primary {}x{} + shadow rays ({} rays)  {} CPU threads\n",
            self.scene, s.triangles, s.width, s.height, s.rays, self.cpu_threads
        );
        if let (Some(a), Some(ts)) = (&self.adapter, s.gpu_timestamps) {
            let timing = if ts { "GPU timestamps" } else { "wall time" };
            out += &format!("adapter {a} (GPU times: {timing})\n");
        }
        out += &format!(
            "leaks: of {LEAK_RAYS} rays aimed at the vertices and edges of a closed icosphere \
             ({} triangles); false misses: of {} constructed hard-case rays; self-hits: % of \
             the secondary rays from {SECONDARY_POINTS} surface points\n",
            s.sphere_triangles, s.case_rays
        );
        out += &format!(
            "renders: {0}x{0} px; reference {1} spp, {2} bounces on the CPU ({3:.0} ms); bounce \
             rows at {BOUNCE_SPP} spp; bias in % of the reference's mean\n",
            s.render_size, s.reference_spp, s.reference_bounces, s.reference_ms
        );
        let mut t = Table::new(&[
            "knob",
            "setting",
            "device",
            "ms",
            "Mrays/s",
            "× default",
            "leaks",
            "false misses",
            "self-hits %",
            "≠ CPU twin",
            "SAH cost",
            "nodes/ray",
            "tris/ray",
            "RMSE",
            "bias %",
        ]);
        let count = |x: Option<usize>| x.map_or("–".into(), |x| x.to_string());
        for r in &self.rows {
            t.row(vec![
                r.knob.clone(),
                r.setting.clone(),
                r.device.to_string(),
                format!("{:.2}", r.ms),
                format!("{:.2}", r.mrays),
                dash(r.relative, 2),
                count(r.leaks),
                count(r.false_misses),
                dash(r.self_hits_pct, 2),
                count(r.twin_mismatches),
                dash(r.sah, 1),
                dash(r.nodes, 1),
                dash(r.tris, 1),
                dash(r.rmse, 4),
                r.bias_pct.map_or("–".into(), |x| format!("{x:+.2}")),
            ]);
        }
        out += &t.text();
        out += &format!(
            "≠ CPU twin: GPU rows, of the {} primary and shadow rays, those whose answer is not \
             bit for bit the CPU twin's (same layout and settings)\n",
            s.rays
        );
        let gpu =
            |setting: &str| (self.rows.iter()).find(|r| r.device == "gpu" && r.setting == setting);
        if let (Some(exact), Some(fused)) = (gpu(DEFAULTS), gpu(WGPU_ARITHMETIC)) {
            out += &format!(
                "gpu: lancer's exact SPIR-V takes {:.2} ms ({} answers not the CPU's); wgpu's \
                 translation {:.2} ms ({} not the CPU's): exactness costs {:+.1}%\n",
                exact.ms,
                count(exact.twin_mismatches),
                fused.ms,
                count(fused.twin_mismatches),
                100.0 * (exact.ms / fused.ms - 1.0)
            );
        }
        for dev in &s.devices {
            let ms = |name| self.ms(dev, name);
            if let (Some(robust), Some(fast), Some(fastest)) =
                (ms(DEFAULTS), ms(FAST_ACCURACY), ms(FASTEST))
            {
                out += &format!(
                    "{dev}: the robust defaults take {robust:.2} ms; the fast accuracy settings \
                     ({FAST_ACCURACY}) {fast:.2} ms: robust costs {:+.1}%; with trusted modules \
                     too ({FASTEST}) {fastest:.2} ms: {:+.1}%\n",
                    100.0 * (robust / fast - 1.0),
                    100.0 * (robust / fastest - 1.0)
                );
            }
        }
        out
    }

    /// Error vs time per device (one point per setting; no chart for a device not
    /// measured), and RMSE vs spp.
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        use super::chart::xy_chart;
        let mut drawn = Vec::new();
        for (path, dev) in paths.iter().zip(["cpu", "gpu"]) {
            if !self.setup.devices.contains(&dev) {
                continue;
            }
            let series: Vec<(String, Vec<(f64, f64)>)> = (self.rows.iter())
                .filter(|r| r.device == dev && r.rmse.is_none())
                .filter_map(|r| {
                    let point = (r.ms, r.error_pct?);
                    Some((format!("{}: {}", r.knob, r.setting), vec![point]))
                })
                .collect();
            xy_chart(
                path,
                &format!("error left vs trace time ({dev})"),
                "primary + shadow rays (ms)",
                "leaks + false misses + self-hits (% of judged rays)",
                false,
                false,
                &series,
                true,
            )?;
            drawn.push(path.clone());
        }
        let Some(path) = paths.get(2) else {
            return Ok(drawn);
        };
        let mut curves = Vec::new();
        for dev in &self.setup.devices {
            let pts: Vec<(f64, f64)> = (self.rows.iter())
                .filter(|r| r.device == *dev && r.knob == "spp")
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
            path,
            "convergence against the reference",
            "samples per pixel",
            "RMSE (linear radiance)",
            true,
            true,
            &curves,
            false,
        )?;
        drawn.push(path.clone());
        Ok(drawn)
    }
}
