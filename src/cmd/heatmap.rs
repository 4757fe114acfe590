use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::render::heat_ramp;
use lancer::{Error, Query, Result, Tracer, TracerOptions};

use super::input::load_geometry;
use super::{AccelArg, BuildArgs, DeviceArgs};

#[derive(Args)]
pub struct HeatmapCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Output PNG.
    #[arg(short, long)]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    device: DeviceArgs,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure (all but the BVH, the kd-tree and the BIH run on the CPU); the map
    /// counts its nodes or cells visited.
    #[arg(long, value_enum, default_value_t = AccelArg::Bvh)]
    accel: AccelArg,
    /// Map the BVH in this file (`build --out`) instead of building one (--accel, --layout
    /// and the builder options are refused with it); MESH must be the one it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = super::BVH_CONFLICTS)]
    bvh: Option<PathBuf>,
}

impl HeatmapCmd {
    pub fn run(self) -> Result<()> {
        if !self
            .out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            return Err(Error::input(
                &self.out,
                None,
                "a heatmap is a PNG: use a .png file name",
            ));
        }
        let mesh = load_geometry(&self.mesh)?;
        lancer::output::check_output(
            &self.out,
            &[&mesh.sources[..], self.bvh.as_slice()].concat(),
        )?;
        let (w, h) = (self.width, self.height);
        // Rays, hits, statistics and the image: about 80 bytes a pixel.
        lancer::limits::check_image(w, h, 80, "use a smaller --width/--height")?;
        let rays = Camera::default_view(&mesh.bounds(), w, h).primary_rays();
        let device = self.accel.open(&self.device)?;
        let options = TracerOptions {
            build: self.build.options(),
            layout: self.build.layout,
            memory: self.device.bvh_memory,
            stats: true,
            ..TracerOptions::default()
        };
        let kind = self.accel.kind(self.build.layout);
        let mut tracer = match &self.bvh {
            Some(path) => {
                let file = super::input::load_bvh(path, &mesh)?;
                Tracer::with_layout(&device, file.layout, &options)?
            }
            None => Tracer::with_structure(&device, &mesh, kind, &options)?,
        };
        let stats = tracer
            .trace(&rays, Query::Closest)?
            .stats
            .unwrap_or_default();
        let max = stats.iter().map(|s| s.nodes).max().unwrap_or(1).max(1);
        let mean = stats.iter().map(|s| s.nodes as f64).sum::<f64>() / stats.len() as f64;
        let mut img = image::RgbImage::new(w, h);
        for (p, s) in img.pixels_mut().zip(&stats) {
            *p = image::Rgb(heat_ramp(s.nodes as f32 / max as f32));
        }
        lancer::output::write_atomic(&self.out, |w| {
            img.write_to(w, image::ImageFormat::Png)
                .map_err(std::io::Error::other)
        })?;
        println!(
            "nodes visited per pixel: mean {mean:.1}, max {max} (white-yellow) -> {}",
            self.out.display()
        );
        Ok(())
    }
}
