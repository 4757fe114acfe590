//! The GPU side: a headless wgpu device, the WGSL kernels, and BVH traversal on the GPU.

mod bvh_memory;
mod context;
pub mod shaders;
mod trace;

pub use bvh_memory::{BvhMemory, GpuBvh, TEXEL_ROW};
pub use context::{AdapterReport, GpuContext};
pub(crate) use trace::storage_entry;
pub use trace::{GpuTimings, GpuTracer, Params, TraceKernel};
