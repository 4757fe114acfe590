//! Tracing: one [`Tracer`] for the CPU and the GPU, the f64 oracle that judges both, and
//! the ray and hit file formats.

pub mod build_on;
pub mod check;
pub mod compare;
pub mod defaults;
pub mod files;
pub mod oracle;
pub mod stats;
mod tracer;

pub use build_on::{gpu_built, BuildOn, GpuBuilt};
pub use defaults::default_layout;
pub use tracer::{TraceResult, Tracer, TracerOptions};
