//! `lancer bench refit`: parses, runs `lancer::bench::refit`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::refit::{run, Config, Report};
use lancer::render::load_geometry;
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchRefit {
    /// Mesh deformed (.obj, .ply, .gltf, .glb; a scene .toml: its flattened mesh).
    mesh: PathBuf,
    /// Deformation steps after the undeformed mesh.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=100))]
    steps: u32,
    /// Twist at the last step: degrees about the mesh's longest axis, from one end to the
    /// other.
    #[arg(long, default_value_t = 90.0, value_parser = super::positive_finite)]
    max_twist: f32,
    /// Width of the primary rays' image (each step's default view).
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
    /// Also draw the refit tree's cost against the rebuilt tree's by twist as a PNG chart
    /// here (none by default).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: BuildArgs,
}

impl BenchRefit {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        let mesh = load_geometry(&self.mesh)?;
        self.out.check::<Report>(&mesh.sources, chart.as_slice())?;
        let config = Config {
            mesh,
            name: self.mesh.display().to_string(),
            steps: self.steps as usize,
            max_twist: self.max_twist,
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
