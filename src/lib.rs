//! lancer: a GPU compute ray tracer. The CPU builds an SAH BVH and flattens it into one of
//! several layouts; a WGSL compute kernel traverses it, and the layout's CPU twin — the same
//! algorithm in the same order — is the reference, judged by an f64 oracle.

pub mod accel;
pub mod camera;
pub mod device;
pub mod error;
pub mod geometry;
pub mod gpu;
pub mod layout;
pub mod mesh;
pub mod output;
pub mod render;
pub mod trace;

pub use accel::{Accel, AccelKind, Query, RayStats};
pub use camera::Camera;
pub use device::{Device, DeviceChoice};
pub use error::{Error, Result};
pub use geometry::{Hit, Ray, Robustness};
pub use glam::{Vec2, Vec3};
pub use layout::{Layout, LayoutKind};
pub use mesh::Mesh;
pub use render::{Image, RenderOptions, RenderScene, Rendered, Renderer};
pub use trace::{TraceResult, Tracer, TracerOptions};
