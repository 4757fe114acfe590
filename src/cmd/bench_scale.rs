//! `lancer bench scale`: parses, runs `lancer::bench::scale`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::memory::fresh_memory;
use lancer::bench::scale::{run, Config, Report};
use lancer::render::load_geometry;
use lancer::Result;

use super::bench::{with_bar, BenchDevice, Outputs};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchScale {
    /// Meshes (.obj, .ply, .gltf, .glb) or scenes (.toml: the assembled mesh), one or more;
    /// each is read anew for every timed run (a file placing meshes more than once:
    /// flattened, as `trace --flatten` takes it).
    #[arg(required = true)]
    meshes: Vec<PathBuf>,
    /// Width of the default view whose primary rays are traced.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the default view.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    gpu: BenchDevice,
    /// Timed runs of the whole pipeline per mesh (medians are reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    out: Outputs,
    /// Also draw each step's time per million triangles as a PNG bar chart here (none by
    /// default).
    #[arg(long, value_name = "FILE.png", value_parser = super::bench::png_file)]
    chart: Option<PathBuf>,
    #[command(flatten)]
    build: BuildArgs,
}

impl BenchScale {
    pub fn run(self) -> Result<()> {
        let chart = self.chart.as_deref();
        // Each mesh read once before the timed runs: a bad file is refused before any
        // work, and every file it names is known for the output checks. Its memory goes
        // back to the system at once, not into the first run's resident set.
        let mut sources = Vec::new();
        fresh_memory(|| -> Result<()> {
            for path in &self.meshes {
                sources.extend(load_geometry(path)?.sources);
            }
            Ok(())
        })?;
        self.out.check::<Report>(&sources, chart.as_slice())?;
        let config = Config {
            meshes: self.meshes,
            width: self.width,
            height: self.height,
            device: self.gpu.device,
            bvh_memory: self.gpu.bvh_memory,
            layout: self.build.layout(),
            repeat: self.repeat as usize,
            build: self.build.options(),
        };
        let report = with_bar("runs", |p| run(&config, p))?;
        self.out.finish(&report, chart.as_slice())
    }
}
