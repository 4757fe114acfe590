//! Rendering on top of the tracers: TOML scenes, the effects they call for, the CPU
//! reference renderer and the GPU renderer (one WGSL source specialised per effect set).

mod effects;
mod gpu;
mod image_out;
mod integrator;
mod sampling;
mod scene;
mod scene_file;
mod shapes;

pub use effects::EffectSet;
pub use gpu::{GpuLight, GpuMaterial, GpuRenderer, GpuShade, RenderParams};
pub use image_out::{image_kind, save_image, to_rgb8, ImageKind};
pub use integrator::{sample_texture, CameraFrame, CpuRenderer};
pub use sampling::{offset_origin, pcg, Rng};
pub use scene::{Light, Material, RenderScene, Settings, Texture};
pub use scene_file::{Integrator, MaterialKind, SceneFile};
