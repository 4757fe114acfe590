//! Scenes: the TOML file format, its assembly into one mesh with materials, textures and
//! lights, and the built-in shapes.

mod assemble;
pub mod builtin;
mod environment;
mod file;
mod imported;
mod open;
mod placements;
mod shapes;
mod tangents;

pub use assemble::{Light, Material, RenderScene, Settings, Texture, TextureSlot};
pub use file::{Integrator, LightKind, MaterialKind, SceneFile};
pub use open::ImageSize;
pub use placements::{Motion, PlacedTriangle, Placements, DEFAULT_FRAME_RATE, TRANSFORM_ERROR};

/// The mesh of a mesh file (.obj, .ply, .gltf, .glb) or of a scene (.toml: all its objects
/// in one mesh, copies flattened), chosen by the extension; an unknown extension is
/// refused by name.
pub fn load_geometry(path: &std::path::Path) -> crate::Result<crate::mesh::Mesh> {
    match crate::mesh::FileKind::of(path)? {
        crate::mesh::FileKind::Scene => Ok(RenderScene::from_file(path)?.flattened()?.mesh),
        _ => crate::mesh::load_mesh(path),
    }
}

/// A file's geometry as `trace` takes it, the file read once: one mesh, or meshes placed by
/// instances where the file places a mesh more than once.
#[derive(Clone, Debug)]
pub enum Geometry {
    /// The file's mesh ([`load_geometry`]'s).
    Mesh(crate::mesh::Mesh),
    /// A glTF mesh drawn by several nodes ([`load_gltf_placed`]; a file placed only for its
    /// animation is taken flattened), or a scene object with `copies` or a `grid`
    /// ([`RenderScene::placements`]).
    ///
    /// [`load_gltf_placed`]: crate::mesh::load_gltf_placed
    Placed(crate::mesh::InstanceSet),
}

/// Reads a file's [`Geometry`]: a mesh file (.obj, .ply, .gltf, .glb) or a scene (.toml),
/// chosen by the extension.
pub fn load_traceable(path: &std::path::Path) -> crate::Result<Geometry> {
    use crate::mesh::{FileKind, GltfLoaded};
    Ok(match FileKind::of(path)? {
        FileKind::Gltf => match crate::mesh::read_gltf(path)? {
            GltfLoaded::Flat(g) => Geometry::Mesh(g.mesh),
            // Placed only for its animation: traced still, flattened as before.
            GltfLoaded::Placed(p) if !p.shares_meshes => {
                Geometry::Mesh(crate::mesh::load_gltf(path)?.mesh)
            }
            GltfLoaded::Placed(p) => Geometry::Placed(
                (p.instance_set()).map_err(|e| crate::Error::input(path, None, e.to_string()))?,
            ),
        },
        FileKind::Scene => {
            let scene = RenderScene::from_file(path)?;
            match scene.placements {
                Some(p) => Geometry::Placed(p.set().clone()),
                None => Geometry::Mesh(scene.mesh),
            }
        }
        _ => Geometry::Mesh(crate::mesh::load_mesh(path)?),
    })
}

/// The geometry of a file as meshes placed by instances, where the file places a mesh more
/// than once ([`Geometry::Placed`]); None where it does not (then [`load_geometry`]'s one
/// mesh is no bigger).
pub fn load_instances(path: &std::path::Path) -> crate::Result<Option<crate::mesh::InstanceSet>> {
    Ok(match load_traceable(path)? {
        Geometry::Placed(set) => Some(set),
        Geometry::Mesh(_) => None,
    })
}
