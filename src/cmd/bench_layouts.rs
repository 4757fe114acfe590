//! `lancer bench layouts`: parses, runs `lancer::bench::layouts`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::layouts::{run, Config, Report};
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};
use super::check::{layout_choice, LayoutChoice};
use super::BuilderArgs;
use lancer::render::load_geometry;

#[derive(Args)]
pub struct BenchLayouts {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Width of the default view (primary rays; shadow and bounce rays start at their hits).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the default view.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    gpu: BenchDevice,
    /// Layouts to measure: a name or all.
    #[arg(long = "layout", value_name = "NAME|all", default_value = "all", value_parser = layout_choice)]
    layouts: LayoutChoice,
    /// Timed runs per layout and ray set (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    out: Outputs,
    /// Also draw Mrays/s per layout and ray set as a PNG bar chart here (none by default).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: BuilderArgs,
}

impl BenchLayouts {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        // Loaded first: every file the mesh names (an MTL library, its textures) is an input.
        let mesh = load_geometry(&self.mesh)?;
        self.out.check::<Report>(&mesh.sources, chart.as_slice())?;
        let config = Config {
            mesh,
            name: self.mesh.display().to_string(),
            width: self.width,
            height: self.height,
            device: self.gpu.device,
            bvh_memory: self.gpu.bvh_memory,
            layouts: self.layouts.kinds(),
            // The driver's rows beside all the layouts only.
            driver: matches!(self.layouts, LayoutChoice::All),
            repeat: self.repeat as usize,
            build: self.build.options(),
        };
        let report = with_bar("runs", |p| run(&config, p))?;
        self.out.finish(&report, chart.as_slice())
    }
}
