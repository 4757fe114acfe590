//! Scenes: the TOML file format, its assembly into one mesh with materials, textures and
//! lights, and the built-in shapes.

mod assemble;
pub mod builtin;
mod file;
mod imported;
mod open;
mod shapes;

pub use assemble::{Light, Material, RenderScene, Settings, Texture};
pub use file::{Integrator, LightKind, MaterialKind, SceneFile};
pub use open::ImageSize;

/// The mesh of a mesh file (.obj, .ply, .gltf, .glb) or of a scene (.toml: all its objects
/// in one mesh), chosen by the extension; an unknown extension is refused by name.
pub fn load_geometry(path: &std::path::Path) -> crate::Result<crate::mesh::Mesh> {
    match crate::mesh::FileKind::of(path)? {
        crate::mesh::FileKind::Scene => Ok(RenderScene::from_file(path)?.mesh),
        _ => crate::mesh::load_mesh(path),
    }
}
