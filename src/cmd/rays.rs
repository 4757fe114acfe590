use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::mesh::load_mesh;
use lancer::trace::files::write_rays;
use lancer::Result;

#[derive(Args)]
pub struct RaysCmd {
    /// OBJ mesh whose default view is used.
    mesh: PathBuf,
    #[arg(long, default_value_t = 512)]
    width: u32,
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Output ray file.
    #[arg(short, long)]
    out: PathBuf,
}

impl RaysCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let cam = Camera::default_view(&mesh.bounds(), self.width.max(1), self.height.max(1));
        let rays = cam.primary_rays();
        write_rays(&self.out, &rays)?;
        println!("{} rays written to {}", rays.len(), self.out.display());
        Ok(())
    }
}
