//! Subcommands of the `lancer` binary.

mod bench;
mod bench_render;
mod build;
mod heatmap;
mod rays;
mod render;
mod trace;

use clap::{Args, Parser, Subcommand};
use lancer::accel::bvh::{BuildOptions, Builder, MAX_BINS};
use lancer::Result;

#[derive(Parser)]
#[command(
    name = "lancer",
    version,
    about = "GPU compute ray tracer with a CPU reference"
)]
pub struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a TOML scene (or an OBJ on a ground plane under a sun) to PNG or EXR.
    Render(render::RenderCmd),
    /// Build a BVH and print its statistics.
    Build(build::BuildCmd),
    /// Trace a ray file, write a hit file.
    Trace(trace::TraceCmd),
    /// Write the primary rays of a mesh's default view.
    Rays(rays::RaysCmd),
    /// Render nodes visited per pixel of the default view as a PNG.
    Heatmap(heatmap::HeatmapCmd),
    /// Measure speed.
    Bench(bench::BenchCmd),
}

/// BVH build options shared by the subcommands that build one.
#[derive(Args, Clone, Debug)]
pub struct BuildArgs {
    /// Builder.
    #[arg(long, value_enum, default_value_t = Builder::Sweep)]
    builder: Builder,
    /// Bins per axis (binned builder), 2 to 64.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(2..=MAX_BINS as i64))]
    bins: u32,
    /// Largest leaf; bigger nodes are always split.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    max_leaf: u32,
    /// SAH cost of one box test.
    #[arg(long, default_value_t = 1.0)]
    t_cube: f32,
    /// SAH cost of one triangle test.
    #[arg(long, default_value_t = 1.0)]
    t_obj: f32,
}

impl BuildArgs {
    pub fn options(&self) -> BuildOptions {
        BuildOptions {
            builder: self.builder,
            t_cube: self.t_cube,
            t_obj: self.t_obj,
            max_leaf: self.max_leaf as usize,
            bins: self.bins as usize,
            ..BuildOptions::default()
        }
    }
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Render(c) => c.run(),
        Cmd::Build(c) => c.run(),
        Cmd::Trace(c) => c.run(),
        Cmd::Rays(c) => c.run(),
        Cmd::Heatmap(c) => c.run(),
        Cmd::Bench(c) => c.run(),
    }
}
