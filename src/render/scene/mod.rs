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

/// The flattened mesh of a file ([`load_geometry`]'s) and, where the file places a mesh
/// more than once, the instances that place it ([`load_traceable`]'s set, for counting):
/// each file read as few times as that allows, its left-out triangles counted once, in the
/// flattened mesh the BVH is built over.
pub fn load_flattened(
    path: &std::path::Path,
) -> crate::Result<(crate::mesh::Mesh, Option<crate::mesh::InstanceSet>)> {
    use crate::mesh::{FileKind, GltfLoaded};
    Ok(match FileKind::of(path)? {
        FileKind::Scene => {
            let scene = RenderScene::from_file(path)?;
            let set = (scene.placements.as_ref()).map(|p| p.set().clone());
            (scene.flattened()?.mesh, set)
        }
        FileKind::Gltf => match crate::mesh::read_gltf(path)? {
            GltfLoaded::Placed(p) if p.shares_meshes => {
                let set = (p.instance_set())
                    .map_err(|e| crate::Error::input(path, None, e.to_string()))?;
                // Flattened as load_geometry flattens it (in world space, where a node's
                // map may leave out more than the meshes do).
                (crate::mesh::load_mesh(path)?, Some(set))
            }
            GltfLoaded::Flat(g) => {
                crate::mesh::check_usable(path, &g.mesh)?;
                (g.mesh, None)
            }
            GltfLoaded::Placed(_) => (load_geometry(path)?, None),
        },
        _ => (crate::mesh::load_mesh(path)?, None),
    })
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
    Ok(load_traceable_with_cameras(path)?.0)
}

/// [`load_traceable`], with a glTF file's cameras (none for other files). What the file
/// leaves out is counted in one warning, and a file with no usable triangle refused.
pub fn load_traceable_with_cameras(
    path: &std::path::Path,
) -> crate::Result<(Geometry, Vec<crate::mesh::GltfCamera>)> {
    use crate::mesh::{FileKind, GltfLoaded};
    // A glTF's flattened mesh is checked as `load_mesh` checks one.
    let usable = |mesh: crate::mesh::Mesh| -> crate::Result<Geometry> {
        crate::mesh::check_usable(path, &mesh)?;
        Ok(Geometry::Mesh(mesh))
    };
    Ok(match FileKind::of(path)? {
        FileKind::Gltf => match crate::mesh::read_gltf(path)? {
            GltfLoaded::Flat(g) => (usable(g.mesh)?, g.cameras),
            // Placed only for its animation: traced still, flattened as before.
            GltfLoaded::Placed(p) if !p.shares_meshes => {
                let g = crate::mesh::load_gltf(path)?;
                (usable(g.mesh)?, g.cameras)
            }
            GltfLoaded::Placed(p) => {
                let set = (p.instance_set())
                    .map_err(|e| crate::Error::input(path, None, e.to_string()))?;
                set.check_usable(path)?;
                (Geometry::Placed(set), p.cameras)
            }
        },
        FileKind::Scene => {
            let scene = RenderScene::from_file(path)?;
            let geometry = match scene.placements {
                Some(p) => Geometry::Placed(p.set().clone()),
                None => Geometry::Mesh(scene.mesh),
            };
            (geometry, Vec::new())
        }
        _ => (Geometry::Mesh(crate::mesh::load_mesh(path)?), Vec::new()),
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
