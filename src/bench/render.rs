//! `lancer bench render`: milliseconds per sample per pixel on the GPU (per-ray, and with
//! subgroup traversal where it runs) and the CPU, with the kernel specialised to the scene's
//! effects, with every effect compiled in, and without each effect the scene calls for in
//! turn (what that effect costs).

use serde::Serialize;

use crate::accel::bvh::layouts::LayoutKind;
use crate::accel::bvh::BuildOptions;
use crate::accel::{AccelKind, TraversalMode};
use crate::device::{Device, DeviceChoice};
use crate::error::{Error, Result};
use crate::geometry::Robustness;
use crate::render::{EffectSet, RenderOptions, RenderScene, Renderer};
use crate::Vec3;

use super::markdown::Table;
use super::timing::{median, min_max};
use super::{BenchReport, Progress, Ticker};

/// What `bench render` measures.
#[derive(Clone)]
pub struct Config {
    /// The scene, its camera at the image size to time.
    pub scene: RenderScene,
    /// The scene's name in the report (its file).
    pub name: String,
    /// Timed samples per pixel per configuration (after one untimed warm-up sample), at
    /// least 1; each is timed alone and the median is reported.
    pub spp: u32,
    /// Where to run beside the CPU: auto and gpu time the GPU on any adapter (a software
    /// one included); cpu measures the CPU alone.
    pub device: DeviceChoice,
    /// How the BVH is built.
    pub build: BuildOptions,
    /// The BVH's layout (None: each device's default).
    pub layout: Option<LayoutKind>,
}

/// `bench render`'s results (`--json`: one object a run).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The scene file.
    pub scene: String,
    /// Triangles in the scene's BVH.
    pub triangles: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The scene's effects (what the specialised kernel compiles in).
    pub effects: String,
    /// The GPU adapter, or null.
    pub adapter: Option<String>,
    /// CPU threads.
    pub cpu_threads: usize,
    /// Timed samples per pixel per configuration.
    pub samples: u32,
    /// One object per device and kernel.
    pub runs: Vec<Run>,
    /// A GPU traversal mode that could not run on the adapter (its rows are missing; the
    /// library's warning says why).
    #[serde(skip)]
    pub not_run: Option<&'static str>,
}

/// One device × kernel.
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// "gpu" or "cpu".
    pub device: &'static str,
    /// GPU: the traversal mode, "per-ray" or "subgroup" (null on the CPU).
    pub mode: Option<&'static str>,
    /// "specialised" (the scene's effects), "all effects", or "without EFFECT" (the
    /// scene's effects but one: the difference to "specialised" is what it costs).
    pub kernel: String,
    /// Median milliseconds per sample per pixel.
    pub ms_per_spp: f64,
    /// Fastest sample, in ms.
    pub ms_min: f64,
    /// Slowest sample, in ms.
    pub ms_max: f64,
    /// Million camera rays per second at the median.
    pub mrays_per_s: f64,
}

/// Runs the bench.
pub fn run(config: &Config, progress: &dyn Fn(Progress)) -> Result<Report> {
    if config.spp == 0 {
        return Err(Error::Usage("bench render times 1 sample or more".into()));
    }
    let scene = &config.scene;
    let device = super::open_device(config.device)?;
    let cpu = Device::cpu();
    let options = RenderOptions {
        build: config.build,
        accel: config.layout.map(AccelKind::Bvh),
        ..RenderOptions::default()
    };
    let specialised = EffectSet::of(scene);
    let mut kernels = vec![
        ("specialised".to_string(), specialised),
        ("all effects".to_string(), EffectSet::ALL),
    ];
    kernels.extend(
        (specialised.each_without().into_iter()).map(|(n, fx)| (format!("without {n}"), fx)),
    );
    // (device, mode): the GPU in both modes (subgroup where it runs), then the CPU.
    let mut configs = vec![("cpu", &cpu, None)];
    if !device.is_cpu() {
        configs.insert(0, ("gpu", &device, Some(TraversalMode::PerRay)));
        configs.insert(1, ("gpu", &device, Some(TraversalMode::Subgroup)));
    }
    let per_kernel = config.spp as u64 + 1;
    let n_kernels = kernels.len() as u64;
    let ticker = Ticker::new(progress, configs.len() as u64 * n_kernels * per_kernel);
    let seed = scene.settings.seed;
    let rob = Robustness::default();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut accum = vec![Vec3::ZERO; (w * h) as usize];
    let pixels = (w * h) as f64;
    let (mut runs, mut triangles, mut not_run) = (Vec::new(), 0, None);
    for (dev_name, dev, mode) in configs {
        let options = RenderOptions {
            mode: mode.unwrap_or_default(),
            ..options.clone()
        };
        let mut renderer = Renderer::new(scene, dev, &options)?;
        if mode.is_some_and(|m| m != renderer.mode()) {
            // Its fallback is the per-ray row already measured (the warning says why).
            not_run = mode.map(TraversalMode::name);
            ticker.inc(n_kernels * per_kernel);
            continue;
        }
        triangles = renderer.bvh_stats().map_or(0, |s| s.triangles);
        for (name, fx) in &kernels {
            let fx = *fx;
            let mode_name = mode.map(TraversalMode::name);
            ticker.say(format!("{dev_name} {}, {name}", mode_name.unwrap_or("")));
            // Sample 0 compiles the pipeline (GPU) and warms caches, outside the timing.
            renderer.add_sample(fx, rob, seed, 0, &mut accum)?;
            ticker.inc(1);
            let mut ms = Vec::new();
            for s in 1..=config.spp {
                ms.push(renderer.add_sample(fx, rob, seed, s, &mut accum)?);
                ticker.inc(1);
            }
            let ms_per_spp = median(ms.clone());
            let (ms_min, ms_max) = min_max(&ms);
            runs.push(Run {
                device: dev_name,
                mode: mode_name,
                kernel: name.clone(),
                ms_per_spp,
                ms_min,
                ms_max,
                mrays_per_s: pixels / (ms_per_spp * 1e-3) * 1e-6,
            });
        }
    }
    Ok(Report {
        scene: config.name.clone(),
        triangles,
        width: w,
        height: h,
        effects: specialised.to_string(),
        adapter: super::adapter_of(&device),
        cpu_threads: super::cpu_threads(),
        samples: config.spp,
        runs,
        not_run,
    })
}

impl Report {
    /// The median ms per spp of one device, mode and kernel.
    pub fn ms_per_spp(&self, device: &str, mode: Option<&str>, kernel: &str) -> Option<f64> {
        (self.runs.iter())
            .find(|r| r.device == device && r.mode == mode && r.kernel == kernel)
            .map(|r| r.ms_per_spp)
    }
}

impl BenchReport for Report {
    const CHARTS: &'static [&'static str] = &[""];

    fn title(&self) -> String {
        format!("bench render: {}", super::file_name(&self.scene))
    }

    fn adapter(&self) -> Option<String> {
        self.adapter.clone()
    }

    fn text(&self) -> String {
        let mut out = format!(
            "scene {}  {} triangles  {}x{}  effects: {}\n",
            self.scene, self.triangles, self.width, self.height, self.effects
        );
        if let Some(a) = &self.adapter {
            out += &format!("adapter {a}\n");
        }
        if let Some(mode) = self.not_run {
            out += &format!("gpu {mode}: not run (see the warning)\n");
        }
        let median = format!("ms per spp (median of {})", self.samples);
        let mut t = Table::new(&[
            "device",
            "mode",
            "kernel",
            &median,
            "fastest – slowest ms",
            "M camera rays/s",
        ]);
        for r in &self.runs {
            t.row(vec![
                r.device.to_string(),
                r.mode.unwrap_or("–").to_string(),
                r.kernel.to_string(),
                format!("{:.1}", r.ms_per_spp),
                format!("{:.1} – {:.1}", r.ms_min, r.ms_max),
                format!("{:.2}", r.mrays_per_s),
            ]);
        }
        out += &t.text();
        for (dev, mode) in [
            ("gpu", Some("per-ray")),
            ("gpu", Some("subgroup")),
            ("cpu", None),
        ] {
            let of = |k| self.ms_per_spp(dev, mode, k);
            if let (Some(s), Some(a)) = (of("specialised"), of("all effects")) {
                out += &format!(
                    "{dev}{}: specialisation saves {:.1}% ({a:.1} → {s:.1} ms per spp)\n",
                    mode.map(|m| format!(" {m}")).unwrap_or_default(),
                    100.0 * (a - s) / a
                );
            }
            // What each effect costs: the specialised kernel against it without the effect.
            let costs: Vec<String> = (self.runs.iter())
                .filter(|r| r.device == dev && r.mode == mode)
                .filter_map(|r| Some((r.kernel.strip_prefix("without ")?, r.ms_per_spp)))
                .filter_map(|(effect, without)| {
                    let s = of("specialised")?;
                    Some(format!("{effect} {:+.1}%", 100.0 * (s - without) / without))
                })
                .collect();
            if !costs.is_empty() {
                out += &format!(
                    "{dev}{}: each effect's cost (specialised ÷ without it − 1): {}\n",
                    mode.map(|m| format!(" {m}")).unwrap_or_default(),
                    costs.join(", ")
                );
            }
        }
        let of = |m| self.ms_per_spp("gpu", Some(m), "specialised");
        if let (Some(p), Some(g)) = (of("per-ray"), of("subgroup")) {
            out += &format!(
                "gpu: subgroup traversal takes {:.2}× per-ray's time per spp ({p:.1} → {g:.1} ms)\n",
                g / p
            );
        }
        out
    }

    /// Milliseconds per spp, one group per device and mode, one bar per kernel.
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>> {
        let mut categories: Vec<String> = Vec::new();
        for r in &self.runs {
            let c = format!("{} {}", r.device, r.mode.unwrap_or(""))
                .trim()
                .to_string();
            if !categories.contains(&c) {
                categories.push(c);
            }
        }
        let series: Vec<(String, Vec<f64>)> = ["specialised", "all effects"]
            .iter()
            .map(|k| {
                let values = (categories.iter())
                    .map(|c| {
                        let mut parts = c.splitn(2, ' ');
                        let (dev, mode) = (parts.next().unwrap_or(""), parts.next());
                        self.ms_per_spp(dev, mode, k).unwrap_or(f64::NAN)
                    })
                    .collect();
                (k.to_string(), values)
            })
            .collect();
        let title = format!(
            "{} {}x{}: ms per spp (median of {})",
            super::file_name(&self.scene),
            self.width,
            self.height,
            self.samples
        );
        for path in paths {
            super::chart::bar_chart(path, &title, "ms per spp", &categories, &series)?;
        }
        Ok(paths.to_vec())
    }
}
