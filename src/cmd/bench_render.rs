//! `lancer bench render`: parses, runs `lancer::bench::render`, prints.

use std::path::PathBuf;

use clap::Args;
use lancer::bench::render::{run, Config, Report};
use lancer::render::{ImageSize, RenderScene};
use lancer::{DeviceChoice, Result};

use super::bench::{with_bar, Outputs};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchRender {
    /// Scene: a .toml scene file or a mesh (.obj, .ply, .gltf, .glb).
    scene: PathBuf,
    /// Image width in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    height: Option<u32>,
    /// Timed samples per pixel per configuration, 3 or more (after one untimed warm-up
    /// sample); each is timed alone and the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(3..))]
    spp: u32,
    /// auto, gpu or cpu. auto and gpu measure the GPU and the CPU side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    #[command(flatten)]
    build: BuildArgs,
    #[command(flatten)]
    out: Outputs,
}

impl BenchRender {
    pub fn run(self) -> Result<()> {
        let size = ImageSize {
            width: self.width,
            height: self.height,
            scale: None,
        };
        let scene = RenderScene::open(&self.scene, &size, &Default::default())?;
        self.out.check::<Report>(&scene.mesh.sources, &[])?;
        let config = Config {
            scene,
            name: self.scene.display().to_string(),
            spp: self.spp,
            device: self.device,
            build: self.build.options(),
            layout: self.build.layout,
        };
        let report = with_bar("samples", |p| run(&config, p))?;
        self.out.finish(&report, &[])
    }
}
