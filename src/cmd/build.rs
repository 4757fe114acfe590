use std::path::PathBuf;

use std::sync::Arc;

use clap::Args;

use lancer::accel::bvh::layouts::{build_and_flatten, bvh_file, BuildReport};
use lancer::accel::bvh::Builder;
use lancer::accel::GpuForm;
use lancer::gpu::GpuContext;
use lancer::trace::{gpu_built, BuildOn};
use lancer::{Device, Error, Result};

use super::out::{print_json, say, Say};
use super::BuildArgs;
use lancer::render::load_flattened;

#[derive(Args)]
pub struct BuildCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Also write the flattened layout to this BVH file (docs/src/reference/file-formats.md), for
    /// `trace`, `check` and `heatmap --bvh`.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print one JSON object instead of text (keys: the book's JSON page, docs/src/reference/json.md).
    #[arg(long)]
    json: bool,
    /// Where the tree is built: cpu, or gpu (the LBVH builder only: the same tree, built by
    /// WGSL kernels on the GPU adapter; flattened there too into dfs-sign, the default
    /// layout here, else read back and flattened on the CPU).
    #[arg(long, value_enum, default_value_t = BuildOn::Cpu)]
    build_on: BuildOn,
}

impl BuildCmd {
    pub fn run(self) -> Result<()> {
        let opts = self.build.options();
        if self.build_on == BuildOn::Gpu && opts.builder != Builder::Lbvh {
            return Err(Error::Usage(format!(
                "--build-on gpu builds with --builder lbvh only, not {}",
                opts.builder.name()
            )));
        }
        // A scene that places a mesh many times is built flattened (a BVH file holds one
        // level), as every command flattens it; the report counts its instances.
        let (mesh, instances) = load_flattened(&self.mesh)?;
        if let Some(out) = &self.out {
            lancer::output::check_output(out, &mesh.sources)?;
        }
        // No device here: a BVH file is for a GPU kernel (or a twin), so the GPU's default.
        let kind = (self.build.layout).unwrap_or(lancer::trace::defaults::GPU_LAYOUT);
        let (layout, mut report) = match self.build_on {
            BuildOn::Cpu => {
                let (layout, report) = build_and_flatten(&mesh, &opts, kind)?;
                (Arc::<dyn GpuForm>::from(layout), report)
            }
            BuildOn::Gpu => {
                let device = Device::gpu(GpuContext::new()?);
                let Some(built) = gpu_built(&device, &mesh, &opts, kind, true)? else {
                    return Err(Error::Gpu("no GPU device to build on".into()));
                };
                // Asked for, the tree is always there.
                let Some(tree) = &built.tree else {
                    return Err(Error::Gpu("the GPU build returned no tree".into()));
                };
                let mut report = BuildReport::new(tree, built.layout.as_ref(), &opts, built.ms);
                report.built_on = device.gpu_context().map(|c| c.adapter.to_string());
                (built.layout, report)
            }
        };
        if let Some(out) = &self.out {
            bvh_file::write(out, layout.as_ref(), mesh.len())?;
            report.out = Some(out.display().to_string());
        }
        if let Some(set) = &instances {
            report.instances = Some(set.instances.len());
            report.instanced_triangles = Some(set.triangle_count());
        }
        report.peak_memory_bytes = lancer::bench::memory::peak_resident();
        if self.json {
            print_json(&report)?;
        } else {
            let say = Say::new(false);
            report.text().iter().for_each(|l| say!(say, "{l}"));
        }
        Ok(())
    }
}
