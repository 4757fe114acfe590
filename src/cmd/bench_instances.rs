//! `lancer bench instances`: parses, runs `lancer::bench::instances`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::instances::{run, Config, Report};
use lancer::render::load_geometry;
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchInstances {
    /// Mesh placed (.obj, .ply, .gltf, .glb; a scene .toml: its assembled mesh).
    mesh: PathBuf,
    /// Copies placed, on a square grid, each turned about the vertical axis; the flattened
    /// copy holds them all (mind its memory).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    copies: u32,
    /// Width of the primary rays' image (the default view of every copy).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the primary rays' image.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    gpu: BenchDevice,
    /// Timed runs per measurement (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    out: Outputs,
    /// Also draw Mrays/s of both variants per ray set as a PNG bar chart here (none by
    /// default).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: BuildArgs,
}

impl BenchInstances {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        let mesh = load_geometry(&self.mesh)?;
        self.out.check::<Report>(&mesh.sources, chart.as_slice())?;
        let config = Config {
            mesh,
            name: self.mesh.display().to_string(),
            copies: self.copies as usize,
            width: self.width,
            height: self.height,
            device: self.gpu.device,
            bvh_memory: self.gpu.bvh_memory,
            layout: self.build.layout(),
            repeat: self.repeat as usize,
            build: self.build.options(),
        };
        let report = with_bar("", |p| run(&config, p))?;
        self.out.finish(&report, chart.as_slice())
    }
}
