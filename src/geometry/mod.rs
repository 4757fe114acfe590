//! Geometric primitives shared by the builders, the CPU tracer and (by layout) the GPU.

mod aabb;
mod hit;
mod ray;
mod triangle;

pub use aabb::{Aabb, FAR_WIDEN, PARALLEL_INV};
pub use hit::{Hit, MISS};
pub use ray::{safe_recip, Ray};
pub use triangle::{
    intersect_moller_trumbore, intersect_watertight, Triangle, TriangleTest, WatertightRay,
};
