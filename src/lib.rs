//! lancer: a GPU compute ray tracer. The CPU builds an SAH BVH and flattens it into a
//! [`GpuForm`]; a WGSL compute kernel traverses it, and the layout's CPU twin — the same
//! algorithm in the same order — is the reference, judged by an f64 oracle.
//!
//! # Quick start
//!
//! Load a mesh, trace four rays on the CPU and on the GPU (a hardware adapter; without one,
//! or with only a software one such as lavapipe, `DeviceChoice::Auto` runs on the CPU and
//! says why; `DeviceChoice::Gpu` takes any adapter), and render a scene to PNG:
//!
//! ```
//! use std::path::Path;
//! use lancer::render::render;
//! use lancer::{Device, DeviceChoice, Query, Ray, RenderOptions, RenderScene, Vec3};
//! use lancer::{Tracer, TracerOptions};
//!
//! # fn main() -> lancer::Result<()> {
//! let mesh = lancer::mesh::load_mesh(Path::new("scenes/cornell-box.obj"))?;
//! // Four rays from the scene's camera position straight into the box, 1 mm apart.
//! let rays: Vec<Ray> = (0..4)
//!     .map(|i| Ray::new(Vec3::new(270.0 + i as f32, 270.0, 1359.2), Vec3::NEG_Z, 0.0, 1e30))
//!     .collect();
//! for choice in [DeviceChoice::Cpu, DeviceChoice::Auto] {
//!     // Auto uses the CPU without a hardware GPU; `device.fallback()` says why.
//!     let device = Device::open(choice)?;
//!     let mut tracer = Tracer::new(&device, &mesh, &TracerOptions::default())?;
//!     let result = tracer.trace(&rays, Query::Closest)?;
//!     assert!(result.hits.iter().all(|h| h.is_hit() && h.t > 0.0));
//! }
//!
//! let mut scene = RenderScene::from_file(Path::new("scenes/cornell.toml"))?;
//! (scene.camera.width, scene.camera.height) = (32, 32);
//! let device = Device::open(DeviceChoice::Auto)?;
//! let options = RenderOptions { spp: Some(2), ..RenderOptions::default() };
//! let rendered = render(&scene, &device, &options)?;
//! rendered.image.save(&std::env::temp_dir().join("lancer-quick-start.png"))?;
//! # Ok(())
//! # }
//! ```
//!
//! The pieces, bottom of the house first (each uses only those before it): [`geometry`]
//! (rays, boxes, triangle tests, [`Robustness`]), [`mesh`] (OBJ, PLY, glTF), [`camera`],
//! [`accel`] (the [`Accel`] trait, every structure in its own folder, and [`GpuForm`], a
//! structure's GPU face; the BVH's builders and its flattened layouts,
//! [`accel::bvh::layouts`], each with its CPU twin), [`gpu`] (the wgpu plumbing and the WGSL
//! sources), [`trace`] ([`Tracer`], the f64 oracle, ray and hit files), [`render`] (scenes
//! and the [`Renderer`]), [`accuracy`] (the error each robustness setting leaves),
//! [`bench`](mod@bench) (every `lancer bench` as `run(&Config, progress) -> Report`, its tables, charts
//! and results pages).

#![warn(missing_docs)]

pub mod accel;
pub mod accuracy;
pub mod bench;
pub mod camera;
pub mod device;
#[cfg(feature = "embree")]
pub mod embree;
pub mod error;
pub mod geometry;
pub mod gpu;
pub mod input;
pub mod limits;
pub mod mesh;
pub mod output;
pub mod render;
pub mod trace;
pub mod util;

pub use accel::bvh::layouts::LayoutKind;
pub use accel::TraversalMode;
pub use accel::{Accel, AccelKind, GpuForm, Query, RayStats};
pub use camera::Camera;
pub use device::{Device, DeviceChoice};
pub use error::{Error, Result};
pub use geometry::{Hit, Ray, Robustness};
pub use glam::{Vec2, Vec3};
pub use mesh::Mesh;
pub use render::{Image, RenderOptions, RenderScene, Rendered, Renderer};
pub use trace::{TraceResult, Tracer, TracerOptions};
