//! Scenes: the TOML file format, its assembly into one mesh with materials, textures and
//! lights, and the built-in shapes.

mod assemble;
pub mod builtin;
mod file;
mod imported;
mod shapes;

pub use assemble::{Light, Material, RenderScene, Settings, Texture};
pub use file::{Integrator, LightKind, MaterialKind, SceneFile};
