//! Rendering on top of the tracers: TOML scenes, the effects they call for, the CPU
//! reference renderer and the GPU renderer (one WGSL source specialised per effect set),
//! behind one [`Renderer`].

mod alpha;
mod aov;
mod bsdf;
mod cpu;
mod crop;
mod effects;
mod environment;
mod exr;
mod gpu;
mod image;
mod image_compare;
pub mod kernel;
mod merge;
mod renderer;
pub(crate) mod sampling;
mod scene;
mod stats;
mod texture;
mod trig;

pub use alpha::{blend_threshold, AlphaMask};
pub use aov::{AovSet, Aovs, FirstHit};
pub use bsdf::{Bsdf, BsdfSample, Principled, ALPHA_MIN, DIELECTRIC_F0, LUMINANCE};
pub use crop::{Crop, Tile};
pub use effects::EffectSet;
pub use environment::{
    read_map, EnvMap, EnvSample, Environment, MAP_PDF_SCALE, UNIFORM_SPHERE_PDF,
};
pub use exr::ExrImage;
pub use gpu::{
    GpuLight, GpuMaterial, GpuPlacement, GpuRenderer, GpuShade, RenderParams, MAT_ALPHA_BLEND,
    MAT_ALPHA_MASK, MAT_EMISSION_TEXTURE, MAT_METALLIC_ROUGHNESS, MAT_NORMAL_MAP, MAT_OCCLUSION,
    MAT_TEXTURED, MAT_TWO_SIDED, MAT_UV_TRANSFORMS,
};
pub use image::{heat_ramp, image_kind, save_image, to_rgb16, to_rgb8, Image, ImageKind};
pub use image_compare::{compare_images, load_image, ImageDiff};
pub use merge::merge_tiles;
pub use renderer::{render, Progress, ProgressFn, RenderOptions, Rendered, Renderer, Stop};
pub use sampling::{cosine_direction, offset_origin, pcg, point_error, Rng, POINT_ERROR};
pub use scene::builtin;
pub use scene::{
    load_flattened, load_geometry, load_instances, load_traceable, load_traceable_with_cameras,
    Geometry,
};
pub use scene::{
    ImageSize, Integrator, Light, LightKind, Material, MaterialKind, Motion, PlacedTriangle,
    Placements, RenderScene, SceneFile, Settings, Texture, TextureSlot, DEFAULT_FRAME_RATE,
    TRANSFORM_ERROR,
};
pub use stats::RenderStats;
pub use texture::texture_uv;
pub use trig::{atan2_turns, sin_cos_turns};
