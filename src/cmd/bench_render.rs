//! `lancer bench render`: milliseconds per sample per pixel on the GPU and the CPU, with
//! the kernel specialised to the scene's effects and with every effect compiled in.

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::render::{EffectSet, RenderOptions, Renderer};
use lancer::{Device, DeviceChoice, Result, Robustness, Vec3};

use super::render::load_scene;
use super::{open_device, BuildArgs};

#[derive(Args)]
pub struct BenchRender {
    /// Scene: a .toml scene file or a mesh (.obj, .ply, .gltf, .glb).
    scene: PathBuf,
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    /// Timed samples per pixel per configuration (after one untimed warm-up sample).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// auto and gpu measure the GPU and the CPU side by side; cpu only the CPU.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    #[command(flatten)]
    build: BuildArgs,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl BenchRender {
    pub fn run(self) -> Result<()> {
        let scene = load_scene(&self.scene, self.width, self.height)?;
        let device = open_device(self.device)?;
        let cpu = Device::cpu();
        let options = RenderOptions {
            build: self.build.options(),
            accel: lancer::AccelKind::Bvh(self.build.layout),
            ..RenderOptions::default()
        };
        let specialised = EffectSet::of(&scene);
        let kernels = [
            ("specialised", specialised),
            ("all effects", EffectSet::ALL),
        ];
        let mut devices = vec![("cpu", &cpu)];
        if !device.is_cpu() {
            devices.insert(0, ("gpu", &device));
        }
        let bar = ProgressBar::new((devices.len() * 2 * (self.spp as usize + 1)) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} samples {msg}").unwrap());
        let seed = scene.settings.seed;
        let rob = Robustness::default();
        let mut accum = vec![Vec3::ZERO; (scene.camera.width * scene.camera.height) as usize];
        // (device, kernel, ms per spp)
        let mut rows: Vec<(&str, &str, f64)> = Vec::new();
        let mut triangles = 0;
        for (dev_name, dev) in devices {
            let mut renderer = Renderer::new(&scene, dev, &options)?;
            triangles = renderer.bvh_stats().map_or(0, |s| s.triangles);
            for (name, fx) in kernels {
                bar.set_message(format!("{dev_name}, {name}"));
                // Sample 0 compiles the pipeline (GPU) and warms caches, outside the timing.
                renderer.add_sample(fx, rob, seed, 0, &mut accum)?;
                bar.inc(1);
                let mut ms = Vec::new();
                for s in 1..=self.spp {
                    ms.push(renderer.add_sample(fx, rob, seed, s, &mut accum)?);
                    bar.inc(1);
                }
                rows.push((dev_name, name, median(ms)));
            }
        }
        bar.finish_and_clear();
        let (w, h) = (scene.camera.width, scene.camera.height);
        println!(
            "scene {}  {} triangles  {w}x{h}  effects: {specialised}",
            self.scene.display(),
            triangles
        );
        if let Some(ctx) = device.gpu_context() {
            println!("adapter {}", ctx.adapter);
        }
        println!(
            "| device | kernel | ms per spp (median of {}) | M camera rays/s |",
            self.spp
        );
        println!("|---|---|---|---|");
        for (dev, kernel, ms) in &rows {
            let rate = (w * h) as f64 / (ms * 1e-3) * 1e-6;
            println!("| {dev} | {kernel} | {ms:.1} | {rate:.2} |");
        }
        for dev in ["gpu", "cpu"] {
            let of = |k: &str| rows.iter().find(|r| r.0 == dev && r.1 == k).map(|r| r.2);
            if let (Some(s), Some(a)) = (of("specialised"), of("all effects")) {
                println!(
                    "{dev}: specialisation saves {:.1}% ({a:.1} → {s:.1} ms per spp)",
                    100.0 * (a - s) / a
                );
            }
        }
        Ok(())
    }
}
