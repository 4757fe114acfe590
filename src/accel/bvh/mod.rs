//! Bounding volume hierarchy: build (sweep SAH, binned SAH, median), flatten to the GPU
//! layout, and statistics.

mod binned;
mod build;
mod flatten;
mod median;
mod stats;
mod sweep;

pub use binned::MAX_BINS;
pub use build::{build, BuildOptions, Builder, Bvh, Node, MAX_DEPTH};
pub use flatten::{FlatBvh, GpuNode, GpuTri, LEAF_TAG};
pub use stats::BvhStats;
