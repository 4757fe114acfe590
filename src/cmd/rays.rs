use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::mesh::FileKind;
use lancer::render::{load_traceable, Geometry};
use lancer::trace::files::encode_rays;
use lancer::{RenderScene, Result};

use super::out::{check_output, is_std, say, write_output, Say};
use super::ViewArgs;

#[derive(Args)]
pub struct RaysCmd {
    /// A scene (.toml: its camera) or a mesh (.obj, .ply, .gltf, .glb: its default view).
    mesh: PathBuf,
    /// Image width in pixels (default: the scene camera's, or 512 for a mesh).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    width: Option<u32>,
    /// Image height in pixels (default: the scene camera's, or 512 for a mesh).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    height: Option<u32>,
    #[command(flatten)]
    view: ViewArgs,
    /// Output ray file (32 bytes a ray), or - for stdout (text then goes to stderr).
    #[arg(short, long)]
    out: PathBuf,
}

impl RaysCmd {
    pub fn run(self) -> Result<()> {
        // A scene's own camera; a mesh's default view, fitted to the image size.
        let size = |own: (u32, u32)| (self.width.unwrap_or(own.0), self.height.unwrap_or(own.1));
        let mesh_size = size((512, 512));
        let (mut cam, sources) = match FileKind::of(&self.mesh)? {
            FileKind::Scene => {
                let mut scene = RenderScene::from_file(&self.mesh)?;
                let c = &mut scene.camera;
                (c.width, c.height) = size((c.width, c.height));
                (scene.camera, scene.mesh.sources)
            }
            _ => match load_traceable(&self.mesh)? {
                // A mesh placed many times: the instances' boxes, without flattening.
                Geometry::Placed(set) => {
                    let sources = set.meshes.iter().flat_map(|m| m.sources.clone());
                    let (w, h) = mesh_size;
                    (Camera::default_view(&set.bounds(), w, h), sources.collect())
                }
                Geometry::Mesh(mesh) => {
                    let (w, h) = mesh_size;
                    (Camera::default_view(&mesh.bounds(), w, h), mesh.sources)
                }
            },
        };
        check_output(&self.out, &sources)?;
        let mesh = FileKind::of(&self.mesh)? != FileKind::Scene;
        (self.view.change().apply(&mut cam, mesh)).map_err(lancer::Error::Usage)?;
        // The rays in memory and their bytes on the way out: 64 bytes a ray.
        lancer::limits::check_image(cam.width, cam.height, 64, "use a smaller --width/--height")?;
        let rays = cam.primary_rays();
        write_output(&self.out, &encode_rays(&rays))?;
        let say = Say::new(is_std(&self.out));
        say!(say, "{} rays written to {}", rays.len(), self.out.display());
        Ok(())
    }
}
