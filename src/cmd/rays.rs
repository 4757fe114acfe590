use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::mesh::load_mesh;
use lancer::trace::files::encode_rays;
use lancer::Result;

use super::out::{check_output, is_std, say, write_output, Say};

#[derive(Args)]
pub struct RaysCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) whose default view is used.
    mesh: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// Output ray file (32 bytes a ray), or - for stdout (text then goes to stderr).
    #[arg(short, long)]
    out: PathBuf,
}

impl RaysCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        check_output(&self.out, &mesh.sources)?;
        // The rays in memory and their bytes on the way out: 64 bytes a ray.
        lancer::limits::check_image(
            self.width,
            self.height,
            64,
            "use a smaller --width/--height",
        )?;
        let cam = Camera::default_view(&mesh.bounds(), self.width, self.height);
        let rays = cam.primary_rays();
        write_output(&self.out, &encode_rays(&rays))?;
        let say = Say::new(is_std(&self.out));
        say!(say, "{} rays written to {}", rays.len(), self.out.display());
        Ok(())
    }
}
