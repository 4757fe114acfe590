//! The TOML scene format (documented in docs/src/reference/scene-format.md). Parsing only: `scene.rs` turns a
//! `SceneFile` into something the renderers can use. Unknown keys and bad values are
//! refused with `FILE:LINE: message`.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::error::{Error, Result};

/// The light transport algorithm (`[render] integrator`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Direct light (point, directional and area lights) plus mirror/glass chains.
    Direct,
    /// Path tracing: direct light at every diffuse bounce, up to max_bounces bounces.
    #[default]
    Path,
    /// Ambient occlusion: the fraction of a cosine lobe unoccluded within ao_distance.
    Ao,
}

/// A parsed scene file, before its meshes, textures and names are resolved.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `[camera]` (required).
    pub camera: CameraDef,
    /// `[render]`: integrator and sampling; defaults when absent.
    #[serde(default)]
    pub render: RenderDef,
    /// `[materials.NAME]`: named materials, with their source spans for error lines.
    #[serde(default)]
    pub materials: BTreeMap<String, Spanned<MaterialDef>>,
    /// `[[objects]]`: meshes and shapes in file order, with their source spans.
    #[serde(default)]
    pub objects: Vec<Spanned<ObjectDef>>,
    /// `[[lights]]`: point and directional lights, with their source spans.
    #[serde(default)]
    pub lights: Vec<Spanned<LightDef>>,
    /// `[environment]`: light from infinitely far away (default: none, or `[render]
    /// background`).
    pub environment: Option<Spanned<EnvironmentDef>>,
}

/// `[environment]`: uniform `radiance`, or an equirectangular `map` times `scale`, turned
/// by `rotate`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDef {
    /// The same radiance from every direction, linear RGB.
    pub radiance: Option<[f32; 3]>,
    /// An OpenEXR or Radiance HDR file, relative to the scene file (Mitsuba 3's `envmap`
    /// placement).
    pub map: Option<String>,
    /// What the map's texels are multiplied by.
    pub scale: Option<f32>,
    /// Rotation of the map in degrees about X, then Y, then Z.
    #[serde(default)]
    pub rotate: [f32; 3],
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDef {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "up")]
    pub up: [f32; 3],
    /// Vertical field of view, degrees.
    #[serde(default = "fov")]
    pub fov: f32,
    #[serde(default = "width")]
    pub width: u32,
    #[serde(default = "height")]
    pub height: u32,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDef {
    #[serde(default)]
    pub integrator: Integrator,
    #[serde(default = "max_bounces")]
    pub max_bounces: u32,
    #[serde(default = "spp")]
    pub spp: u32,
    #[serde(default)]
    pub seed: u32,
    /// Shorthand for `[environment] radiance`.
    #[serde(default)]
    pub background: [f32; 3],
    /// AO ray length; default: a tenth of the scene's bounding-box diagonal.
    pub ao_distance: Option<f32>,
}

impl Default for RenderDef {
    fn default() -> Self {
        RenderDef {
            integrator: Integrator::default(),
            max_bounces: max_bounces(),
            spp: spp(),
            seed: 0,
            background: [0.0; 3],
            ao_distance: None,
        }
    }
}

/// How a material scatters or emits light (a material's `type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaterialKind {
    /// Lambertian reflection of `albedo` (or of a texture).
    Diffuse,
    /// Perfect specular reflection, tinted by `albedo`.
    Mirror,
    /// Smooth dielectric of index `ior`: Fresnel-weighted reflection or refraction,
    /// tinted by `albedo`.
    Glass,
    /// Emits `emission` and reflects nothing; its triangles are area lights.
    Emissive,
    /// glTF 2.0's metallic-roughness: a GGX specular lobe over a Lambert base, mixed by
    /// `metallic` (render::bsdf).
    Principled,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDef {
    #[serde(rename = "type")]
    pub kind: MaterialKind,
    /// Linear RGB reflectance (diffuse, mirror) or transmittance tint (glass).
    pub albedo: Option<[f32; 3]>,
    /// Principled: linear RGB base colour (multiplies `texture`).
    pub base_color: Option<[f32; 3]>,
    /// Principled: metalness in [0, 1] (multiplies the blue channel of
    /// `metallic_roughness_texture`).
    pub metallic: Option<f32>,
    /// Principled: perceptual roughness in [0, 1], α = roughness² (multiplies the green
    /// channel of `metallic_roughness_texture`).
    pub roughness: Option<f32>,
    /// Image file (PNG, JPEG…), relative to the scene file: a diffuse material's albedo,
    /// a principled one's base colour (sRGB).
    pub texture: Option<String>,
    /// Principled: glTF's metallic-roughness image (linear; green: roughness, blue:
    /// metalness).
    pub metallic_roughness_texture: Option<String>,
    /// Principled: an image (sRGB) that multiplies `emission`.
    pub emission_texture: Option<String>,
    /// Principled: an ambient-occlusion image (linear, red channel; glTF's
    /// `occlusionTexture`), read for the `occlusion` AOV only.
    pub occlusion_texture: Option<String>,
    /// Principled: the occlusion texture's strength in [0, 1] (default 1).
    pub occlusion_strength: Option<f32>,
    /// Diffuse and principled: a tangent-space normal map (linear; glTF's and OpenGL's
    /// convention: red along +u, green along +v).
    pub normal_texture: Option<String>,
    /// The normal map's scale of red and green (default 1).
    pub normal_scale: Option<f32>,
    /// All but emissive: an alpha mask — where the alpha (`alpha` times `texture`'s alpha
    /// channel) is below this cutoff in [0, 1], the surface is not there (glTF's `MASK`).
    pub alpha_cutoff: Option<f32>,
    /// The alpha an alpha mask or blend reads, in [0, 1] (default 1; multiplies
    /// `texture`'s alpha).
    pub alpha: Option<f32>,
    /// All but emissive: stochastic transparency (glTF's `BLEND`) — the surface is there
    /// with probability alpha at each hit. Not with `alpha_cutoff`.
    #[serde(default)]
    pub alpha_blend: bool,
    /// Index of refraction (glass).
    pub ior: Option<f32>,
    /// Emitted radiance (emissive; principled: emitted where hit, not sampled as a light).
    pub emission: Option<[f32; 3]>,
    /// Emissive: emit from both faces (default: the front face only).
    #[serde(default)]
    pub two_sided: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shape {
    /// Unit square in the XZ plane, centred, facing +Y.
    Quad,
    /// Unit cube, centred.
    Box,
    /// Unit-radius sphere, centred, tessellated.
    Sphere,
    /// Open stadium bowl of radius 1 on y = 0, tessellated (`segments` slices).
    Stadium,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum Scale {
    Uniform(f32),
    Axes([f32; 3]),
}

impl Default for Scale {
    fn default() -> Self {
        Scale::Uniform(1.0)
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDef {
    /// OBJ file, relative to the scene file. Exactly one of `mesh` and `shape`.
    pub mesh: Option<String>,
    pub shape: Option<Shape>,
    /// Material name; default: the OBJ's MTL materials, else a grey diffuse.
    pub material: Option<String>,
    #[serde(default)]
    pub scale: Scale,
    /// Rotation in degrees about X, then Y, then Z.
    #[serde(default)]
    pub rotate: [f32; 3],
    #[serde(default)]
    pub translate: [f32; 3],
    /// Sphere and stadium tessellation: segments around (a sphere's rings are half as many).
    #[serde(default = "segments")]
    pub segments: u32,
    /// Shading normals: a mesh's own (OBJ `vn`, PLY `nx ny nz`, glTF `NORMAL`) and a
    /// sphere's exact ones, interpolated across each triangle (default); false shades every
    /// triangle flat.
    #[serde(default)]
    pub smooth: Option<bool>,
    /// `[[objects.copies]]`: the object placed once per entry, each entry's transform
    /// applied after the object's own (default: placed once, as it is).
    #[serde(default)]
    pub copies: Vec<CopyDef>,
    /// `grid = { count = [nx, ny, nz], step = [dx, dy, dz] }`: the object placed on a grid
    /// of offsets (x fastest, then y, then z), instead of `copies`.
    pub grid: Option<GridDef>,
    /// Motion per frame (`render --frames`): each copy moves by this much a frame.
    #[serde(default, rename = "move")]
    pub velocity: [f32; 3],
    /// Motion per frame: each copy turns by these degrees a frame about X, then Y, then Z,
    /// about where the object's origin lies in that copy.
    #[serde(default)]
    pub spin: [f32; 3],
}

/// One placement of an object (`[[objects.copies]]`): scale, rotation, then translation.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CopyDef {
    #[serde(default)]
    pub scale: Scale,
    /// Rotation in degrees about X, then Y, then Z.
    #[serde(default)]
    pub rotate: [f32; 3],
    #[serde(default)]
    pub translate: [f32; 3],
}

/// Copies of an object on a grid of offsets (`grid = { … }`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridDef {
    /// Copies along x, y and z.
    pub count: [u32; 3],
    /// Offset between neighbours along x, y and z.
    pub step: [f32; 3],
}

/// A light's `type`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    /// Radiant intensity `color·intensity` from `position`, falling off with 1/d².
    Point,
    /// Irradiance `color·intensity` arriving along `direction` (a sun).
    Directional,
    /// Radiant intensity `color·intensity` from `position` along `direction`, full inside
    /// `inner_angle` and fading to none at `outer_angle` (glTF's spot falloff).
    Spot,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDef {
    #[serde(rename = "type")]
    pub kind: LightKind,
    pub position: Option<[f32; 3]>,
    pub direction: Option<[f32; 3]>,
    #[serde(default = "white")]
    pub color: [f32; 3],
    #[serde(default = "one")]
    pub intensity: f32,
    /// Spot: the half-angle of full intensity, degrees (default 0).
    pub inner_angle: Option<f32>,
    /// Spot: the half-angle beyond which no light goes, degrees (default 45).
    pub outer_angle: Option<f32>,
}

fn up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn fov() -> f32 {
    40.0
}
fn width() -> u32 {
    512
}
fn height() -> u32 {
    512
}
fn max_bounces() -> u32 {
    4
}
fn spp() -> u32 {
    16
}
fn segments() -> u32 {
    32
}
fn white() -> [f32; 3] {
    [1.0; 3]
}
fn one() -> f32 {
    1.0
}

/// 1-based line of a byte offset.
pub fn line_of(src: &str, offset: usize) -> usize {
    src[..offset.min(src.len())].matches('\n').count() + 1
}

/// The lines of a text, for the line of many offsets: each found by a binary search over
/// where the lines start (counting from the top for each would take time quadratic in a
/// scene's number of objects, lights and materials).
pub struct Lines {
    /// Byte offsets just past each newline.
    starts: Vec<usize>,
}

impl Lines {
    /// Indexes `src`'s newlines.
    pub fn new(src: &str) -> Lines {
        let starts = (src.bytes().enumerate())
            .filter(|&(_, b)| b == b'\n')
            .map(|(i, _)| i + 1)
            .collect();
        Lines { starts }
    }

    /// 1-based line of a byte offset, as [`line_of`] gives it.
    pub fn of(&self, offset: usize) -> usize {
        self.starts.partition_point(|&s| s <= offset) + 1
    }
}

impl SceneFile {
    /// Parses scene text; errors name `path` and the line.
    pub fn parse(path: &Path, src: &str) -> Result<SceneFile> {
        toml::from_str(src).map_err(|e| {
            let line = e.span().map(|s| line_of(src, s.start));
            Error::input(path, line, e.message().trim().to_string())
        })
    }
}

// The codes the render kernel reads (generated into the WGSL prelude by gpu::shaders).

impl Integrator {
    /// Code in the render kernel's `Params.integrator`.
    pub fn code(self) -> u32 {
        match self {
            Integrator::Direct => 0,
            Integrator::Path => 1,
            Integrator::Ao => 2,
        }
    }
}

impl MaterialKind {
    /// Code in the render kernel's `Material.kind`.
    pub fn code(self) -> u32 {
        match self {
            MaterialKind::Diffuse => 0,
            MaterialKind::Mirror => 1,
            MaterialKind::Glass => 2,
            MaterialKind::Emissive => 3,
            MaterialKind::Principled => 4,
        }
    }
}

impl LightKind {
    /// Code in the render kernel's `Light.kind`.
    pub fn code(self) -> u32 {
        match self {
            LightKind::Point => 0,
            LightKind::Directional => 1,
            LightKind::Spot => 2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The index gives every offset the line counting from the top gives.
    #[test]
    fn lines_are_counted_lines() {
        let src = "a\n\nbc\nd";
        let lines = Lines::new(src);
        for offset in 0..=src.len() + 2 {
            assert_eq!(lines.of(offset), line_of(src, offset), "offset {offset}");
        }
    }
}
