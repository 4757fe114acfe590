//! `lancer bench render`: milliseconds per sample per pixel on the GPU (per-ray, and with
//! subgroup traversal where it runs) and the CPU, with the kernel specialised to the scene's
//! effects and with every effect compiled in.

use std::path::PathBuf;

use clap::Args;
use indicatif::ProgressStyle;
use lancer::render::{EffectSet, RenderOptions, Renderer};
use lancer::{Device, DeviceChoice, Result, Robustness, TraversalMode, Vec3};

use serde::Serialize;

use super::bench::{median, JsonArg};
use super::out::say;
use super::render::load_scene;
use super::{open_bench_device, BuildArgs};

#[derive(Args)]
pub struct BenchRender {
    /// Scene: a .toml scene file or a mesh (.obj, .ply, .gltf, .glb).
    scene: PathBuf,
    /// Image width in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    height: Option<u32>,
    /// Timed samples per pixel per configuration, 3 or more (after one untimed warm-up
    /// sample); each is timed alone and the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(3..))]
    spp: u32,
    /// auto, gpu or cpu. auto and gpu measure the GPU and the CPU side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    #[command(flatten)]
    build: BuildArgs,
    #[command(flatten)]
    json: JsonArg,
}

/// `bench render --json`: one object a run.
#[derive(Serialize)]
struct BenchRenderReport {
    /// The scene file.
    scene: String,
    /// Triangles in the scene's BVH.
    triangles: usize,
    /// Image width in pixels.
    width: u32,
    /// Image height in pixels.
    height: u32,
    /// The scene's effects (what the specialised kernel compiles in).
    effects: String,
    /// The GPU adapter, or null.
    adapter: Option<String>,
    /// CPU threads.
    cpu_threads: usize,
    /// Timed samples per pixel per configuration.
    samples: u32,
    /// One object per device and kernel.
    runs: Vec<BenchRenderRun>,
}

/// One device × kernel.
#[derive(Serialize)]
struct BenchRenderRun {
    /// "gpu" or "cpu".
    device: &'static str,
    /// GPU: the traversal mode, "per-ray" or "subgroup" (null on the CPU).
    mode: Option<&'static str>,
    /// "specialised" (the scene's effects) or "all effects".
    kernel: &'static str,
    /// Median milliseconds per sample per pixel.
    ms_per_spp: f64,
    /// Fastest sample, in ms.
    ms_min: f64,
    /// Slowest sample, in ms.
    ms_max: f64,
    /// Million camera rays per second at the median.
    mrays_per_s: f64,
}

impl BenchRender {
    pub fn run(self) -> Result<()> {
        let say = self.json.say();
        self.json.check(std::slice::from_ref(&self.scene))?;
        let scene = load_scene(&self.scene, self.width, self.height)?;
        let device = open_bench_device(self.device)?;
        let cpu = Device::cpu();
        let options = RenderOptions {
            build: self.build.options(),
            accel: self.build.layout.map(lancer::AccelKind::Bvh),
            ..RenderOptions::default()
        };
        let specialised = EffectSet::of(&scene);
        let kernels = [
            ("specialised", specialised),
            ("all effects", EffectSet::ALL),
        ];
        // (device, mode): the GPU in both modes (subgroup where it runs), then the CPU.
        let mut configs = vec![("cpu", &cpu, None)];
        if !device.is_cpu() {
            configs.insert(0, ("gpu", &device, Some(TraversalMode::PerRay)));
            configs.insert(1, ("gpu", &device, Some(TraversalMode::Subgroup)));
        }
        let bar = super::out::progress_bar((configs.len() * 2 * (self.spp as usize + 1)) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} samples {msg}").unwrap());
        let seed = scene.settings.seed;
        let rob = Robustness::default();
        let mut accum = vec![Vec3::ZERO; (scene.camera.width * scene.camera.height) as usize];
        let mut rows = Vec::new();
        let pixels = (scene.camera.width * scene.camera.height) as f64;
        let mut triangles = 0;
        let mut not_run = None;
        for (dev_name, dev, mode) in configs {
            let options = RenderOptions {
                mode: mode.unwrap_or_default(),
                ..options.clone()
            };
            let mut renderer = Renderer::new(&scene, dev, &options)?;
            if mode.is_some_and(|m| m != renderer.mode()) {
                // Its fallback is the per-ray row already measured (the warning says why).
                not_run = mode;
                bar.inc(2 * (self.spp as u64 + 1));
                continue;
            }
            triangles = renderer.bvh_stats().map_or(0, |s| s.triangles);
            for (name, fx) in kernels {
                let mode_name = mode.map(TraversalMode::name);
                bar.set_message(format!("{dev_name} {}, {name}", mode_name.unwrap_or("")));
                // Sample 0 compiles the pipeline (GPU) and warms caches, outside the timing.
                renderer.add_sample(fx, rob, seed, 0, &mut accum)?;
                bar.inc(1);
                let mut ms = Vec::new();
                for s in 1..=self.spp {
                    ms.push(renderer.add_sample(fx, rob, seed, s, &mut accum)?);
                    bar.inc(1);
                }
                let ms_per_spp = median(ms.clone());
                rows.push(BenchRenderRun {
                    device: dev_name,
                    mode: mode_name,
                    kernel: name,
                    ms_per_spp,
                    ms_min: ms.iter().copied().fold(f64::INFINITY, f64::min),
                    ms_max: ms.iter().copied().fold(0.0, f64::max),
                    mrays_per_s: pixels / (ms_per_spp * 1e-3) * 1e-6,
                });
            }
        }
        bar.finish_and_clear();
        let (w, h) = (scene.camera.width, scene.camera.height);
        say!(
            say,
            "scene {}  {} triangles  {w}x{h}  effects: {specialised}",
            self.scene.display(),
            triangles
        );
        if let Some(ctx) = device.gpu_context() {
            say!(say, "adapter {}", ctx.adapter);
        }
        if let Some(mode) = not_run {
            say!(say, "gpu {mode}: not run (see the warning)");
        }
        say!(
            say,
            "| device | mode | kernel | ms per spp (median of {}) | fastest – slowest ms | M camera rays/s |",
            self.spp
        );
        say!(say, "|---|---|---|---|---|---|");
        for r in &rows {
            say!(
                say,
                "| {} | {} | {} | {:.1} | {:.1} – {:.1} | {:.2} |",
                r.device,
                r.mode.unwrap_or("–"),
                r.kernel,
                r.ms_per_spp,
                r.ms_min,
                r.ms_max,
                r.mrays_per_s
            );
        }
        for (dev, mode) in [
            ("gpu", Some("per-ray")),
            ("gpu", Some("subgroup")),
            ("cpu", None),
        ] {
            let of = |k: &str| {
                (rows.iter())
                    .find(|r| r.device == dev && r.mode == mode && r.kernel == k)
                    .map(|r| r.ms_per_spp)
            };
            if let (Some(s), Some(a)) = (of("specialised"), of("all effects")) {
                say!(
                    say,
                    "{dev}{}: specialisation saves {:.1}% ({a:.1} → {s:.1} ms per spp)",
                    mode.map(|m| format!(" {m}")).unwrap_or_default(),
                    100.0 * (a - s) / a
                );
            }
        }
        let of = |m: &str| {
            (rows.iter())
                .find(|r| r.mode == Some(m) && r.kernel == "specialised")
                .map(|r| r.ms_per_spp)
        };
        if let (Some(p), Some(g)) = (of("per-ray"), of("subgroup")) {
            say!(
                say,
                "gpu: subgroup traversal takes {:.2}× per-ray's time per spp ({p:.1} → {g:.1} ms)",
                g / p
            );
        }
        let report = BenchRenderReport {
            scene: self.scene.display().to_string(),
            triangles,
            width: w,
            height: h,
            effects: specialised.to_string(),
            adapter: device.gpu_context().map(|c| c.adapter.to_string()),
            cpu_threads: rayon::current_num_threads(),
            samples: self.spp,
            runs: rows,
        };
        self.json.write(&report, say)
    }
}
