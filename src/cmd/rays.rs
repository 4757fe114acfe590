use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::mesh::FileKind;
use lancer::render::{load_traceable_with_cameras, Geometry};
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
    /// Image height in pixels (default: the scene camera's, or 512 for a mesh; a glTF
    /// camera's aspect ratio sets it from the width's default).
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
        let view = self.view.change();
        let (mut cam, sources, default_view) = match FileKind::of(&self.mesh)? {
            FileKind::Scene => {
                if let Some(c) = &view.camera {
                    return Err(lancer::Error::Usage(format!(
                        "--camera {c} picks a camera of a glTF file; a scene file has one [camera]"
                    )));
                }
                let mut scene = RenderScene::from_file(&self.mesh)?;
                let c = &mut scene.camera;
                (c.width, c.height) = size((c.width, c.height));
                (scene.camera, scene.mesh.sources, false)
            }
            _ => {
                // A glTF file read once: its geometry and its cameras.
                let (geometry, cameras) = load_traceable_with_cameras(&self.mesh)?;
                let picked = lancer::camera::pick_camera(&cameras, view.camera.as_deref())
                    .map_err(|e| lancer::Error::input(&self.mesh, None, e))?;
                let (w, h) = mesh_size;
                // A mesh placed many times: the instances' boxes, without flattening.
                let (bounds, sources) = match geometry {
                    Geometry::Placed(set) => {
                        let sources = set.meshes.iter().flat_map(|m| m.sources.clone());
                        (set.bounds(), sources.collect())
                    }
                    Geometry::Mesh(mesh) => (mesh.bounds(), mesh.sources),
                };
                match picked {
                    // A camera's aspect ratio shapes the image (512 wide), as in `render`.
                    Some(c) => {
                        let (w, h) = c.shaped(512).map_or((w, h), size);
                        (Camera::from_gltf(c, w, h), sources, false)
                    }
                    None => (Camera::default_view(&bounds, w, h), sources, true),
                }
            }
        };
        check_output(&self.out, &sources)?;
        (view.apply(&mut cam, default_view)).map_err(lancer::Error::Usage)?;
        // The rays in memory and their bytes on the way out: 64 bytes a ray.
        lancer::limits::check_image(cam.width, cam.height, 64, "use a smaller --width/--height")?;
        let rays = cam.primary_rays();
        write_output(&self.out, &encode_rays(&rays))?;
        let say = Say::new(is_std(&self.out));
        say!(say, "{} rays written to {}", rays.len(), self.out.display());
        Ok(())
    }
}
