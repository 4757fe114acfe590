//! Geometric primitives shared by the builders, the CPU tracers and (by layout) the GPU:
//! boxes, rays, hits, triangle tests, the robustness settings and the affine maps that place
//! instances.

mod aabb;
mod affine;
mod clip;
mod hit;
mod octahedral;
mod ray;
mod robustness;
mod slab4;
mod triangle;
mod triangle4;
mod triangle_f64;
mod vector;

pub use aabb::{Aabb, FAR_WIDEN, PARALLEL_INV};
pub use affine::Affine;
pub(crate) use clip::{chopped_bounds, clip_bounds, clipped_area, covered};
pub use hit::{Hit, MISS};
pub use octahedral::{
    pack_tangent, pack_unit, unpack_tangent, unpack_unit, NO_NORMAL, NO_TANGENT, SNORM15_SCALE,
    SNORM16_SCALE, TANGENT_FLIPPED, TANGENT_PRESENT,
};
pub use ray::{safe_recip, Ray, RECIP_FLOOR};
pub use robustness::{
    prune_bound, Precision, RayOffset, Robustness, SlabTest, FIXED_OFFSET, TIE_SLACK,
};
pub use slab4::SlabRay4;
pub(crate) use triangle::gamma;
pub use triangle::{
    grazing_in_front, intersect_moller_trumbore, intersect_triangle, intersect_triangle_bounded,
    intersect_watertight, intersect_watertight_bounded, t_error_bound, TriHit, Triangle,
    TriangleTest, WatertightRay, NEAR_HIT_PLANE_REL,
};
pub use triangle4::{TriHits4, TriangleRay4, Watertight4};
pub use triangle_f64::{d3, intersect_f64, triangle_hit_f64};
pub use vector::{cross, dot, normalize};
