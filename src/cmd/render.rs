use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bvh::{build, FlatBvh};
use lancer::geometry::TriangleTest;
use lancer::gpu::{GpuTracer, TraceKernel};
use lancer::render::{preview, PreviewOptions};
use lancer::scene::{load_mesh, Camera};
use lancer::trace::rays::default_light;
use lancer::trace::trace_batch;
use lancer::{Error, Result};

use super::trace::{open_device, Device};
use super::BuildArgs;

#[derive(Args)]
pub struct RenderCmd {
    /// OBJ mesh, seen from its default view and lit by one point light.
    mesh: PathBuf,
    /// Output PNG.
    #[arg(short, long)]
    out: PathBuf,
    #[arg(long, default_value_t = 640)]
    width: u32,
    #[arg(long, default_value_t = 480)]
    height: u32,
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    device: Device,
    /// Print the device, BVH and timing.
    #[arg(long)]
    stats: bool,
    #[command(flatten)]
    build: BuildArgs,
}

impl RenderCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let t0 = Instant::now();
        let flat = FlatBvh::new(&build(&mesh, &self.build.options()), &mesh);
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        let cam = Camera::default_view(&mesh.bounds(), self.width.max(1), self.height.max(1));
        let opts = PreviewOptions {
            light: default_light(&mesh.bounds()),
            ambient: 0.1,
            albedo: glam::Vec3::splat(0.8),
            background: glam::Vec3::new(0.05, 0.06, 0.09),
        };
        let ctx = open_device(self.device)?;
        let bar = ProgressBar::new(2);
        bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} passes {msg}").unwrap());
        let t1 = Instant::now();
        let img = match &ctx {
            Some(ctx) => {
                let mut tracer = GpuTracer::new(ctx, &flat)?;
                preview(&mesh, &cam, &opts, |rays, query| {
                    bar.set_message(format!("{} rays on the GPU", rays.len()));
                    let r = tracer.trace(
                        rays,
                        TraceKernel {
                            query,
                            ..TraceKernel::default()
                        },
                    );
                    bar.inc(1);
                    r.map(|(h, _, _)| h)
                })?
            }
            None => preview(&mesh, &cam, &opts, |rays, query| {
                bar.set_message(format!("{} rays on the CPU", rays.len()));
                let h = trace_batch(&flat, rays, query, TriangleTest::Watertight).0;
                bar.inc(1);
                Ok(h)
            })?,
        };
        bar.finish_and_clear();
        let ms = t1.elapsed().as_secs_f64() * 1e3;
        img.save(&self.out)
            .map_err(|e| Error::input(&self.out, None, format!("cannot write image: {e}")))?;
        let device = ctx
            .as_ref()
            .map_or("cpu".to_string(), |c| format!("gpu: {}", c.adapter));
        println!(
            "{}x{} -> {} ({device}, {ms:.0} ms)",
            self.width,
            self.height,
            self.out.display()
        );
        if self.stats {
            println!(
                "triangles {}  nodes {}  build {build_ms:.1} ms",
                flat.tris.len(),
                flat.nodes.len()
            );
        }
        Ok(())
    }
}
