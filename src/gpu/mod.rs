//! The GPU side: a headless wgpu device, the shared plumbing, the WGSL sources and the
//! trace kernel.

mod adapters;
pub mod bindings;
mod buffer_parts;
mod bvh_memory;
mod context;
mod driver;
pub mod exact_spirv;
#[cfg(not(any(target_vendor = "apple", target_arch = "wasm32")))]
mod host_import;
#[cfg(any(target_vendor = "apple", target_arch = "wasm32"))]
#[path = "host_import_none.rs"]
mod host_import;
mod lbvh_build;
mod parted_array;
pub mod plumbing;
pub mod shaders;
mod trace;
pub(crate) mod word_array;

pub use adapters::{adapters, AdapterSummary};
pub use buffer_parts::BufferParts;
pub use bvh_memory::{BvhMemory, GpuBvh, TEXEL_ROW};
pub use context::{AdapterReport, GpuContext, SubgroupSizes};
pub use driver::DriverTracer;
pub use lbvh_build::{build_lbvh, lbvh_dfs_sign, lbvh_radix_tree, lbvh_source};
pub use trace::{GpuTracer, Timings, TraceKernel, TraceParams, INCOMPLETE};
/// The wgpu crate lancer is built on: create the device you hand to
/// [`GpuContext::from_wgpu`] with it (or with the same major version, wgpu 30).
pub use wgpu;
pub(crate) use word_array::WordArray;
