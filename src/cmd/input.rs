//! The geometry a command traces: a mesh file, or a scene's assembled mesh.

use std::path::Path;

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
