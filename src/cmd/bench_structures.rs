//! `lancer bench structures`: parses, runs `lancer::bench::structures`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::structures::{load, run, Config, Report};
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};

#[derive(Args)]
pub struct BenchStructures {
    /// Mesh (.obj, .ply, .gltf, .glb; primary rays from its default view) or TOML scene (all its objects, primary
    /// rays from its camera), e.g. scenes/teapot-in-stadium.toml.
    mesh: PathBuf,
    /// Image width of the primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height of the primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// Random rays: origins uniform in the bounds, directions uniform (default: as many as
    /// primary rays).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    random: Option<u32>,
    #[command(flatten)]
    gpu: BenchDevice,
    /// Timed runs per structure and ray set (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    out: Outputs,
    /// Also draw Mrays/s per structure and ray set (CPU, GPU) as a PNG bar chart here (none
    /// by default).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: super::BuilderArgs,
}

impl BenchStructures {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        let (mesh, camera) = load(&self.mesh)?;
        self.out.check::<Report>(&mesh.sources, chart.as_slice())?;
        let config = Config {
            mesh,
            camera,
            name: self.mesh.display().to_string(),
            width: self.width,
            height: self.height,
            random: self.random,
            device: self.gpu.device,
            bvh_memory: self.gpu.bvh_memory,
            repeat: self.repeat as usize,
            build: self.build.options(),
        };
        let report = with_bar("", |p| run(&config, p))?;
        self.out.finish(&report, chart.as_slice())
    }
}
