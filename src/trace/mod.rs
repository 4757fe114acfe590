//! Tracing: the CPU reference, the f64 oracle, and the ray/hit file formats.

pub mod cpu;
pub mod oracle;
pub mod rays;

pub use cpu::{trace_batch, trace_ray, Query, RayStats};
