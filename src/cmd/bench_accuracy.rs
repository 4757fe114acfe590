//! `lancer bench accuracy`: parses, runs `lancer::bench::accuracy`, prints the table and
//! writes the charts, the JSON and the results page where asked (`--chart`, `--json`,
//! `--report`).

use std::path::{Path, PathBuf};

use clap::Args;
use lancer::bench::accuracy::{run, Config, Report};
use lancer::bench::{page, BenchReport};
use lancer::render::{ImageSize, RenderScene};
use lancer::{DeviceChoice, Result};

use super::bench::{with_bar, Outputs};

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
    /// Also draw the error-vs-time charts, NAME-cpu.png and NAME-gpu.png, and the spp
    /// convergence curve, NAME-spp.png, from this path's stem (none by default).
    #[arg(long, value_name = "NAME.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    out: Outputs,
}

impl BenchAccuracy {
    pub fn run(self) -> Result<()> {
        // The charts beside --chart: NAME-cpu.png, NAME-gpu.png, NAME-spp.png.
        let charts: Vec<PathBuf> = (self.chart.iter())
            .flat_map(|c| {
                let stem = c.with_extension("md");
                (Report::CHARTS.iter())
                    .map(|s| page::beside(&stem, s))
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut inputs: Vec<PathBuf> = self.scene.iter().cloned().collect();
        let (scene, name) = match &self.scene {
            Some(path) => (
                RenderScene::open(path, &ImageSize::default(), &Default::default())?,
                path.display().to_string(),
            ),
            None => (
                lancer::render::builtin::cornell_box()?,
                lancer::render::builtin::CORNELL_NAME.to_string(),
            ),
        };
        inputs.extend(scene.mesh.sources.iter().cloned());
        let chart_paths: Vec<&Path> = charts.iter().map(PathBuf::as_path).collect();
        self.out.check::<Report>(&inputs, &chart_paths)?;
        let config = Config {
            width: self.width,
            height: self.height,
            render_size: self.render_size,
            reference_spp: self.reference_spp,
            max_spp: self.max_spp,
            reference_bounces: self.reference_bounces,
            repeat: self.repeat as usize,
            device: self.device,
            ..Config::new(scene, name)
        };
        let report = with_bar("settings", |p| run(&config, p))?;
        self.out.finish(&report, &chart_paths)
    }
}
