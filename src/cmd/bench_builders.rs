//! `lancer bench builders`: parses, runs `lancer::bench::builders`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::accel::bvh::{BuildOptions, Builder};
use lancer::bench::builders::{run, Config, Report};
use lancer::render::load_geometry;
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};

#[derive(Args)]
pub struct BenchBuilders {
    /// Meshes (.obj, .ply, .gltf, .glb) or scenes (.toml: the assembled mesh), one or more.
    #[arg(required = true)]
    meshes: Vec<PathBuf>,
    /// A builder to compare (sweep, binned, median, ploc); repeat the option for several.
    /// Default: all.
    #[arg(long = "builder", value_enum, hide_possible_values = true)]
    builders: Vec<Builder>,
    /// Also measure each builder's tree optimised by reinsertion (rows `BUILDER+reinsert`).
    #[arg(long)]
    optimize: bool,
    /// Width of the default view (primary rays; shadow and bounce rays start at their hits;
    /// as many random rays).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the default view.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    gpu: BenchDevice,
    /// Timed builds and traversals per builder, mesh and ray set (medians are reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    out: Outputs,
    /// Also draw the build times as a PNG bar chart here (a --report page also draws each
    /// tree's SAH against its time per ray beside itself).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
}

impl BenchBuilders {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        let mut meshes = Vec::new();
        let mut sources = Vec::new();
        for path in &self.meshes {
            let mesh = load_geometry(path)?;
            sources.extend(mesh.sources.iter().cloned());
            meshes.push((path.display().to_string(), mesh));
        }
        self.out.check::<Report>(&sources, chart.as_slice())?;
        let builders = match self.builders.is_empty() {
            true => Builder::ALL.to_vec(),
            false => self.builders,
        };
        let config = Config {
            meshes,
            builders,
            optimize: self.optimize,
            build: BuildOptions::default(),
            width: self.width,
            height: self.height,
            device: self.gpu.device,
            bvh_memory: self.gpu.bvh_memory,
            repeat: self.repeat as usize,
        };
        let report = with_bar("", |p| run(&config, p))?;
        self.out.finish(&report, chart.as_slice())
    }
}
