//! `lancer bench accuracy`: parses, runs `lancer::bench::accuracy`, prints the table and
//! writes the charts and the JSON.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::accuracy::{run, Config, Report};
use lancer::bench::{page, BenchReport};
use lancer::render::{ImageSize, RenderScene};
use lancer::{DeviceChoice, Result};

use super::bench::{print_text, with_bar, ReportArg};
use super::out::{json_to, say, JsonTo, Say};

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
    #[command(flatten)]
    report: ReportArg,
}

impl BenchAccuracy {
    pub fn run(self) -> Result<()> {
        let json =
            (self.json.clone()).unwrap_or_else(|| JsonTo::File(self.chart.with_extension("json")));
        let say = Say::new(json.is_stdout());
        // The charts beside --chart: NAME-cpu.png, NAME-gpu.png, NAME-spp.png.
        let stem = self.chart.with_extension("md");
        let charts: Vec<PathBuf> = (Report::CHARTS.iter())
            .map(|s| page::beside(&stem, s))
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
        for out in &charts {
            lancer::output::check_output(out, &inputs)?;
        }
        json.check(&inputs)?;
        self.report.check::<Report>(&inputs)?;
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
        print_text(say, &report.text());
        report.draw_charts(&charts)?;
        let names: Vec<String> = charts.iter().map(|c| c.display().to_string()).collect();
        say!(say, "charts -> {}", names.join(", "));
        json.write(&report, say)?;
        self.report.write(&report, say)
    }
}
