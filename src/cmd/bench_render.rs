//! `lancer bench render`: milliseconds per sample per pixel on the GPU and the CPU, with
//! the kernel specialised to the scene's effects and with every effect compiled in.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bvh::{build, FlatBvh};
use lancer::render::{CpuRenderer, EffectSet, GpuRenderer};
use lancer::Result;

use super::render::load_scene;
use super::trace::{open_device, Device};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchRender {
    /// Scene: a .toml scene file or an .obj mesh.
    scene: PathBuf,
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    /// Timed samples per pixel per configuration (after one untimed warm-up sample).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// auto and gpu measure the GPU and the CPU side by side; cpu only the CPU.
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    device: Device,
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
        let flat = FlatBvh::new(&build(&scene.mesh, &self.build.options()), &scene.mesh);
        let ctx = open_device(self.device)?;
        let specialised = EffectSet::of(&scene);
        let kernels = [
            ("specialised", specialised),
            ("all effects", EffectSet::ALL),
        ];
        let devices = if ctx.is_some() { 2 } else { 1 };
        let bar = ProgressBar::new((devices * 2 * (self.spp + 1)) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} samples {msg}").unwrap());
        // (device, kernel, ms per spp)
        let mut rows: Vec<(&str, &str, f64)> = Vec::new();
        if let Some(ctx) = &ctx {
            let mut gpu = GpuRenderer::new(ctx, &scene, &flat)?;
            for (name, fx) in kernels {
                bar.set_message(format!("gpu, {name}"));
                gpu.add_sample(fx, 0)?; // compiles the pipeline outside the timing
                bar.inc(1);
                let mut ms = Vec::new();
                for s in 1..=self.spp {
                    ms.push(gpu.add_sample(fx, s)?);
                    bar.inc(1);
                }
                rows.push(("gpu", name, median(ms)));
            }
        }
        let mut accum = vec![Vec3::ZERO; (scene.camera.width * scene.camera.height) as usize];
        for (name, fx) in kernels {
            bar.set_message(format!("cpu, {name}"));
            let cpu = CpuRenderer::new(&scene, &flat, fx);
            let mut ms = Vec::new();
            for s in 0..=self.spp {
                let t0 = Instant::now();
                cpu.accumulate(&mut accum, s, 1);
                if s > 0 {
                    ms.push(t0.elapsed().as_secs_f64() * 1e3);
                }
                bar.inc(1);
            }
            rows.push(("cpu", name, median(ms)));
        }
        bar.finish_and_clear();
        let (w, h) = (scene.camera.width, scene.camera.height);
        println!(
            "scene {}  {} triangles  {w}x{h}  effects: {specialised}",
            self.scene.display(),
            flat.tris.len()
        );
        if let Some(ctx) = &ctx {
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
