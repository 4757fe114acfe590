//! The GPU renderer: the scene uploaded once, one pipeline per effect set (override
//! constants of shaders/render.wgsl), samples accumulated over many short dispatches.

use std::collections::HashMap;
use std::sync::Arc;

use crate::accel::capacity_for;

use glam::Vec3;

use super::aov::FirstHit;
use super::crop::Crop;
use super::effects::EffectSet;
use super::scene::{Light, LightKind, RenderScene};
use crate::accel::GpuForm;
use crate::accel::TraversalMode;
use crate::error::{Error, Result};
use crate::geometry::{Affine, Robustness, NO_NORMAL, NO_TANGENT};
use crate::gpu::plumbing::{
    buffer_binding, dynamic_uniform_entry, storage_entry, uniform_binding, wait, Chunks, Kernel,
    Readback,
};
use crate::gpu::{bindings, word_array, BufferParts, BvhMemory, GpuBvh, GpuContext, WordArray};

/// Storage buffers the render kernel binds with every word array in one part (nodes,
/// triangles, shading words, materials, lights, emitters, texels, the accumulator).
const RENDER_STORAGE_BUFFERS: u32 = 8;

/// Pixels per dispatch: keeps every dispatch short on a software rasteriser.
const CHUNK: u32 = 1 << 16;
const WORKGROUP: u32 = 64;
/// Bytes of [`RenderParams`] (WGSL `Params`).
const PARAMS_SIZE: u64 = std::mem::size_of::<RenderParams>() as u64;

/// A triangle by original index, for shading (WGSL `Shade`).
/// WGSL twin: `Shade` in shaders/kernels/render.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuShade {
    /// Vertex 0, scene space.
    pub v0: [f32; 3],
    /// Index into the materials buffer ([`GpuMaterial`]).
    pub material: u32,
    /// Vertex 1 (barycentric weight `u` of a hit).
    pub v1: [f32; 3],
    /// Vertex 0's shading normal, packed ([`RenderScene::normals`]; [`NO_NORMAL`]: the
    /// triangle shades flat).
    pub n0: u32,
    /// Vertex 2 (barycentric weight `v` of a hit).
    pub v2: [f32; 3],
    /// Vertex 1's shading normal, packed.
    pub n1: u32,
    /// Texture coordinates of vertex 0.
    pub uv0: [f32; 2],
    /// Texture coordinates of vertex 1.
    pub uv1: [f32; 2],
    /// Texture coordinates of vertex 2.
    pub uv2: [f32; 2],
    /// Vertex 2's shading normal, packed.
    pub n2: u32,
    /// Vertex 0's tangent, packed ([`RenderScene::tangents`]; [`NO_TANGENT`]: none); the
    /// others' follow the placements ([`RenderParams::tangent_base`]).
    pub tangent: u32,
}

/// An instance of a scene with placements ([`RenderScene::placements`]), as the render
/// kernel reads it: seven words after the shading triangles (WGSL `placed_shade`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuPlacement {
    /// Object space to world space.
    pub to_world: Affine,
    /// World space to object space (the f32 inverse).
    pub to_object: Affine,
    /// Its first triangle number.
    pub first_prim: u32,
    /// Where its mesh's shading triangles start.
    pub shade_base: u32,
    /// Padding (zero).
    pub _pad: [u32; 2],
}

/// WGSL `Material`.
/// WGSL twin: `Material` in shaders/kernels/render.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuMaterial {
    /// Linear RGB reflectance or transmittance tint; a texture, if any, replaces it.
    pub albedo: [f32; 3],
    /// [`MaterialKind::code`](super::scene::MaterialKind::code): 0 diffuse, 1 mirror,
    /// 2 glass, 3 emissive.
    pub kind: u32,
    /// Emitted radiance, linear RGB (zero unless emissive).
    pub emission: [f32; 3],
    /// Index of refraction (glass; 1 otherwise).
    pub ior: f32,
    /// Index of the texture's first texel in the texel buffer (one `vec4` per texel).
    pub tex_offset: u32,
    /// Texture width in texels (0 without a texture).
    pub tex_width: u32,
    /// Texture height in texels (0 without a texture).
    pub tex_height: u32,
    /// Bits: [`MAT_TEXTURED`] (albedo times the texture), [`MAT_TWO_SIDED`] (emits from
    /// both faces), [`MAT_METALLIC_ROUGHNESS`], [`MAT_EMISSION_TEXTURE`],
    /// [`MAT_NORMAL_MAP`], [`MAT_ALPHA_MASK`], [`MAT_OCCLUSION`], [`MAT_ALPHA_BLEND`],
    /// [`MAT_UV_TRANSFORMS`].
    pub flags: u32,
    /// Principled: metalness.
    pub metallic: f32,
    /// Principled: perceptual roughness.
    pub roughness: f32,
    /// Principled: where the metallic-roughness texture's texels start.
    pub mr_offset: u32,
    /// Principled: where the emission texture's texels start.
    pub emission_offset: u32,
    /// The metallic-roughness texture's width (0 without one).
    pub mr_width: u32,
    /// The metallic-roughness texture's height.
    pub mr_height: u32,
    /// The emission texture's width (0 without one).
    pub emission_width: u32,
    /// The emission texture's height.
    pub emission_height: u32,
    /// Where the normal map's texels start.
    pub normal_offset: u32,
    /// The normal map's width (0 without one).
    pub normal_width: u32,
    /// The normal map's height.
    pub normal_height: u32,
    /// The normal map's scale of red and green.
    pub normal_scale: f32,
    /// An alpha mask's alpha (times the texture's alpha).
    pub alpha: f32,
    /// An alpha mask's cutoff ([`MAT_ALPHA_MASK`]).
    pub alpha_cutoff: f32,
    /// Where the occlusion texture's texels start ([`MAT_OCCLUSION`]).
    pub occlusion_offset: u32,
    /// The occlusion texture's width (0 without one).
    pub occlusion_width: u32,
    /// The occlusion texture's height.
    pub occlusion_height: u32,
    /// The occlusion texture's strength.
    pub occlusion_strength: f32,
    /// Where its textures' coordinate maps start in the texel buffer
    /// ([`MAT_UV_TRANSFORMS`]): two texels (the rows) per [`TextureSlot`](super::TextureSlot), the identity for
    /// a slot without one (WGSL `slot_uv`).
    pub uv_maps: u32,
    /// Padding (zero).
    pub _pad2: u32,
}

/// [`GpuMaterial::flags`] bit: the albedo is multiplied by the material's texture.
pub const MAT_TEXTURED: u32 = 1;
/// [`GpuMaterial::flags`] bit: an emitter that emits from both faces.
pub const MAT_TWO_SIDED: u32 = 2;
/// [`GpuMaterial::flags`] bit: metalness and roughness are multiplied by a texture's blue
/// and green channels.
pub const MAT_METALLIC_ROUGHNESS: u32 = 4;
/// [`GpuMaterial::flags`] bit: the emission is multiplied by a texture.
pub const MAT_EMISSION_TEXTURE: u32 = 8;
/// [`GpuMaterial::flags`] bit: a normal map tilts the shading normal.
pub const MAT_NORMAL_MAP: u32 = 16;
/// [`GpuMaterial::flags`] bit: an alpha mask cuts the surface where its alpha is below
/// `alpha_cutoff`.
pub const MAT_ALPHA_MASK: u32 = 32;
/// [`GpuMaterial::flags`] bit: an occlusion texture (read for the occlusion AOV).
pub const MAT_OCCLUSION: u32 = 64;
/// [`GpuMaterial::flags`] bit: stochastic transparency, the alpha tested against a cutoff
/// drawn per hit (with [`MAT_ALPHA_MASK`]).
pub const MAT_ALPHA_BLEND: u32 = 128;
/// [`GpuMaterial::flags`] bit: a texture is read at moved coordinates
/// ([`GpuMaterial::uv_maps`]).
pub const MAT_UV_TRANSFORMS: u32 = 256;

/// WGSL `Light`.
/// WGSL twin: `Light` in shaders/kernels/render.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    /// Point and spot: position. Directional: unit direction the light travels in.
    pub v: [f32; 3],
    /// [`LightKind::code`]: 0 point, 1 directional, 2 spot.
    pub kind: u32,
    /// Point and spot: radiant intensity. Directional: irradiance. Linear RGB.
    pub power: [f32; 3],
    /// Spot: the falloff's offset ([`Light::Spot`]).
    pub offset: f32,
    /// Spot: the unit direction of the cone's axis.
    pub axis: [f32; 3],
    /// Spot: the falloff's scale.
    pub scale: f32,
}

/// WGSL `Params` (uniform).
/// WGSL twin: `Params` in shaders/kernels/render.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RenderParams {
    /// Camera position.
    pub eye: [f32; 3],
    /// Image width in pixels.
    pub width: u32,
    /// Unit view direction.
    pub fwd: [f32; 3],
    /// Image height in pixels.
    pub height: u32,
    /// Camera right · half-width of the image plane at distance 1.
    pub right: [f32; 3],
    /// 2 / width.
    pub inv_w2: f32,
    /// Camera up · half-height of the image plane at distance 1.
    pub up: [f32; 3],
    /// 2 / height.
    pub inv_h2: f32,
    /// The environment's uniform radiance, or its map's scale, linear RGB (the
    /// ENVIRONMENT effect reads it).
    pub env_radiance: [f32; 3],
    /// Random seed, hashed with the pixel and sample index.
    pub seed: u32,
    /// Index of the sample this pass adds.
    pub sample: u32,
    /// First pixel (row-major index) of this dispatch.
    pub offset: u32,
    /// Pixels in this dispatch.
    pub count: u32,
    /// Most bounces after the primary hit.
    pub max_bounces: u32,
    /// [`Integrator::code`](super::scene::Integrator::code): 0 direct, 1 path, 2 AO.
    pub integrator: u32,
    /// Point and directional lights in the lights buffer (which holds one more, zeroed).
    pub n_lights: u32,
    /// Emissive triangles in the emitters buffer (which holds one more, zeroed).
    pub n_emitters: u32,
    /// Total area of the emissive triangles (the last entry of the emitter CDF; 0 if none).
    pub emit_total: f32,
    /// Ambient-occlusion ray length, scene units.
    pub ao_distance: f32,
    /// The epsilon of the fixed ray offset (RayOffset::Fixed), scene units.
    pub fixed_offset: f32,
    /// First column of the crop rendered (0: the whole image).
    pub crop_x0: u32,
    /// First row of the crop rendered.
    pub crop_y0: u32,
    /// Columns in the crop: the accumulator is the crop's pixels, row-major.
    pub crop_width: u32,
    /// With AOVs: the accumulator entry where they start (two per pixel, after the sums).
    pub aov_base: u32,
    /// With placements: the shading word where the [`GpuPlacement`]s start.
    pub placement_base: u32,
    /// Placements (0 without).
    pub n_placements: u32,
    /// The first row of the environment's rotation from world to map space.
    pub env_x: [f32; 3],
    /// The environment map's width in texels (0: uniform).
    pub env_width: u32,
    /// The second row of that rotation.
    pub env_y: [f32; 3],
    /// The environment map's height in texels.
    pub env_height: u32,
    /// The third row of that rotation.
    pub env_z: [f32; 3],
    /// Where the map's texels start in the texel buffer (a `vec4` each).
    pub env_texels: u32,
    /// Where the map's CDFs start in the texel buffer ([`EnvMap::cdf`](super::EnvMap::cdf),
    /// four floats a `vec4`).
    pub env_cdf: u32,
    /// 1: the scene has an environment (the ENVIRONMENT effect may be compiled in for a
    /// scene without: then it draws no random numbers, as on the CPU).
    pub has_env: u32,
    /// Where the triangles' other corner tangents start, in shading words: two per triangle
    /// (corners 1 and 2; [`GpuShade::tangent`] is corner 0's), two triangles a word; read
    /// only where a material has a normal map.
    pub tangent_base: u32,
    /// Padding (zero).
    pub _pad2: u32,
}

/// The scene and a layout on the device, the render kernel compiled for them, and the
/// accumulator of samples.
pub struct GpuRenderer<'a> {
    ctx: &'a GpuContext,
    bvh: GpuBvh,
    /// The shading words (the placements among them) in the BVH's memory, and the
    /// emitters: written over where the scene moves ([`GpuRenderer::move_to`]).
    shades: WordArray,
    emitters: wgpu::Buffer,
    layout_constants: Vec<(&'static str, f64)>,
    kernel: Kernel,
    bind: wgpu::BindGroup,
    accum: WordArray,
    params: wgpu::Buffer,
    pipelines: HashMap<(EffectSet, Robustness), wgpu::ComputePipeline>,
    aovs: bool,
    base: RenderParams,
    chunks: Chunks,
    mode: TraversalMode,
}

impl<'a> GpuRenderer<'a> {
    /// Validates and uploads the layout (in `memory`) and the scene, and compiles the
    /// kernel that renders the pixels of `crop` (checked against the image by the caller),
    /// writing their AOVs in sample 0 when `aovs`, traversing in `mode` (per ray, with a
    /// warning, where that mode cannot run: see [`GpuRenderer::mode`]); the accumulator
    /// starts at zero.
    pub fn new(
        ctx: &'a GpuContext,
        scene: &RenderScene,
        layout: &dyn GpuForm,
        memory: BvhMemory,
        crop: Crop,
        aovs: bool,
        mode: TraversalMode,
    ) -> Result<Self> {
        Self::new_with(ctx, scene, (layout, None), memory, crop, aovs, mode)
    }

    /// Whether the BVH's nodes, its triangles and the shading triangles are read where the
    /// host holds them ([`GpuRenderer::new_shared`]) rather than copied.
    pub fn in_place(&self) -> [bool; 3] {
        let [nodes, tris] = self.bvh.in_place();
        [nodes, tris, self.shades.in_place()]
    }

    /// [`GpuRenderer::new`] over a layout nothing changes while it is uploaded: where the
    /// device's memory is the host's, its arrays are read in place
    /// ([`GpuBvh::upload_shared`]). Such a renderer cannot [`move_to`](Self::move_to)
    /// another frame (the top level's words cannot be written over).
    pub fn new_shared(
        ctx: &'a GpuContext,
        scene: &RenderScene,
        layout: &Arc<dyn GpuForm>,
        memory: BvhMemory,
        crop: Crop,
        aovs: bool,
        mode: TraversalMode,
    ) -> Result<Self> {
        let shared = (layout.as_ref(), Some(layout));
        Self::new_with(ctx, scene, shared, memory, crop, aovs, mode)
    }

    fn new_with(
        ctx: &'a GpuContext,
        scene: &RenderScene,
        (layout, shared): (&dyn GpuForm, Option<&Arc<dyn GpuForm>>),
        memory: BvhMemory,
        crop: Crop,
        aovs: bool,
        mode: TraversalMode,
    ) -> Result<Self> {
        scene.check()?;
        // Fits a u32: the crop lies in the image, whose pixel count the caller checked.
        let pixels = crop.pixels() as u32;
        let placements = placements_of(scene);
        let tangents = other_tangents(scene);
        // Room past the end (where big) for a device to read them in place.
        let placement_words: &[GpuShade] = bytemuck::cast_slice(&placements);
        let len = scene.mesh.triangles.len() + placement_words.len() + tangents.len();
        let mut shades: Vec<GpuShade> = Vec::with_capacity(capacity_for::<GpuShade>(len));
        shades.extend((scene.mesh.triangles.iter().enumerate()).map(|(i, t)| {
            let uv = scene.uvs[i];
            let n = scene.normals.get(i).copied().unwrap_or([NO_NORMAL; 3]);
            GpuShade {
                v0: t.v[0].into(),
                material: scene.material_of[i],
                v1: t.v[1].into(),
                n0: n[0],
                v2: t.v[2].into(),
                n1: n[1],
                uv0: uv[0].into(),
                uv1: uv[1].into(),
                uv2: uv[2].into(),
                n2: n[2],
                tangent: scene.tangents.get(i).map_or(NO_TANGENT, |t| t[0]),
            }
        }));
        let placement_base = shades.len() * 5;
        shades.extend_from_slice(placement_words);
        let tangent_base = shades.len() * 5;
        shades.extend_from_slice(&tangents);
        drop((placements, tangents));
        let mut texels: Vec<[f32; 4]> = Vec::new();
        let mut tex_at = Vec::new();
        for t in &scene.textures {
            tex_at.push(texels.len() as u32);
            // Alpha in w (1 where the image has none): what an alpha mask reads.
            let whole = t.alpha.len() == t.texels.len();
            let alpha = |i: usize| if whole { t.alpha[i] } else { 1.0 };
            texels
                .extend((t.texels.iter().enumerate()).map(|(i, c)| c.extend(alpha(i)).to_array()));
        }
        // Each material's coordinate maps, where it moves any (WGSL slot_uv).
        let uv_maps: Vec<u32> = (scene.materials.iter())
            .map(|m| {
                if !m.moves_textures() {
                    return 0;
                }
                let at = texels.len() as u32;
                for map in m.uv_transforms {
                    let [a, b] = map.unwrap_or([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
                    texels.extend([a, b].map(|r| [r[0], r[1], r[2], 0.0]));
                }
                at
            })
            .collect();
        let env = scene.environment.as_ref();
        let (env_texels, env_cdf) = (
            texels.len() as u32,
            texels.len() as u32 + {
                env.and_then(|e| e.map.as_ref())
                    .map_or(0, |m| m.texels.len() as u32)
            },
        );
        if let Some(m) = env.and_then(|e| e.map.as_ref()) {
            texels.extend(m.texels.iter().map(|c| c.extend(1.0).to_array()));
            texels.extend(m.cdf.chunks(4).map(|c| {
                let mut v = [0.0; 4];
                v[..c.len()].copy_from_slice(c);
                v
            }));
        }
        if texels.is_empty() {
            texels.push([0.0; 4]);
        }
        let slot = |t: Option<usize>| {
            t.map_or((0, 0, 0), |t| {
                (tex_at[t], scene.textures[t].width, scene.textures[t].height)
            })
        };
        let materials: Vec<GpuMaterial> = (scene.materials.iter().zip(&uv_maps))
            .map(|(m, &uv_maps)| {
                let (off, w, h) = slot(m.texture);
                let (mr_off, mr_w, mr_h) = slot(m.metallic_roughness_texture);
                let (e_off, e_w, e_h) = slot(m.emission_texture);
                let (n_off, n_w, n_h) = slot(m.normal_texture);
                let (o_off, o_w, o_h) = slot(m.occlusion_texture);
                let bit = |on: bool, b: u32| if on { b } else { 0 };
                GpuMaterial {
                    albedo: m.albedo.into(),
                    kind: m.kind.code(),
                    emission: m.emission.into(),
                    ior: m.ior,
                    tex_offset: off,
                    tex_width: w,
                    tex_height: h,
                    flags: bit(m.texture.is_some(), MAT_TEXTURED)
                        | bit(m.two_sided, MAT_TWO_SIDED)
                        | bit(
                            m.metallic_roughness_texture.is_some(),
                            MAT_METALLIC_ROUGHNESS,
                        )
                        | bit(m.emission_texture.is_some(), MAT_EMISSION_TEXTURE)
                        | bit(m.normal_texture.is_some(), MAT_NORMAL_MAP)
                        | bit(m.alpha_cutoff.is_some() || m.alpha_blend, MAT_ALPHA_MASK)
                        | bit(m.alpha_blend && m.alpha_cutoff.is_none(), MAT_ALPHA_BLEND)
                        | bit(m.occlusion_texture.is_some(), MAT_OCCLUSION)
                        | bit(m.moves_textures(), MAT_UV_TRANSFORMS),
                    metallic: m.metallic,
                    roughness: m.roughness,
                    mr_offset: mr_off,
                    emission_offset: e_off,
                    mr_width: mr_w,
                    mr_height: mr_h,
                    emission_width: e_w,
                    emission_height: e_h,
                    normal_offset: n_off,
                    normal_width: n_w,
                    normal_height: n_h,
                    normal_scale: m.normal_scale,
                    alpha: m.alpha,
                    alpha_cutoff: m.alpha_cutoff.unwrap_or(0.0),
                    occlusion_offset: o_off,
                    occlusion_width: o_w,
                    occlusion_height: o_h,
                    occlusion_strength: m.occlusion_strength,
                    uv_maps,
                    _pad2: 0,
                }
            })
            .collect();
        let mut lights: Vec<GpuLight> = (scene.lights.iter())
            .map(|l| match *l {
                Light::Point {
                    position,
                    intensity,
                } => GpuLight {
                    v: position.into(),
                    kind: LightKind::Point.code(),
                    power: intensity.into(),
                    ..bytemuck::Zeroable::zeroed()
                },
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    scale,
                    offset,
                } => GpuLight {
                    v: position.into(),
                    kind: LightKind::Spot.code(),
                    power: intensity.into(),
                    offset,
                    axis: direction.into(),
                    scale,
                },
                Light::Directional {
                    direction,
                    irradiance,
                } => GpuLight {
                    v: direction.into(),
                    kind: LightKind::Directional.code(),
                    power: irradiance.into(),
                    ..bytemuck::Zeroable::zeroed()
                },
            })
            .collect();
        let n_lights = lights.len() as u32;
        lights.push(bytemuck::Zeroable::zeroed());
        let mut emitters = emitter_words(scene);
        let n_emitters = emitters.len() as u32;
        emitters.push([0; 2]);

        // The sums, then (with AOVs) two entries a pixel.
        let accum_bytes = pixels as u64 * 16 * if aovs { 3 } else { 1 };
        let sized: [(u32, &str, &[u8]); 3] = [
            (
                bindings::RENDER_MATERIALS,
                "the materials",
                bytemuck::cast_slice(&materials),
            ),
            (
                bindings::RENDER_LIGHTS,
                "the lights",
                bytemuck::cast_slice(&lights),
            ),
            (
                bindings::RENDER_EMITTERS,
                "the emitters",
                bytemuck::cast_slice(&emitters),
            ),
        ];
        for (_, what, bytes) in &sized {
            ctx.check_binding(what, bytes.len() as u64)?;
        }
        WordArray::check(
            ctx,
            BvhMemory::Buffers,
            "the image accumulator",
            accum_bytes as usize,
        )?;
        let texel_bytes: &[u8] = bytemuck::cast_slice(&texels);
        let shade_bytes: &[u8] = bytemuck::cast_slice(&shades);
        WordArray::check(ctx, BvhMemory::Buffers, "the textures", texel_bytes.len())?;
        WordArray::check(ctx, memory, "the shading triangles", shade_bytes.len())?;
        // The kernel's bindings checked before anything is uploaded.
        let parts = BufferParts {
            shades: word_array::parts_for(ctx, memory, shade_bytes.len() as u64),
            texels: word_array::parts_for(ctx, BvhMemory::Buffers, texel_bytes.len() as u64),
            accum: word_array::parts_for(ctx, BvhMemory::Buffers, accum_bytes),
            ..GpuBvh::checked_parts(ctx, layout, memory)?
        };
        parts.check(ctx, "render", RENDER_STORAGE_BUFFERS, true)?;
        let bvh = match shared {
            Some(layout) => GpuBvh::upload_shared(ctx, layout, memory)?,
            None => GpuBvh::upload(ctx, layout, memory)?,
        };
        // The shading triangles, one per mesh triangle, go where the BVH's triangles do:
        // read in place with the layout's arrays (kept until the device is done with them).
        let what = "the shading triangles";
        let room = shades.capacity() * std::mem::size_of::<GpuShade>();
        let shades = Arc::new(shades);
        let shade_bytes: &[u8] = bytemuck::cast_slice(&shades[..]);
        let shade_words = match shared {
            // SAFETY: the Arc handed on keeps the vector allocated, and nothing writes it
            // (its only owner besides is this function, which only reads it).
            Some(_) => unsafe {
                WordArray::upload_in_place(ctx, memory, what, (shade_bytes, room), shades.clone())
            },
            None => WordArray::upload(ctx, memory, what, shade_bytes),
        }?;
        drop(shades);
        // The texels (textures, coordinate maps, the environment) in a storage buffer, in
        // parts where one binding cannot hold them.
        let texel_words = WordArray::upload(ctx, BvhMemory::Buffers, "the textures", texel_bytes)?;
        drop(texels);
        // The emitters may be written over (their areas move with the placements).
        let usage = |b: u32| match b == bindings::RENDER_EMITTERS {
            true => wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            false => wgpu::BufferUsages::STORAGE,
        };
        let buffers: Vec<(u32, wgpu::Buffer)> = (sized.iter())
            .map(|&(b, what, bytes)| (b, ctx.buffer_with(what, bytes, usage(b))))
            .collect();
        let emitters_buf = (buffers.iter())
            .find(|(b, _)| *b == bindings::RENDER_EMITTERS)
            .map(|(_, buf)| buf.clone())
            .ok_or_else(|| Error::Gpu("no emitters buffer".into()))?;
        let accum = WordArray::output(ctx, "the image accumulator", accum_bytes)?;
        let chunks = Chunks::new(ctx, pixels, CHUNK, PARAMS_SIZE as u32);
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render params"),
            size: (chunks.count() * chunks.align) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut entries = bvh.layout_entries();
        entries.extend(shade_words.layout_entries(bindings::SHADE_ARRAY));
        entries.extend(texel_words.layout_entries(bindings::TEXEL_ARRAY));
        entries.extend(sized.iter().map(|&(b, _, _)| storage_entry(b, true)));
        entries.extend(accum.layout_entries(bindings::ACCUM_ARRAY));
        entries.push(dynamic_uniform_entry(bindings::RENDER_PARAMS, PARAMS_SIZE));
        let subgroup_source = match mode {
            TraversalMode::PerRay => None,
            TraversalMode::Subgroup => {
                let source = super::kernel::render_subgroup_source(layout, &parts);
                let why = ctx.subgroup_unavailable(layout.name(), source.is_some(), WORKGROUP);
                if let Some(why) = &why {
                    log::warn!("no {mode} traversal ({why}): rendering per ray");
                }
                source.filter(|_| why.is_none())
            }
        };
        let mode = match subgroup_source {
            Some(_) => TraversalMode::Subgroup,
            None => TraversalMode::PerRay,
        };
        let source =
            subgroup_source.unwrap_or_else(|| super::kernel::render_source(layout, &parts));
        let kernel = Kernel::new(
            ctx, "render", "render", &source, &entries,
            // Trusted modules are offered: the layout was validated by GpuBvh::upload, the
            // scene's indices (materials, emitters, texels) are built here in range, and
            // every pixel index is guarded by params.count.
            true,
        )?;
        let mut bind_entries = bvh.bind_entries();
        bind_entries.extend(shade_words.bind_entries(bindings::SHADE_ARRAY));
        bind_entries.extend(texel_words.bind_entries(bindings::TEXEL_ARRAY));
        bind_entries.extend(buffers.iter().map(|(b, buf)| buffer_binding(*b, buf)));
        bind_entries.extend(accum.bind_entries(bindings::ACCUM_ARRAY));
        bind_entries.push(uniform_binding(
            bindings::RENDER_PARAMS,
            &params,
            PARAMS_SIZE,
        ));
        let bind = kernel.bind(ctx, &bind_entries)?;
        let s = &scene.settings;
        let mut base = RenderParams {
            env_radiance: env.map_or(Vec3::ZERO, |e| e.radiance).into(),
            seed: s.seed,
            max_bounces: s.max_bounces,
            integrator: s.integrator.code(),
            n_lights,
            n_emitters,
            emit_total: scene.emitter_cdf.last().copied().unwrap_or(0.0),
            ao_distance: s.ao_distance,
            fixed_offset: scene.fixed_offset(),
            crop_x0: crop.x0,
            crop_y0: crop.y0,
            crop_width: crop.width(),
            aov_base: pixels,
            // Placements need not fit: placement_base is read only with placements, which
            // the upload's size check bounds.
            placement_base: placement_base as u32,
            n_placements: (scene.placements.as_ref()).map_or(0, |p| p.set().instances.len()) as u32,
            env_x: env.map_or(Vec3::X, |e| e.to_local[0]).into(),
            env_y: env.map_or(Vec3::Y, |e| e.to_local[1]).into(),
            env_z: env.map_or(Vec3::Z, |e| e.to_local[2]).into(),
            env_width: env.and_then(|e| e.map.as_ref()).map_or(0, |m| m.width),
            env_height: env.and_then(|e| e.map.as_ref()).map_or(0, |m| m.height),
            env_texels,
            env_cdf,
            has_env: env.is_some() as u32,
            // Read only with tangents, which the upload's size check bounds.
            tangent_base: tangent_base as u32,
            ..RenderParams::default()
        };
        set_view(&mut base, scene);
        Ok(GpuRenderer {
            ctx,
            bvh,
            shades: shade_words,
            emitters: emitters_buf,
            layout_constants: layout.overrides(),
            kernel,
            bind,
            accum,
            params,
            pipelines: HashMap::new(),
            base,
            chunks,
            aovs,
            mode,
        })
    }

    /// Moves what was uploaded to `scene`, the scene it was made for at another frame
    /// ([`RenderScene::at_frame`]: the same meshes, materials and lights; its placements,
    /// emitters' areas and view moved): writes `top` (the first word and the words of the
    /// moved two levels' top level) over the BVH's, the placements and the emitters over
    /// theirs, and takes the new view. Nothing else is uploaded and no kernel is made
    /// again. Refused where the emitters or placements are not as many as uploaded.
    pub fn move_to(&mut self, scene: &RenderScene, (first, top): (u32, &[u8])) -> Result<()> {
        let placements = placements_of(scene);
        let n_placements = (scene.placements.as_ref()).map_or(0, |p| p.set().instances.len());
        let n_emitters = scene.emitters.len() as u32;
        if n_placements as u32 != self.base.n_placements || n_emitters != self.base.n_emitters {
            return Err(Error::Usage(format!(
                "the moved scene has {n_placements} placements and {n_emitters} emitters \
                 where the uploaded one had {} and {}: render it anew",
                self.base.n_placements, self.base.n_emitters
            )));
        }
        let mut emitters = emitter_words(scene);
        emitters.push([0; 2]);
        self.bvh.write_node_words(self.ctx, first, top)?;
        let at = self.base.placement_base;
        (self.shades).write(self.ctx, at, bytemuck::cast_slice(&placements))?;
        (self.ctx.queue).write_buffer(&self.emitters, 0, bytemuck::cast_slice(&emitters));
        self.ctx.finish_writes();
        self.base.emit_total = scene.emitter_cdf.last().copied().unwrap_or(0.0);
        // The fixed offset is a share of the scene's diagonal, which moves with it.
        self.base.fixed_offset = scene.fixed_offset();
        set_view(&mut self.base, scene);
        Ok(())
    }

    /// The traversal mode the kernel runs: the one asked for, or per ray where it could not.
    pub fn mode(&self) -> TraversalMode {
        self.mode
    }

    fn pipeline(&mut self, fx: EffectSet, rob: Robustness) -> Result<wgpu::ComputePipeline> {
        if let Some(p) = self.pipelines.get(&(fx, rob)) {
            return Ok(p.clone());
        }
        let mut constants: Vec<(&str, f64)> = (fx.flags().iter())
            .map(|&(name, on)| (name, if on { 1.0 } else { 0.0 }))
            .collect();
        constants.push(("WORKGROUP_SIZE", WORKGROUP as f64));
        constants.push(("AOVS", if self.aovs { 1.0 } else { 0.0 }));
        constants.push(self.bvh.override_constant());
        constants.extend(rob.overrides());
        constants.extend(self.layout_constants.iter().copied());
        let p = (self.kernel).pipeline(self.ctx, &constants, !rob.checked_module)?;
        self.pipelines.insert((fx, rob), p.clone());
        Ok(p)
    }

    /// Compiles the pipeline for `fx` and `rob` unless it is already (the driver's shader
    /// compilation, kept out of the first sample's time: a dispatch with no pixel follows,
    /// for drivers that compile at the first dispatch); returns the milliseconds it took (0
    /// when it was compiled already).
    pub fn prepare(&mut self, fx: EffectSet, rob: Robustness) -> Result<f64> {
        rob.check_gpu()?;
        if self.pipelines.contains_key(&(fx, rob)) {
            return Ok(0.0);
        }
        let start = std::time::Instant::now();
        let pipeline = self.pipeline(fx, rob)?;
        // A driver may compile at the first dispatch (lavapipe does): one workgroup with no
        // pixel (count 0, so every invocation returns at once) does that here.
        let base = self.base;
        let bytes = self.chunks.uniforms(|offset, _| RenderParams {
            offset,
            count: 0,
            ..base
        });
        self.ctx.queue.write_buffer(&self.params, 0, &bytes);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &self.bind, &[0]);
            pass.dispatch_workgroups(1, 1, 1);
        }
        self.ctx.queue.submit([enc.finish()]);
        wait(self.ctx)?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    /// Sets the accumulator to zero.
    pub fn clear(&mut self) -> Result<()> {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        enc.clear_buffer(self.accum.buffer(), 0, None);
        self.ctx.queue.submit([enc.finish()]);
        wait(self.ctx)
    }

    /// Adds sample number `sample` of every pixel (random numbers of `seed`) to the
    /// accumulator, simulating `fx` with the robustness settings `rob`, and waits for it.
    /// Returns the pass's wall time in milliseconds.
    pub fn add_sample(
        &mut self,
        fx: EffectSet,
        rob: Robustness,
        seed: u32,
        sample: u32,
    ) -> Result<f64> {
        rob.check_gpu()?;
        let start = std::time::Instant::now();
        let pipeline = self.pipeline(fx, rob)?;
        let base = self.base;
        let bytes = self.chunks.uniforms(|offset, count| RenderParams {
            seed,
            sample,
            offset,
            count,
            ..base
        });
        self.ctx.queue.write_buffer(&self.params, 0, &bytes);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.chunks
            .record(&mut enc, &pipeline, &self.bind, WORKGROUP, None);
        self.ctx.queue.submit([enc.finish()]);
        wait(self.ctx)?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    /// The AOVs sample 0 wrote (the renderer was made with `aovs`), one per pixel of the
    /// crop, row-major. Pixels the driver cut short hold wrong values (see
    /// [`GpuRenderer::read_accum`]).
    pub fn read_aovs(&self) -> Result<Vec<FirstHit>> {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let n = self.chunks.items as u64;
        let readback = Readback::record(self.ctx, &mut enc, &[(self.accum.buffer(), n * 48)]);
        self.ctx.queue.submit([enc.finish()]);
        let bytes = readback.read(self.ctx)?;
        let px: Vec<[f32; 8]> = bytemuck::pod_collect_to_vec(&bytes[0][n as usize * 16..]);
        Ok(px
            .iter()
            .map(|p| match p[0] < 0.0 {
                true => FirstHit::MISS,
                false => FirstHit {
                    depth: p[0],
                    normal: Vec3::new(p[1], p[2], p[3]),
                    albedo: Vec3::new(p[4], p[5], p[6]),
                    occlusion: p[7],
                },
            })
            .collect())
    }

    /// The accumulated sums, one per pixel of the crop, row-major, and for each pixel the
    /// number of its samples in which the driver cut a traversal short (those sums are
    /// wrong).
    pub fn read_accum(&self) -> Result<(Vec<Vec3>, Vec<u32>)> {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let size = self.chunks.items as u64 * 16;
        let readback = Readback::record(self.ctx, &mut enc, &[(self.accum.buffer(), size)]);
        self.ctx.queue.submit([enc.finish()]);
        let bytes = readback.read(self.ctx)?;
        let px: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[0]);
        let sums = px.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
        let cut = px.iter().map(|p| p[3] as u32).collect();
        Ok((sums, cut))
    }
}

/// The tangents of the triangles' corners 1 and 2 as the kernel reads them, two triangles
/// a word, padded to whole [`GpuShade`]s: empty without tangents.
fn other_tangents(scene: &RenderScene) -> Vec<GpuShade> {
    let mut words: Vec<u32> = (scene.tangents.iter()).flat_map(|t| [t[1], t[2]]).collect();
    let per_shade = std::mem::size_of::<GpuShade>() / 4;
    words.resize(words.len().next_multiple_of(per_shade), NO_TANGENT);
    bytemuck::pod_collect_to_vec(&words)
}

/// The emissive triangles and the running sum of their areas, as the kernel reads them.
fn emitter_words(scene: &RenderScene) -> Vec<[u32; 2]> {
    (scene.emitters.iter().zip(&scene.emitter_cdf))
        .map(|(&p, &c)| [p, c.to_bits()])
        .collect()
}

/// Sets the camera's frame and image size in `params` from `scene`'s camera.
fn set_view(params: &mut RenderParams, scene: &RenderScene) {
    let f = scene.camera.frame();
    params.eye = f.eye.into();
    params.width = scene.camera.width;
    params.fwd = f.fwd.into();
    params.height = scene.camera.height;
    params.right = f.right.into();
    params.inv_w2 = f.inv_w2;
    params.up = f.up.into();
    params.inv_h2 = f.inv_h2;
}

/// The scene's placements as the kernel reads them, padded to a whole number of
/// [`GpuShade`]s (five placements fill seven): empty without placements.
fn placements_of(scene: &RenderScene) -> Vec<GpuPlacement> {
    let Some(pl) = &scene.placements else {
        return Vec::new();
    };
    let set = pl.set();
    let mut v: Vec<GpuPlacement> = (set.instances.iter().enumerate())
        .map(|(i, inst)| GpuPlacement {
            to_world: inst.to_world,
            to_object: pl.to_object()[i],
            first_prim: pl.first_prims()[i],
            shade_base: pl.mesh_base()[inst.mesh as usize],
            _pad: [0; 2],
        })
        .collect();
    v.resize(v.len().next_multiple_of(5), bytemuck::Zeroable::zeroed());
    v
}
