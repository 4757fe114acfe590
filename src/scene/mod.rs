//! Scene input: meshes from OBJ files and the default view.

mod camera;
mod load;
mod mesh;
mod obj;

pub use camera::{Camera, PRIMARY_TMAX};
pub use load::{check_usable, load_mesh};
pub(crate) use mesh::classify;
pub use mesh::{Mesh, TriStatus};
pub use obj::{load_obj, load_obj_scene, ObjScene};
