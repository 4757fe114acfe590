use std::path::PathBuf;

use clap::Args;
use lancer::accel::bvh::layouts::{build_and_flatten, bvh_file};
use lancer::Result;

use super::out::{print_json, say, Say};
use super::BuildArgs;
use lancer::render::{load_geometry, load_traceable, Geometry};

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
}

impl BuildCmd {
    pub fn run(self) -> Result<()> {
        // A scene that places a mesh many times is built flattened (a BVH file holds one
        // level); the report counts its instances.
        // The flattened mesh as every command flattens it (a placed file is read again).
        let (mesh, instances) = match load_traceable(&self.mesh)? {
            Geometry::Mesh(mesh) => (mesh, None),
            Geometry::Placed(set) => (load_geometry(&self.mesh)?, Some(set)),
        };
        if let Some(out) = &self.out {
            lancer::output::check_output(out, &mesh.sources)?;
        }
        // No device here: a BVH file is for a GPU kernel (or a twin), so the GPU's default.
        let kind = (self.build.layout).unwrap_or(lancer::trace::defaults::GPU_LAYOUT);
        let (layout, mut report) = build_and_flatten(&mesh, &self.build.options(), kind)?;
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
