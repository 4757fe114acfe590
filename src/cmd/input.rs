//! A BVH file a command traces (`--bvh`), checked against the mesh it was built from.

use std::path::Path;

use lancer::accel::bvh::layouts::bvh_file::BvhFile;
use lancer::mesh::Mesh;
use lancer::Result;

/// The BVH file `path` (`--bvh`), refused unless it was built from `mesh`.
pub fn load_bvh(path: &Path, mesh: &Mesh) -> Result<BvhFile> {
    let file = lancer::accel::bvh::layouts::bvh_file::read(path)?;
    file.check_mesh(path, mesh)?;
    log::info!("{}: a {} BVH", path.display(), file.kind);
    Ok(file)
}
