//! The render kernel's WGSL: the GPU form's traversal (through `gpu::shaders`), then the
//! renderer's own constants — material, light and integrator codes, defined here in Rust —
//! and `shaders/kernels/render.wgsl`. The renderer owns these constants, so `gpu` never
//! needs to know what a material is.

use crate::accel::GpuForm;
use crate::gpu::shaders::{self, Shared};
use crate::gpu::BufferParts;

use super::bsdf::{ALPHA_MIN, DIELECTRIC_F0, LUMINANCE};
use super::environment::{MAP_PDF_SCALE, UNIFORM_SPHERE_PDF};
use super::sampling::POINT_ERROR;
use super::scene::TextureSlot;
use super::trig::{ATAN_C, COS_C, INV_TAU, SIN_C};
use super::{Integrator, LightKind, MaterialKind, TRANSFORM_ERROR};
use super::{MAT_ALPHA_BLEND, MAT_OCCLUSION, MAT_UV_TRANSFORMS};
use super::{MAT_ALPHA_MASK, MAT_EMISSION_TEXTURE, MAT_METALLIC_ROUGHNESS, MAT_NORMAL_MAP};
use super::{MAT_TEXTURED, MAT_TWO_SIDED};
use crate::geometry::{NO_NORMAL, SNORM15_SCALE, SNORM16_SCALE, TANGENT_FLIPPED, TANGENT_PRESENT};

/// The render kernel (one sample of one pixel per invocation).
pub const RENDER: &str = include_str!("../../shaders/kernels/render.wgsl");
/// The environment light's lookups and sampling, and the polynomial trigonometry they use.
pub const ENVIRONMENT: &str = include_str!("../../shaders/lib/environment.wgsl");
/// The surfaces' scattering: Lambert and glTF's metallic-roughness (render::bsdf).
pub const BSDF: &str = include_str!("../../shaders/lib/bsdf.wgsl");

/// The render kernel where each lane traverses alone: it traces each ray where the CPU
/// does (`lanes_any(b)`, unused there, is the lane's own `b`).
const LANES_PER_RAY: &str = "const LANES_TOGETHER = false;\n\
                             fn lanes_any(b: bool) -> bool { return b; }\n";
/// The render kernel where the lanes of a subgroup traverse together: every lane traces
/// one ray a round, and `lanes_any(b)` is any lane's `b`.
const LANES_SUBGROUP: &str = "const LANES_TOGETHER = true;\n\
                              fn lanes_any(b: bool) -> bool { return subgroupAny(b); }\n";

/// The constants the render kernel shares with the renderer, by WGSL name; like
/// [`shaders::shared_constants`], the Rust definition is the only one.
pub fn render_constants() -> Vec<(&'static str, Shared)> {
    use Shared::{F32, U32};
    vec![
        ("PI_INV", F32(std::f32::consts::FRAC_1_PI)), // the CPU renderer's FRAC_1_PI
        ("KIND_DIFFUSE", U32(MaterialKind::Diffuse.code())),
        ("KIND_MIRROR", U32(MaterialKind::Mirror.code())),
        ("KIND_GLASS", U32(MaterialKind::Glass.code())),
        ("KIND_EMISSIVE", U32(MaterialKind::Emissive.code())),
        ("KIND_PRINCIPLED", U32(MaterialKind::Principled.code())),
        ("INTEGRATOR_DIRECT", U32(Integrator::Direct.code())),
        ("INTEGRATOR_PATH", U32(Integrator::Path.code())),
        ("INTEGRATOR_AO", U32(Integrator::Ao.code())),
        ("LIGHT_POINT", U32(LightKind::Point.code())),
        ("LIGHT_DIRECTIONAL", U32(LightKind::Directional.code())),
        ("LIGHT_SPOT", U32(LightKind::Spot.code())),
        ("MAT_TEXTURED", U32(MAT_TEXTURED)),
        ("MAT_TWO_SIDED", U32(MAT_TWO_SIDED)),
        ("MAT_METALLIC_ROUGHNESS", U32(MAT_METALLIC_ROUGHNESS)),
        ("MAT_EMISSION_TEXTURE", U32(MAT_EMISSION_TEXTURE)),
        ("MAT_NORMAL_MAP", U32(MAT_NORMAL_MAP)),
        ("MAT_ALPHA_MASK", U32(MAT_ALPHA_MASK)),
        ("MAT_OCCLUSION", U32(MAT_OCCLUSION)),
        ("MAT_ALPHA_BLEND", U32(MAT_ALPHA_BLEND)),
        ("MAT_UV_TRANSFORMS", U32(MAT_UV_TRANSFORMS)),
        // render::scene::TextureSlot
        ("UV_SLOT_BASE", U32(TextureSlot::Base as u32)),
        (
            "UV_SLOT_METALLIC_ROUGHNESS",
            U32(TextureSlot::MetallicRoughness as u32),
        ),
        ("UV_SLOT_EMISSION", U32(TextureSlot::Emission as u32)),
        ("UV_SLOT_NORMAL", U32(TextureSlot::Normal as u32)),
        ("UV_SLOT_OCCLUSION", U32(TextureSlot::Occlusion as u32)),
        ("POINT_ERROR", F32(POINT_ERROR)), // render::sampling::POINT_ERROR
        ("TRANSFORM_ERROR", F32(TRANSFORM_ERROR)), // render::scene::TRANSFORM_ERROR
        ("NO_NORMAL", U32(NO_NORMAL)),     // geometry::NO_NORMAL
        ("SNORM16_SCALE", F32(SNORM16_SCALE)), // geometry::SNORM16_SCALE
        ("SNORM15_SCALE", F32(SNORM15_SCALE)), // geometry::SNORM15_SCALE
        ("TANGENT_PRESENT", U32(TANGENT_PRESENT)),
        ("TANGENT_FLIPPED", U32(TANGENT_FLIPPED)),
        // render::trig and render::environment
        ("PI", F32(std::f32::consts::PI)),
        ("FRAC_PI_2", F32(std::f32::consts::FRAC_PI_2)),
        ("INV_TAU", F32(INV_TAU)),
        ("SIN_C1", F32(SIN_C[0])),
        ("SIN_C2", F32(SIN_C[1])),
        ("SIN_C3", F32(SIN_C[2])),
        ("SIN_C4", F32(SIN_C[3])),
        ("COS_C1", F32(COS_C[0])),
        ("COS_C2", F32(COS_C[1])),
        ("COS_C3", F32(COS_C[2])),
        ("COS_C4", F32(COS_C[3])),
        ("ATAN_C0", F32(ATAN_C[0])),
        ("ATAN_C1", F32(ATAN_C[1])),
        ("ATAN_C2", F32(ATAN_C[2])),
        ("ATAN_C3", F32(ATAN_C[3])),
        ("ATAN_C4", F32(ATAN_C[4])),
        ("ATAN_C5", F32(ATAN_C[5])),
        ("UNIFORM_SPHERE_PDF", F32(UNIFORM_SPHERE_PDF)),
        ("MAP_PDF_SCALE", F32(MAP_PDF_SCALE)),
        // render::bsdf
        ("DIELECTRIC_F0", F32(DIELECTRIC_F0)),
        ("ALPHA_MIN", F32(ALPHA_MIN)),
        ("LUMINANCE_R", F32(LUMINANCE[0])),
        ("LUMINANCE_G", F32(LUMINANCE[1])),
        ("LUMINANCE_B", F32(LUMINANCE[2])),
    ]
}

/// The renderer's constants, the lane mode and the render kernel.
fn render_kernel(lanes: &str) -> String {
    let constants = shaders::constants_wgsl("render::kernel", &render_constants());
    format!("{constants}\n{lanes}\n{RENDER}\n{ENVIRONMENT}\n{BSDF}")
}

/// The render kernel's full source for a GPU form.
pub fn render_source(form: &dyn GpuForm, parts: &BufferParts) -> String {
    let kernel = render_kernel(LANES_PER_RAY) + &parts.render_wgsl();
    shaders::kernel_source(form, &kernel, parts)
}

/// The render kernel's source for a GPU form's subgroup traversal, or None when the form
/// has none; like [`shaders::trace_subgroup_source`], it needs the device's
/// `Features::SUBGROUP`.
pub fn render_subgroup_source(form: &dyn GpuForm, parts: &BufferParts) -> Option<String> {
    let kernel = render_kernel(LANES_SUBGROUP) + &parts.render_wgsl();
    shaders::subgroup_kernel_source(form, &kernel, parts)
}

/// Every kernel's full source for a GPU form whose arrays are bound in `parts`, by name (for
/// validation and layout tests): the trace kernels ([`shaders::all`]) and the render
/// kernels, the subgroup kernels included where the form has a subgroup traversal.
pub fn all_kernels(form: &dyn GpuForm, parts: &BufferParts) -> Vec<(&'static str, String)> {
    let mut v = shaders::all(form, parts);
    v.push(("render", render_source(form, parts)));
    v.extend(render_subgroup_source(form, parts).map(|s| ("render-subgroup", s)));
    v
}
