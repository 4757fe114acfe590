//! lancer: a GPU compute ray tracer. The CPU builds an SAH BVH and flattens it into a
//! depth-first node array; a WGSL compute kernel traverses it, and a CPU tracer running
//! the same algorithm is the reference.

pub mod accel;
pub mod error;
pub mod geometry;
pub mod gpu;
pub mod render;
pub mod scene;
pub mod trace;

pub use error::{Error, Result};
