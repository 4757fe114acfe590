//! Two-level acceleration: meshes built once each (the bottom level, any structure) and
//! placed many times by instances, under a top-level BVH over the instances' world boxes.
//!
//! Memory grows with the unique geometry: a mesh placed 1,000 times is stored and built
//! once. Triangles are numbered as the flattened scene numbers them ([`InstanceSet::flatten`]):
//! instances in order, each mesh's triangles in file order within them, so hits of the two
//! are comparable; the tie rule (equal t → smaller index) holds across instances.
//!
//! Rays are moved into each instance's object space by its inverse map in f32
//! ([`Affine::ray`]); the direction is not renormalised, so hit distances t compare across
//! instances. The world boxes are padded for the rounding of that move
//! ([`Affine::bound_box`]). The CPU traversal here ([`TwoLevel`]) is the reference a GPU
//! traversal of the top level is to match.

mod gpu;
mod interleaved;
mod top_level;
mod two_level;

pub use crate::geometry::Affine;
pub use crate::mesh::{Instance, InstanceSet, MAX_INSTANCED_TRIANGLES};
pub use gpu::{GpuTwoLevel, MeshWords};
pub use two_level::TwoLevel;
