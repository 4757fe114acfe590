//! The geometry a command traces: a mesh file, or a scene's assembled mesh.

use std::path::Path;

use lancer::accel::bvh::layouts::bvh_file::BvhFile;
use lancer::mesh::{load_mesh, Mesh};
use lancer::{RenderScene, Result};

/// The mesh of a mesh file (.obj, .ply, .gltf, .glb) or of a scene (.toml, all its objects
/// in one mesh); an unknown extension is refused by name.
pub fn load_geometry(path: &Path) -> Result<Mesh> {
    match lancer::mesh::FileKind::of(path)? {
        lancer::mesh::FileKind::Scene => Ok(RenderScene::from_file(path)?.mesh),
        _ => load_mesh(path),
    }
}

/// The BVH file `path` (`--bvh`), refused unless it was built from `mesh`.
pub fn load_bvh(path: &Path, mesh: &Mesh) -> Result<BvhFile> {
    let file = lancer::accel::bvh::layouts::bvh_file::read(path)?;
    file.check_mesh(path, mesh)?;
    log::info!("{}: a {} BVH", path.display(), file.kind);
    Ok(file)
}
