use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bvh::{build, BvhStats, FlatBvh};
use lancer::gpu::BvhMemory;
use lancer::render::{image_kind, save_image, CpuRenderer, EffectSet, GpuRenderer, RenderScene};
use lancer::{Error, Result};

use super::trace::{memory_name, open_device, Device};
use super::BuildArgs;

#[derive(Args)]
pub struct RenderCmd {
    /// Scene: a .toml scene file, or an .obj mesh (default view, ground plane, sun).
    scene: PathBuf,
    /// Output image: .png (sRGB, 8-bit) or .exr (linear float).
    #[arg(short, long)]
    out: PathBuf,
    /// Image width (default: the scene's, 640 for a mesh).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene's, 480 for a mesh).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    spp: Option<u32>,
    /// Random seed (default: the scene's).
    #[arg(long)]
    seed: Option<u32>,
    /// Stop after the last sample that fits in this many seconds (at least one sample).
    #[arg(long)]
    time_limit: Option<f64>,
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    device: Device,
    /// Compile every effect in, whatever the scene calls for (for comparisons).
    #[arg(long)]
    all_effects: bool,
    /// Print build time, BVH statistics, effects, device and speed.
    #[arg(long)]
    stats: bool,
    /// GPU: where the kernels read the BVH from (storage textures or storage buffers).
    #[arg(long, value_enum, default_value_t = BvhMemory::default())]
    bvh_memory: BvhMemory,
    #[command(flatten)]
    build: BuildArgs,
}

/// Loads a scene with the command line's overrides applied.
pub fn load_scene(
    path: &std::path::Path,
    width: Option<u32>,
    height: Option<u32>,
) -> Result<RenderScene> {
    let is_obj = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let mut scene = if is_obj {
        RenderScene::from_mesh(path, width.unwrap_or(640), height.unwrap_or(480))?
    } else {
        RenderScene::from_file(path)?
    };
    if width == Some(0) || height == Some(0) {
        return Err(Error::input(
            path,
            None,
            "--width and --height must be positive",
        ));
    }
    scene.camera.width = width.unwrap_or(scene.camera.width);
    scene.camera.height = height.unwrap_or(scene.camera.height);
    Ok(scene)
}

impl RenderCmd {
    pub fn run(self) -> Result<()> {
        image_kind(&self.out)?;
        let mut scene = load_scene(&self.scene, self.width, self.height)?;
        if let Some(s) = self.spp {
            scene.settings.spp = s;
        }
        if let Some(s) = self.seed {
            scene.settings.seed = s;
        }
        let opts = self.build.options();
        let t0 = Instant::now();
        let flat = FlatBvh::new(&build(&scene.mesh, &opts), &scene.mesh);
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        let effects = if self.all_effects {
            EffectSet::ALL
        } else {
            EffectSet::of(&scene)
        };
        let ctx = open_device(self.device)?;

        let stop = Arc::new(AtomicBool::new(false));
        {
            let stop = stop.clone();
            // A second Ctrl-C while saving is not caught: the default handler ends the run.
            let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
        }
        let (w, h) = (scene.camera.width, scene.camera.height);
        let spp = scene.settings.spp;
        let bar = ProgressBar::new(spp as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} spp  {msg}  {elapsed_precise}")
                .expect("valid template"),
        );
        let start = Instant::now();
        let mut gpu_ms = 0.0;
        let mut done = 0u32;
        let mut gpu = match &ctx {
            Some(c) => Some(GpuRenderer::with_memory(c, &scene, &flat, self.bvh_memory)?),
            None => None,
        };
        let cpu = CpuRenderer::new(&scene, &flat, effects);
        let mut accum = vec![Vec3::ZERO; (w * h) as usize];
        let mut interrupted = false;
        while done < spp {
            if stop.load(Ordering::SeqCst) {
                interrupted = true;
                break;
            }
            let elapsed = start.elapsed().as_secs_f64();
            if let Some(limit) = self.time_limit {
                if done > 0 && elapsed * (done + 1) as f64 / done as f64 > limit {
                    break;
                }
            }
            match gpu.as_mut() {
                Some(g) => gpu_ms += g.add_sample(effects, done)?,
                None => cpu.accumulate(&mut accum, done, 1),
            }
            done += 1;
            let rate = (done as f64 * (w * h) as f64) / start.elapsed().as_secs_f64();
            bar.set_message(format!("{:.2} M camera rays/s", rate * 1e-6));
            bar.set_position(done as u64);
        }
        bar.finish_and_clear();
        let secs = start.elapsed().as_secs_f64();
        if let Some(g) = &gpu {
            accum = g.read_accum()?;
        }
        if done == 0 {
            return Err(Error::Gpu(
                "interrupted before the first sample finished: nothing to save".into(),
            ));
        }
        let inv = 1.0 / done as f32;
        let px: Vec<Vec3> = accum.iter().map(|c| *c * inv).collect();
        save_image(&self.out, &px, w, h)?;
        let device = ctx
            .as_ref()
            .map_or("cpu".to_string(), |c| format!("gpu: {}", c.adapter));
        let why = if interrupted {
            " (interrupted: saved what had accumulated)"
        } else if done < spp {
            " (time limit)"
        } else {
            ""
        };
        println!(
            "{w}x{h} {done}/{spp} spp -> {} ({device}, {secs:.2} s){why}",
            self.out.display()
        );
        if self.stats {
            let s = BvhStats::of(&flat, &opts);
            println!(
                "triangles {}  nodes {}  leaves {}  max depth {}  SAH {:.2}  build {build_ms:.1} ms",
                s.triangles, s.nodes, s.leaves, s.max_depth, s.sah_cost
            );
            println!("effects: {effects}");
            if gpu.is_some() {
                println!("BVH memory: {}", memory_name(self.bvh_memory));
            }
            println!(
                "{:.2} M camera rays/s, {:.1} ms per spp{}",
                done as f64 * (w * h) as f64 / secs * 1e-6,
                secs * 1e3 / done as f64,
                if gpu.is_some() {
                    format!(", GPU wall {gpu_ms:.0} ms")
                } else {
                    String::new()
                }
            );
        }
        Ok(())
    }
}
