//! Scenes: the TOML file format, its assembly into one mesh with materials, textures and
//! lights, and the built-in shapes.

mod assemble;
pub mod builtin;
mod file;
mod imported;
mod open;
mod placements;
mod shapes;

pub use assemble::{Light, Material, RenderScene, Settings, Texture};
pub use file::{Integrator, LightKind, MaterialKind, SceneFile};
pub use open::ImageSize;
pub use placements::{PlacedTriangle, Placements, TRANSFORM_ERROR};

/// The mesh of a mesh file (.obj, .ply, .gltf, .glb) or of a scene (.toml: all its objects
/// in one mesh, copies flattened), chosen by the extension; an unknown extension is
/// refused by name.
pub fn load_geometry(path: &std::path::Path) -> crate::Result<crate::mesh::Mesh> {
    match crate::mesh::FileKind::of(path)? {
        crate::mesh::FileKind::Scene => Ok(RenderScene::from_file(path)?.flattened()?.mesh),
        _ => crate::mesh::load_mesh(path),
    }
}

/// The geometry of a file as meshes placed by instances, where the file places a mesh more
/// than once (a glTF mesh drawn by several nodes: [`load_gltf_instances`]; a scene object
/// with `copies` or a `grid`: [`RenderScene::instances_of_file`]); None where it does not
/// (then [`load_geometry`]'s one mesh is no bigger), and for OBJ and PLY.
///
/// [`load_gltf_instances`]: crate::mesh::load_gltf_instances
pub fn load_instances(path: &std::path::Path) -> crate::Result<Option<crate::mesh::InstanceSet>> {
    match crate::mesh::FileKind::of(path)? {
        crate::mesh::FileKind::Gltf => crate::mesh::load_gltf_instances(path),
        crate::mesh::FileKind::Scene => RenderScene::instances_of_file(path),
        _ => Ok(None),
    }
}
