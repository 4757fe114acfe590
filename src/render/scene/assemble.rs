//! A scene ready to render: every object's triangles in one mesh (triangle index = the
//! order of objects in the file, then file order within each), per-triangle materials
//! and texture coordinates, lights, and the emissive triangles that act as area lights.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec2, Vec3};

use super::environment::environment_of;
use super::file::{
    line_of, Integrator, LightKind, Lines, MaterialDef, MaterialKind, ObjectDef, Scale, SceneFile,
};
use super::placements::{Motion, PlacedTriangle, Placements};
use super::shapes;
use super::tangents::{self, tangents_of, TangentInputs};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::geometry::{unpack_unit, Aabb, Affine, Triangle};
use crate::geometry::{NO_NORMAL, NO_TANGENT};
use crate::mesh::{
    check_traceable, classify, warn_exclusions, Instance, InstanceSet, Mesh, ObjScene, TriStatus,
};
use crate::render::environment::Environment;

/// A surface's material, as both renderers shade it.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// How the surface reflects, refracts or emits.
    pub kind: MaterialKind,
    /// Linear RGB reflectance / transmittance tint.
    pub albedo: Vec3,
    /// Emitted radiance, linear RGB (zero unless emissive).
    pub emission: Vec3,
    /// Index of refraction (glass; 1 otherwise).
    pub ior: f32,
    /// Index into [`RenderScene::textures`] of a diffuse or base colour texture, which
    /// multiplies `albedo`.
    pub texture: Option<usize>,
    /// Emissive: emits from both faces (default: the front face only, the one the
    /// vertices' winding makes the normal of — the convention of Mitsuba and pbrt).
    /// Principled: emits from both faces.
    pub two_sided: bool,
    /// Principled: metalness in [0, 1].
    pub metallic: f32,
    /// Principled: perceptual roughness in [0, 1] (GGX α = roughness²).
    pub roughness: f32,
    /// Principled: index into [`RenderScene::textures`] of glTF's metallic-roughness
    /// texture (linear; its green channel scales `roughness`, its blue `metallic`).
    pub metallic_roughness_texture: Option<usize>,
    /// Principled: index into [`RenderScene::textures`] of a texture that multiplies
    /// `emission`.
    pub emission_texture: Option<usize>,
    /// Diffuse and principled: index into [`RenderScene::textures`] of a tangent-space
    /// normal map (linear; glTF's convention: red along +u, green along +v, blue out).
    pub normal_texture: Option<usize>,
    /// The normal map's scale of its red and green (glTF's `normalTexture.scale`).
    pub normal_scale: f32,
    /// Principled: index into [`RenderScene::textures`] of an ambient-occlusion texture
    /// (linear, red channel; glTF's `occlusionTexture`), read for the occlusion AOV only.
    pub occlusion_texture: Option<usize>,
    /// The occlusion texture's strength: occlusion = 1 + strength · (red − 1).
    pub occlusion_strength: f32,
    /// Opacity (glTF's base colour alpha), multiplied by `texture`'s alpha channel where
    /// it has one; read only for an alpha mask.
    pub alpha: f32,
    /// An alpha mask (glTF's alpha mode `MASK`): where the alpha is below this cutoff the
    /// surface is not there — rays pass through it, shadow rays included. None: opaque.
    pub alpha_cutoff: Option<f32>,
    /// Stochastic transparency (glTF's alpha mode `BLEND`): the surface is there at a hit
    /// with probability alpha, decided by a hash of the hit (so rays, jittered from sample
    /// to sample, average to the blend).
    pub alpha_blend: bool,
    /// Where each of its textures is read, by [`TextureSlot`]: the interpolated texture
    /// coordinates moved by this 2 × 3 map (rows; a glTF texture's `KHR_texture_transform`
    /// relative to the material's interpolated set) where the `texture-transforms` effect
    /// is simulated; None: where they are.
    pub uv_transforms: [Option<[[f32; 3]; 2]>; 5],
}

/// Which of a material's textures a lookup reads (the index of its
/// [`Material::uv_transforms`]; WGSL `UV_SLOT_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureSlot {
    /// [`Material::texture`] (base colour, and its alpha).
    Base = 0,
    /// [`Material::metallic_roughness_texture`].
    MetallicRoughness = 1,
    /// [`Material::emission_texture`].
    Emission = 2,
    /// [`Material::normal_texture`].
    Normal = 3,
    /// [`Material::occlusion_texture`].
    Occlusion = 4,
}

impl Material {
    /// An untextured diffuse material of linear RGB reflectance `albedo`.
    pub fn diffuse(albedo: Vec3) -> Material {
        Material {
            kind: MaterialKind::Diffuse,
            albedo,
            emission: Vec3::ZERO,
            ior: 1.0,
            texture: None,
            two_sided: false,
            metallic: 0.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            emission_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            alpha: 1.0,
            alpha_cutoff: None,
            alpha_blend: false,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            uv_transforms: [None; 5],
        }
    }

    /// An untextured glTF metallic-roughness material.
    pub fn principled(base_color: Vec3, metallic: f32, roughness: f32) -> Material {
        Material {
            kind: MaterialKind::Principled,
            metallic,
            roughness,
            ..Material::diffuse(base_color)
        }
    }

    /// Whether the material reads any texture.
    pub fn textured(&self) -> bool {
        self.texture.is_some()
            || self.metallic_roughness_texture.is_some()
            || self.emission_texture.is_some()
            || self.occlusion_texture.is_some()
    }

    /// The texture in `slot` (an index into [`RenderScene::textures`]).
    pub fn texture_in(&self, slot: TextureSlot) -> Option<usize> {
        match slot {
            TextureSlot::Base => self.texture,
            TextureSlot::MetallicRoughness => self.metallic_roughness_texture,
            TextureSlot::Emission => self.emission_texture,
            TextureSlot::Normal => self.normal_texture,
            TextureSlot::Occlusion => self.occlusion_texture,
        }
    }

    /// Whether a texture it reads is read at moved coordinates.
    pub fn moves_textures(&self) -> bool {
        self.uv_transforms.iter().any(Option::is_some)
    }
}

/// A texture in linear RGB, row 0 at the top (v = 1).
#[derive(Clone, Debug)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width · height` texels, row-major from the top row.
    pub texels: Vec<Vec3>,
    /// Their alpha (linear, in [0, 1]), or empty where the image has no alpha channel
    /// (opaque everywhere; so is an alpha of another length than `texels`).
    pub alpha: Vec<f32>,
}

/// A point or directional light (area lights are the emissive triangles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity from a point.
    Point {
        /// Position, scene space.
        position: Vec3,
        /// Radiant intensity, linear RGB (falls off with 1/d²).
        intensity: Vec3,
    },
    /// Irradiance arriving along `direction` (unit, the way the light travels).
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light, linear RGB.
        irradiance: Vec3,
    },
    /// Radiant intensity from a point into a cone ([`Light::spot`]).
    Spot {
        /// Position, scene space.
        position: Vec3,
        /// Unit direction of the cone's axis.
        direction: Vec3,
        /// Radiant intensity on the axis, linear RGB.
        intensity: Vec3,
        /// The falloff: a direction at cosine c to the axis gets the intensity times
        /// clamp(c·scale + offset, 0, 1)² (glTF's `KHR_lights_punctual` formula).
        scale: f32,
        /// See `scale`.
        offset: f32,
    },
}

/// The luminous efficacy glTF's photometric light units are divided by ([`Light::from_gltf`]).
pub const LUMENS_PER_WATT: f32 = 683.0;

impl Light {
    /// A spot light at `position` shining along `direction` (unit), with `intensity` on
    /// its axis, full within `inner` radians of it and none beyond `outer` (inner <
    /// outer ≤ π/2, as glTF has them).
    pub fn spot(position: Vec3, direction: Vec3, intensity: Vec3, inner: f32, outer: f32) -> Light {
        let (ci, co) = (inner.cos(), outer.cos());
        let scale = 1.0 / (ci - co).max(1e-3);
        Light::Spot {
            position,
            direction,
            intensity,
            scale,
            offset: -co * scale,
        }
    }

    /// A glTF punctual light in lancer's radiometric units: candela and lux over 683 lm/W
    /// (the luminous efficacy glTF exporters such as Blender's multiply by), so a 1 W
    /// Blender point light is 1/(4π) W/sr and a sun of strength 1 is 1 W/m².
    pub fn from_gltf(l: &crate::mesh::GltfLight) -> Light {
        use crate::mesh::GltfLightKind;
        let power = l.photometric / LUMENS_PER_WATT;
        match l.kind {
            GltfLightKind::Point => Light::Point {
                position: l.position,
                intensity: power,
            },
            GltfLightKind::Spot { inner, outer } => {
                Light::spot(l.position, l.direction, power, inner, outer)
            }
            GltfLightKind::Directional => Light::Directional {
                direction: l.direction,
                irradiance: power,
            },
        }
    }

    /// The fraction of a spot light's intensity that goes at cosine `c` to its axis.
    pub fn spot_falloff(c: f32, scale: f32, offset: f32) -> f32 {
        let a = (c * scale + offset).clamp(0.0, 1.0);
        a * a
    }
}

/// How to render: the scene file's `[render]` table, defaults filled in.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The light transport algorithm.
    pub integrator: Integrator,
    /// Most bounces after the primary hit (diffuse, mirror or glass).
    pub max_bounces: u32,
    /// Samples per pixel (at least 1).
    pub spp: u32,
    /// Random seed, hashed with the pixel and sample index.
    pub seed: u32,
    /// Ambient-occlusion ray length, scene units; when not set (≤ 0), assembly makes it a
    /// tenth of the scene's bounding-box diagonal.
    pub ao_distance: f32,
}

impl Settings {
    /// Refuses settings a render cannot run with: no sample per pixel, more bounces than
    /// [`MAX_BOUNCES`](crate::limits::MAX_BOUNCES), an AO distance that is not a finite
    /// length (≤ 0: a tenth of the scene's diagonal).
    pub fn check(&self) -> std::result::Result<(), String> {
        let max = crate::limits::MAX_BOUNCES;
        if self.spp == 0 {
            return Err("spp must be at least 1".into());
        }
        if self.max_bounces > max {
            return Err(format!(
                "max_bounces is {}, more than {max} (paths follow every bounce: each sample \
                 of a closed scene would take that many); set it to at most {max}",
                self.max_bounces
            ));
        }
        if !self.ao_distance.is_finite() {
            return Err(format!(
                "ao_distance must be a finite distance, got {}",
                self.ao_distance
            ));
        }
        Ok(())
    }
}

/// A scene ready to render: one mesh with per-triangle texture coordinates and materials,
/// lights, and the emissive triangles that act as area lights. A scene that places an
/// object more than once keeps each object once, with its placements.
#[derive(Clone, Debug)]
pub struct RenderScene {
    /// The view and image size.
    pub camera: Camera,
    /// Integrator and sampling settings.
    pub settings: Settings,
    /// Every object's triangles: objects in file order, then file order within each. With
    /// [`placements`](Self::placements), each object once, as its placements' meshes; the
    /// triangles rendered are numbered as those placements number them ([`Self::triangle`]).
    pub mesh: Mesh,
    /// Texture coordinates of the vertices of each triangle of [`Self::mesh`].
    pub uvs: Vec<[Vec2; 3]>,
    /// Shading normals of the vertices of each triangle of [`Self::mesh`] (in its object's
    /// space where it is placed), packed ([`pack_unit`](crate::geometry::pack_unit));
    /// [`NO_NORMAL`] on a triangle that shades flat. Empty where no triangle has normals.
    pub normals: Vec<[u32; 3]>,
    /// The tangents at the vertices of each triangle of [`Self::mesh`] whose material has a
    /// normal map (in its object's space where it is placed): a file's own (glTF
    /// `TANGENT`), else generated MikkTSpace-style (welded corners averaged); each packed
    /// with its handedness relative to the triangle's winding
    /// ([`pack_tangent`](crate::geometry::pack_tangent)). [`NO_TANGENT`] three times
    /// elsewhere; empty where no material has a normal map.
    pub tangents: Vec<[u32; 3]>,
    /// Material index of each triangle of [`Self::mesh`].
    pub material_of: Vec<u32>,
    /// Distinct materials, indexed by `material_of`.
    pub materials: Vec<Material>,
    /// Textures, indexed by [`Material::texture`].
    pub textures: Vec<Texture>,
    /// Point and directional lights.
    pub lights: Vec<Light>,
    /// Light from infinitely far away, seen by rays that leave the scene; None: black.
    pub environment: Option<Environment>,
    /// Emissive triangles by number (area lights), with the running sum of their areas.
    pub emitters: Vec<u32>,
    /// Running sum of the emitters' areas: `emitter_cdf[i]` = area of `emitters[..=i]`.
    pub emitter_cdf: Vec<f32>,
    /// Where the scene places objects more than once (`copies`, `grid`): the objects as
    /// meshes placed by instances, rendered in two levels. None: [`Self::mesh`] is the
    /// scene, in world space.
    pub placements: Option<Placements>,
}

/// sRGB 8-bit → linear, exactly as the image would be displayed.
fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn load_texture(path: &Path, srgb: bool) -> Result<Texture> {
    let bytes = crate::input::read(path)?;
    decode_texture(&bytes, srgb)
        .map_err(|e| Error::input(path, None, format!("cannot read texture: {e}")))
}

/// An image file's bytes (PNG, JPEG, … by their content) decoded as a linear texture from
/// sRGB (colours), or as they are (`srgb` false: data such as glTF's metallic-roughness,
/// scaled to [0, 1]). Its size is read from its header and checked first — at least one
/// texel, at most [`MAX_TEXTURE_SIDE`](crate::limits::MAX_TEXTURE_SIDE) a side, and the memory decoding
/// takes (the decoded image, its RGB8 and RGBA8 copies, the f32 texels and alpha) — so
/// nothing is decoded that would not fit. The alpha channel, where there is one, is kept
/// as it is (alpha masks).
pub(super) fn decode_texture(bytes: &[u8], srgb: bool) -> std::result::Result<Texture, String> {
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())
    };
    let (width, height) = reader()?.into_dimensions().map_err(|e| e.to_string())?;
    if width == 0 || height == 0 {
        return Err(format!(
            "a {width}×{height} texture has no texels: give an image of at least one pixel"
        ));
    }
    let side = crate::limits::MAX_TEXTURE_SIDE;
    if width > side || height > side {
        return Err(format!(
            "a {width}×{height} texture is larger than {side} a side: scale it down"
        ));
    }
    crate::limits::check_image(width, height, 16 + 4 + 3 + 12 + 4, "scale the texture down")
        .map_err(|e| e.to_string())?;
    let decoded = crate::limits::decode_checked(reader()?, 16 * width as u64 * height as u64)
        .map_err(|e| e.to_string())?;
    // Alpha is data (glTF: linear, never sRGB-encoded), kept only where the image has it.
    let alpha = if decoded.color().has_alpha() {
        let a = decoded.to_rgba8();
        a.pixels().map(|p| p[3] as f32 / 255.0).collect()
    } else {
        Vec::new()
    };
    let img = decoded.to_rgb8();
    let lut: Vec<f32> = (0..=255u8)
        .map(|c| {
            if srgb {
                srgb_to_linear(c)
            } else {
                c as f32 / 255.0
            }
        })
        .collect();
    Ok(Texture {
        width: img.width(),
        height: img.height(),
        texels: img
            .pixels()
            .map(|p| Vec3::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]))
            .collect(),
        alpha,
    })
}

/// Accumulates objects into one mesh.
#[derive(Default)]
pub(super) struct Builder {
    pub(super) triangles: Vec<Triangle>,
    pub(super) status: Vec<TriStatus>,
    uvs: Vec<[Vec2; 3]>,
    /// Packed corner normals, by triangle from the first object that has any (empty
    /// before: [`Builder::push`] fills the triangles before it flat).
    normals: Vec<[u32; 3]>,
    /// A file's own packed corner tangents ([`Builder::give_tangents`]), by triangle from
    /// the first that has any ([`NO_TANGENT`] before, and where none is given).
    tangents: Vec<[u32; 3]>,
    material_of: Vec<u32>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    texture_ids: HashMap<PathBuf, usize>,
    pub(super) short_faces: usize,
    /// Triangles with a texture coordinate that is not finite (read as 0 there).
    unfinite_uvs: usize,
    /// Every file read: the scene, meshes, MTL libraries, textures.
    pub(super) sources: Vec<PathBuf>,
    /// The triangles as meshes placed by instances: where each mesh starts (its triangles
    /// run to the next one's start), and the instances in numbering order. Used where
    /// `placed` (a mesh placed other than once as it is).
    pub(super) mesh_starts: Vec<usize>,
    pub(super) instances: Vec<Instance>,
    pub(super) placed: bool,
    /// Each instance's motion from frame to frame, where a scene file gives any (else
    /// empty: nothing moves).
    motions: Vec<Motion>,
    /// A glTF file's animation and the first instance it places, where a file added by
    /// [`Builder::add_placed_file`] moves its meshes.
    pub(super) animation: Option<(usize, crate::mesh::GltfAnimation)>,
    /// The perspective cameras of a glTF file added by [`Builder::add_placed_file`].
    pub(super) cameras: Vec<crate::mesh::GltfCamera>,
    /// The punctual lights of a glTF file added by [`Builder::add_placed_file`].
    pub(super) gltf_lights: Vec<crate::mesh::GltfLight>,
}

impl Builder {
    /// The index of the texture in image file `path`, read from sRGB (`srgb`) or as data.
    fn texture(&mut self, path: &Path, srgb: bool) -> Result<usize> {
        // The same file read both ways is two textures.
        let key = if srgb {
            path.to_path_buf()
        } else {
            PathBuf::from(format!("{}#linear", path.display()))
        };
        let known = self.texture_ids.contains_key(&key);
        let i = self.texture_with(key, || load_texture(path, srgb))?;
        if !known {
            self.sources.push(path.to_path_buf());
        }
        Ok(i)
    }

    /// The index of the texture under `key`, made by `load` the first time.
    pub(super) fn texture_with(
        &mut self,
        key: PathBuf,
        load: impl FnOnce() -> Result<Texture>,
    ) -> Result<usize> {
        if let Some(&i) = self.texture_ids.get(&key) {
            return Ok(i);
        }
        self.textures.push(load()?);
        self.texture_ids.insert(key, self.textures.len() - 1);
        Ok(self.textures.len() - 1)
    }

    pub(super) fn material(&mut self, m: Material) -> u32 {
        if let Some(i) = self.materials.iter().position(|x| *x == m) {
            return i as u32;
        }
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Adds an OBJ's triangles, transformed; `material` overrides its MTL materials,
    /// `grey` stands in for faces with none.
    pub(super) fn add_obj(
        &mut self,
        obj: &ObjScene,
        path: &Path,
        material: Option<u32>,
        grey: u32,
        xf: impl Fn(Vec3) -> Vec3,
        nm: NormalMap,
    ) -> Result<()> {
        if let Some(e) = &obj.mtl_error {
            log::warn!("{}: materials not read ({e}); using grey", path.display());
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut mtl = Vec::new();
        for mm in &obj.materials {
            let m = mtl_material(self, &dir, mm)?;
            mtl.push(self.material(m));
        }
        for (i, tri) in obj.mesh.triangles.iter().enumerate() {
            let id = material.unwrap_or_else(|| {
                obj.material_ids[i]
                    .and_then(|k| mtl.get(k).copied())
                    .unwrap_or(grey)
            });
            let t = Triangle::new(xf(tri.v[0]), xf(tri.v[1]), xf(tri.v[2]));
            let n = map_normals(nm, obj.normals.get(i));
            self.push(t, obj.mesh.status[i], obj.uvs[i], n, id);
        }
        warn_exclusions(path, &obj.mesh);
        self.short_faces += obj.mesh.short_faces;
        self.sources.extend(obj.mesh.sources.iter().cloned());
        Ok(())
    }

    /// Adds a built-in shape, transformed, in one material; `smooth`: with its vertices as
    /// normals (a unit sphere's), else flat.
    fn add_shape(
        &mut self,
        (tris, uvs): shapes::ShapeMesh,
        material: u32,
        xf: impl Fn(Vec3) -> Vec3,
        smooth: Option<NormalMap>,
    ) {
        for (tri, uv) in tris.iter().zip(uvs) {
            let t = Triangle::new(xf(tri.v[0]), xf(tri.v[1]), xf(tri.v[2]));
            let n = match smooth {
                Some(nm) => map_normals(nm, Some(&crate::mesh::pack_corners(tri.v))),
                None => [NO_NORMAL; 3],
            };
            self.push(t, TriStatus::Ok, uv, n, material);
        }
    }

    /// Starts a mesh at the next triangle, placed by `maps` (after the instances so far).
    pub(super) fn start_mesh(&mut self, maps: impl IntoIterator<Item = Affine>) {
        let mesh = self.mesh_starts.len() as u32;
        self.mesh_starts.push(self.triangles.len());
        (self.instances).extend(maps.into_iter().map(|to_world| Instance { mesh, to_world }));
    }

    pub(super) fn push(
        &mut self,
        t: Triangle,
        status: TriStatus,
        uv: [Vec2; 3],
        normals: [u32; 3],
        material: u32,
    ) {
        // NaN or infinite coordinates (a file's) would wrap to texels that differ between
        // devices: read as 0, and counted.
        let uv = if uv.iter().all(|c| c.is_finite()) {
            uv
        } else {
            self.unfinite_uvs += 1;
            uv.map(|c| Vec2::select(c.is_finite_mask(), c, Vec2::ZERO))
        };
        // A transform can make a good triangle degenerate or overflow: classify again.
        let status = match status {
            TriStatus::Ok => classify(&t),
            s => s,
        };
        if normals[0] != NO_NORMAL || !self.normals.is_empty() {
            self.normals.resize(self.triangles.len(), [NO_NORMAL; 3]);
            self.normals.push(normals);
        }
        self.triangles.push(t);
        self.status.push(status);
        self.uvs.push(uv);
        self.material_of.push(material);
    }

    /// Gives the last triangle pushed the file's corner tangents `t` (packed, handedness
    /// relative to its winding as pushed).
    pub(super) fn give_tangents(&mut self, t: [u32; 3]) {
        if t[0] == NO_TANGENT && self.tangents.is_empty() {
            return;
        }
        self.tangents
            .resize(self.triangles.len() - 1, [NO_TANGENT; 3]);
        self.tangents.push(t);
    }
}

/// How an object's map moves its normals: by the inverse transpose of its linear part;
/// None: as they are (the packed words kept). A map's `Some(None)` at a call that takes
/// `Option<NormalMap>` keeps normals, where `None` drops them (flat shading).
pub(super) type NormalMap = Option<Mat3>;

/// A triangle's packed corner normals moved by `nm` ([`NO_NORMAL`] where it has none).
pub(super) fn map_normals(nm: NormalMap, n: Option<&[u32; 3]>) -> [u32; 3] {
    match (nm, n) {
        (_, None) => [NO_NORMAL; 3],
        (_, Some(n)) if n[0] == NO_NORMAL => [NO_NORMAL; 3],
        (None, Some(n)) => *n,
        (Some(m), Some(n)) => crate::mesh::pack_corners(n.map(|w| m * unpack_unit(w))),
    }
}

/// Material from an MTL entry: Kd (or map_Kd) diffuse, Ke emissive, illum 5 mirror,
/// illum 7 glass with Ni.
fn mtl_material(b: &mut Builder, dir: &Path, m: &tobj::Material) -> Result<Material> {
    // Above 1 is clamped (mtl::check warned with the MTL's line).
    let kd = Vec3::from(m.diffuse.unwrap_or([0.7; 3])).min(Vec3::ONE);
    let ke = Vec3::from(m.emissive.unwrap_or([0.0; 3]));
    let mut mat = Material::diffuse(kd);
    if ke.max_element() > 0.0 {
        mat.kind = MaterialKind::Emissive;
        mat.emission = ke;
    } else if m.illumination_model == Some(5) {
        mat.kind = MaterialKind::Mirror;
        mat.albedo = Vec3::from(m.specular.unwrap_or([1.0; 3]));
    } else if m.illumination_model == Some(7) {
        mat.kind = MaterialKind::Glass;
        mat.albedo = Vec3::ONE;
        mat.ior = m.optical_density.unwrap_or(1.5);
    } else if let Some(t) = &m.diffuse_texture {
        // map_Kd replaces Kd (textures multiply the albedo: make it 1).
        mat.albedo = Vec3::ONE;
        let file = dir.join(t);
        mat.texture = Some(b.texture(&file, true).map_err(|e| {
            Error::input(
                &file,
                None,
                format!("map_Kd of MTL material {:?}: {}", m.name, error_message(&e)),
            )
        })?);
    }
    Ok(mat)
}

/// Adds one object (a mesh file or a shape) under its own transform, in `mat` (None: the
/// file's materials, `grey` where it has none); `bad` names its line in the scene file.
fn add_object(
    b: &mut Builder,
    dir: &Path,
    o: &ObjectDef,
    mat: Option<u32>,
    grey: u32,
    bad: &dyn Fn(String) -> Error,
) -> Result<()> {
    check_placement(&o.scale, &o.rotate, &o.translate).map_err(bad)?;
    let (m, t) = transform(o);
    let xf = |p: Vec3| m * p + t;
    // Normals keep their packed words where the object is not turned or scaled.
    let nm = (m != Mat3::IDENTITY).then(|| m.inverse().transpose());
    if o.smooth == Some(true) && o.shape.is_some_and(|s| s != super::file::Shape::Sphere) {
        return Err(bad(
            "'smooth' applies to spheres and meshes (a box, quad or stadium is flat)".into(),
        ));
    }
    let smooth = o.smooth != Some(false);
    match (&o.mesh, o.shape) {
        (Some(file), None) => {
            b.add_mesh_file(&dir.join(file), mat, grey, xf, smooth.then_some(nm))?;
        }
        (None, Some(shape)) => {
            let shape = match shape {
                super::file::Shape::Quad => shapes::quad(),
                super::file::Shape::Box => shapes::cube(),
                round @ (super::file::Shape::Sphere | super::file::Shape::Stadium) => {
                    let sphere = round == super::file::Shape::Sphere;
                    let what = if sphere { "sphere" } else { "stadium" };
                    if o.segments < 3 {
                        return Err(bad(format!(
                            "'segments' must be at least 3, got {}",
                            o.segments
                        )));
                    }
                    // ~256 bytes a triangle through the BVH build.
                    let n = o.segments as u128;
                    let tris = match sphere {
                        true => n * n,
                        false => n * shapes::STADIUM_TRIS_PER_SEGMENT as u128,
                    };
                    if tris >= u32::MAX as u128 / 2 {
                        return Err(bad(format!(
                            "'segments' {} makes {tris} triangles, more than lancer \
                                 indexes: use fewer",
                            o.segments
                        )));
                    }
                    crate::limits::check_memory(
                        &format!("a {what} of {} segments ({tris} triangles)", o.segments),
                        tris * 256,
                        "use fewer segments",
                    )
                    .map_err(|e| bad(error_message(&e)))?;
                    match sphere {
                        true => shapes::sphere(o.segments),
                        false => shapes::stadium(o.segments),
                    }
                }
            };
            let round = o.shape == Some(super::file::Shape::Sphere);
            b.add_shape(
                shape,
                mat.unwrap_or(grey),
                xf,
                (smooth && round).then_some(nm),
            );
        }
        _ => {
            return Err(bad(
                "an object needs exactly one of 'mesh' and 'shape'".into()
            ))
        }
    }
    Ok(())
}

/// An object's placements, each a transform applied after its own: its `copies`, or its
/// `grid` (x fastest, then y, then z); None when it has neither (placed once, as it is).
fn copies_of(o: &ObjectDef) -> std::result::Result<Option<Vec<(Mat3, Vec3)>>, String> {
    let copies: Vec<(Mat3, Vec3)> = match (&o.copies[..], &o.grid) {
        ([], None) => return Ok(None),
        ([_, ..], Some(_)) => return Err("use one of 'copies' and 'grid', not both".into()),
        (copies, None) => {
            let mut out = Vec::with_capacity(copies.len());
            for c in copies {
                check_placement(&c.scale, &c.rotate, &c.translate)?;
                out.push(transform_of(&c.scale, &c.rotate, &c.translate));
            }
            out
        }
        ([], Some(g)) => {
            // u32 counts: the product of three fits in u128, not always in u64.
            let n: u128 = g.count.iter().map(|&c| c as u128).product();
            if n == 0 || n > MAX_COPIES as u128 {
                return Err(format!(
                    "'grid' count {:?} makes {n} copies: give 1 to {MAX_COPIES}",
                    g.count
                ));
            }
            if !g.step.iter().all(|x| x.is_finite()) {
                return Err("'grid' step must be finite numbers".into());
            }
            let [nx, ny, nz] = g.count;
            let mut out = Vec::with_capacity(n as usize);
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        let at = Vec3::new(i as f32, j as f32, k as f32) * Vec3::from(g.step);
                        out.push((Mat3::IDENTITY, at));
                    }
                }
            }
            out
        }
    };
    if copies.len() as u64 > MAX_COPIES {
        return Err(format!(
            "{} copies: give at most {MAX_COPIES}",
            copies.len()
        ));
    }
    Ok(Some(copies))
}

/// Most copies of one object.
const MAX_COPIES: u64 = 10_000_000;

/// Refuses a non-finite or zero scale, and non-finite angles or offsets.
fn check_placement(
    scale: &Scale,
    rotate: &[f32; 3],
    translate: &[f32; 3],
) -> std::result::Result<(), String> {
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    let scale_ok = match scale {
        Scale::Uniform(s) => s.is_finite() && *s != 0.0,
        Scale::Axes(a) => finite(a) && a.iter().all(|&x| x != 0.0),
    };
    if !scale_ok {
        return Err("'scale' must be finite and non-zero".into());
    }
    if !finite(rotate) || !finite(translate) {
        return Err("'rotate' and 'translate' must be finite numbers".into());
    }
    Ok(())
}

fn transform(o: &ObjectDef) -> (Mat3, Vec3) {
    transform_of(&o.scale, &o.rotate, &o.translate)
}

/// Scale, then rotation about X, Y and Z (degrees), then translation.
fn transform_of(scale: &Scale, rotate: &[f32; 3], translate: &[f32; 3]) -> (Mat3, Vec3) {
    let s = match *scale {
        Scale::Uniform(s) => Vec3::splat(s),
        Scale::Axes(a) => Vec3::from(a),
    };
    let [rx, ry, rz] = rotate.map(f32::to_radians);
    let r = Mat3::from_rotation_z(rz) * Mat3::from_rotation_y(ry) * Mat3::from_rotation_x(rx);
    (r * Mat3::from_diagonal(s), Vec3::from(*translate))
}

fn check_rgb(path: &Path, line: usize, what: &str, c: [f32; 3]) -> Result<Vec3> {
    if c.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(Error::input(
            path,
            Some(line),
            format!("{what} must be finite and non-negative, got {c:?}"),
        ));
    }
    Ok(Vec3::from(c))
}

fn scene_material(
    b: &mut Builder,
    path: &Path,
    dir: &Path,
    line: usize,
    name: &str,
    d: &MaterialDef,
) -> Result<Material> {
    let bad = |msg: String| Error::input(path, Some(line), format!("material {name:?}: {msg}"));
    let only = |field: &str, set: bool, kinds: &str| {
        if set {
            Err(bad(format!("'{field}' applies to {kinds} materials only")))
        } else {
            Ok(())
        }
    };
    let mut m = Material::diffuse(Vec3::ONE);
    m.kind = d.kind;
    let principled = d.kind == MaterialKind::Principled;
    only(
        "texture",
        d.texture.is_some() && !matches!(d.kind, MaterialKind::Diffuse | MaterialKind::Principled),
        "diffuse and principled",
    )?;
    only(
        "ior",
        d.ior.is_some() && d.kind != MaterialKind::Glass,
        "glass",
    )?;
    only(
        "emission",
        d.emission.is_some()
            && !matches!(d.kind, MaterialKind::Emissive | MaterialKind::Principled),
        "emissive and principled",
    )?;
    only(
        "two_sided",
        d.two_sided && d.kind != MaterialKind::Emissive,
        "emissive",
    )?;
    for (field, set) in [
        ("base_color", d.base_color.is_some()),
        ("metallic", d.metallic.is_some()),
        ("roughness", d.roughness.is_some()),
        (
            "metallic_roughness_texture",
            d.metallic_roughness_texture.is_some(),
        ),
        ("emission_texture", d.emission_texture.is_some()),
        ("occlusion_texture", d.occlusion_texture.is_some()),
        ("occlusion_strength", d.occlusion_strength.is_some()),
    ] {
        only(field, set && !principled, "principled")?;
    }
    for (field, set) in [
        ("normal_texture", d.normal_texture.is_some()),
        ("normal_scale", d.normal_scale.is_some()),
    ] {
        let shaded = matches!(d.kind, MaterialKind::Diffuse | MaterialKind::Principled);
        only(field, set && !shaded, "diffuse and principled")?;
    }
    only(
        "alpha_cutoff",
        d.alpha_cutoff.is_some() && d.kind == MaterialKind::Emissive,
        "non-emissive",
    )?;
    only(
        "alpha_blend",
        d.alpha_blend && d.kind == MaterialKind::Emissive,
        "non-emissive",
    )?;
    if d.alpha_blend && d.alpha_cutoff.is_some() {
        return Err(bad(
            "'alpha_blend' and 'alpha_cutoff' exclude each other: a blend or a mask".into(),
        ));
    }
    if d.alpha.is_some() && d.alpha_cutoff.is_none() && !d.alpha_blend {
        return Err(bad(
            "'alpha' is read by an alpha mask or blend only: give 'alpha_cutoff' or \
             'alpha_blend = true' too"
                .into(),
        ));
    }
    for (field, value) in [("alpha_cutoff", d.alpha_cutoff), ("alpha", d.alpha)] {
        match value {
            Some(x) if !(0.0..=1.0).contains(&x) => {
                return Err(bad(format!("{field} must be in [0, 1], got {x}")));
            }
            _ => {}
        }
    }
    m.alpha = d.alpha.unwrap_or(1.0);
    m.alpha_cutoff = d.alpha_cutoff;
    m.alpha_blend = d.alpha_blend;
    if let Some(s) = d.normal_scale {
        if !s.is_finite() {
            return Err(bad(format!("normal_scale must be finite, got {s}")));
        }
        m.normal_scale = s;
    }
    if principled && d.albedo.is_some() {
        return Err(bad(
            "a principled material takes 'base_color', not 'albedo'".into(),
        ));
    }
    if let Some(a) = d.albedo.or(d.base_color) {
        let what = if principled { "base_color" } else { "albedo" };
        m.albedo = check_rgb(path, line, what, a)?;
        if m.albedo.max_element() > 1.0 {
            log::warn!(
                "{}:{line}: {what} {a:?} reflects more light than arrives; clamped to 1",
                path.display()
            );
            m.albedo = m.albedo.min(Vec3::ONE);
        }
    } else if d.kind == MaterialKind::Diffuse && d.texture.is_none() {
        m.albedo = Vec3::splat(0.7);
    } else if principled && d.texture.is_none() {
        m.albedo = Vec3::splat(0.8);
    }
    match d.kind {
        MaterialKind::Emissive => {
            let e = d
                .emission
                .ok_or_else(|| bad("needs 'emission = [r, g, b]'".into()))?;
            m.emission = check_rgb(path, line, "emission", e)?;
            m.two_sided = d.two_sided;
        }
        MaterialKind::Glass => {
            m.ior = d.ior.unwrap_or(1.5);
            if !(m.ior >= 1.0 && m.ior <= 4.0) {
                return Err(bad(format!("ior must be in [1, 4], got {}", m.ior)));
            }
        }
        MaterialKind::Principled => {
            let unit = |field: &str, x: Option<f32>, default: f32| match x {
                Some(v) if !(0.0..=1.0).contains(&v) => {
                    Err(bad(format!("{field} must be in [0, 1], got {v}")))
                }
                v => Ok(v.unwrap_or(default)),
            };
            // glTF's defaults: a rough metal; lancer's: a rough dielectric (a plastic).
            m.metallic = unit("metallic", d.metallic, 0.0)?;
            m.roughness = unit("roughness", d.roughness, 0.5)?;
            m.occlusion_strength = unit("occlusion_strength", d.occlusion_strength, 1.0)?;
            if let Some(e) = d.emission {
                m.emission = check_rgb(path, line, "emission", e)?;
            } else if d.emission_texture.is_some() {
                m.emission = Vec3::ONE;
            }
            m.two_sided = true;
        }
        _ => {}
    }
    let mut image = |name: &str, file: &Option<String>, srgb: bool| -> Result<Option<usize>> {
        let Some(t) = file else { return Ok(None) };
        let file = dir.join(t);
        b.texture(&file, srgb).map(Some).map_err(|e| {
            Error::input(
                path,
                Some(line),
                format!("{name} {}: {}", file.display(), error_message(&e)),
            )
        })
    };
    m.texture = image("texture", &d.texture, true)?;
    m.metallic_roughness_texture = image(
        "metallic_roughness_texture",
        &d.metallic_roughness_texture,
        false,
    )?;
    m.emission_texture = image("emission_texture", &d.emission_texture, true)?;
    m.normal_texture = image("normal_texture", &d.normal_texture, false)?;
    m.occlusion_texture = image("occlusion_texture", &d.occlusion_texture, false)?;
    Ok(m)
}

impl RenderScene {
    /// The epsilon of [`RayOffset::Fixed`](crate::geometry::RayOffset::Fixed): a fixed
    /// fraction of the scene's bounding-box diagonal.
    pub fn fixed_offset(&self) -> f32 {
        crate::geometry::FIXED_OFFSET * self.bounds().extent().length()
    }
}

impl RenderScene {
    /// A scene file's objects as meshes placed by instances, where an object has `copies`
    /// or a `grid` (its [`placements`](Self::placements)); None where none has (the
    /// assembled mesh is then no bigger).
    pub fn instances_of_file(path: &Path) -> Result<Option<InstanceSet>> {
        Ok(RenderScene::from_file(path)?
            .placements
            .map(|p| p.set().clone()))
    }

    /// Reads a TOML scene file and everything it names.
    pub fn from_file(path: &Path) -> Result<RenderScene> {
        let src = crate::input::read_text(path)?;
        let f = SceneFile::parse(path, &src)?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let lines = Lines::new(&src);
        let line = |span: std::ops::Range<usize>| lines.of(span.start);
        let mut b = Builder::default();
        b.sources.push(path.to_path_buf());

        let mut named = HashMap::new();
        for (name, d) in &f.materials {
            let m = scene_material(&mut b, path, &dir, line(d.span()), name, d.get_ref())?;
            named.insert(name.clone(), b.material(m));
        }
        let grey = b.material(Material::diffuse(Vec3::splat(0.7)));

        if f.objects.is_empty() {
            return Err(Error::input(
                path,
                None,
                "no [[objects]]: nothing to render",
            ));
        }
        for o in &f.objects {
            let ln = line(o.span());
            let o = o.get_ref();
            let bad = |msg: String| Error::input(path, Some(ln), msg);
            let mat = match &o.material {
                Some(n) => Some(
                    *named
                        .get(n)
                        .ok_or_else(|| bad(format!("no material named {n:?} in [materials]")))?,
                ),
                None => None,
            };
            let copies = copies_of(o).map_err(bad)?;
            if !o.velocity.iter().chain(&o.spin).all(|x| x.is_finite()) {
                return Err(bad("'move' and 'spin' must be finite numbers".into()));
            }
            let (velocity, spin) = (Vec3::from(o.velocity), Vec3::from(o.spin));
            let moves = velocity != Vec3::ZERO || spin != Vec3::ZERO;
            b.placed |= copies.is_some() || moves;
            let copies = copies.unwrap_or_else(|| vec![(Mat3::IDENTITY, Vec3::ZERO)]);
            // Each copy turns about where the object's origin lies in it.
            let origin = Vec3::from(o.translate);
            b.motions.extend(copies.iter().map(|&(m, t)| Motion {
                pivot: m * origin + t,
                velocity,
                spin,
            }));
            b.start_mesh(
                copies
                    .into_iter()
                    .map(|(m, t)| Affine::from_mat3_translation(m, t)),
            );
            add_object(&mut b, &dir, o, mat, grey, &bad)?;
        }

        let mut lights = Vec::new();
        for l in &f.lights {
            let ln = line(l.span());
            let l = l.get_ref();
            let bad = |msg: &str| Error::input(path, Some(ln), msg.to_string());
            if !(l.intensity.is_finite() && l.intensity >= 0.0) {
                return Err(bad("'intensity' must be a finite number ≥ 0"));
            }
            let finite = |v: Option<[f32; 3]>| v.is_none_or(|v| v.iter().all(|x| x.is_finite()));
            if !finite(l.position) || !finite(l.direction) {
                return Err(bad("'position' and 'direction' must be finite numbers"));
            }
            let power = check_rgb(path, ln, "color", l.color)? * l.intensity;
            lights.push(match l.kind {
                LightKind::Point => Light::Point {
                    position: Vec3::from(
                        l.position
                            .ok_or_else(|| bad("a point light needs 'position'"))?,
                    ),
                    intensity: power,
                },
                LightKind::Directional => {
                    let d = Vec3::from(
                        l.direction
                            .ok_or_else(|| bad("a directional light needs 'direction'"))?,
                    );
                    if d.length().is_nan() || d.length() <= 0.0 {
                        return Err(bad("'direction' must not be zero"));
                    }
                    Light::Directional {
                        direction: d.normalize(),
                        irradiance: power,
                    }
                }
                LightKind::Spot => {
                    let (p, d) = match (l.position, l.direction) {
                        (Some(p), Some(d)) => (Vec3::from(p), Vec3::from(d)),
                        _ => return Err(bad("a spot light needs 'position' and 'direction'")),
                    };
                    if d.length().is_nan() || d.length() <= 0.0 {
                        return Err(bad("'direction' must not be zero"));
                    }
                    let (inner, outer) =
                        (l.inner_angle.unwrap_or(0.0), l.outer_angle.unwrap_or(45.0));
                    if !(0.0 <= inner && inner < outer && outer <= 90.0) {
                        return Err(bad(&format!(
                            "spot angles must be 0 ≤ inner_angle < outer_angle ≤ 90 degrees, \
                             got {inner} and {outer}"
                        )));
                    }
                    Light::spot(
                        p,
                        d.normalize(),
                        power,
                        inner.to_radians(),
                        outer.to_radians(),
                    )
                }
            });
            if l.kind != LightKind::Spot && (l.inner_angle.is_some() || l.outer_angle.is_some()) {
                return Err(bad("'inner_angle' and 'outer_angle' are for spot lights"));
            }
        }

        let c = &f.camera;
        let ln = line_of(&src, src.find("[camera]").unwrap_or(0));
        if c.width == 0 || c.height == 0 || !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(Error::input(
                path,
                Some(ln),
                "camera: width and height must be positive and fov in (0, 180) degrees",
            ));
        }
        let cam_bad = |msg: &str| Error::input(path, Some(ln), format!("camera: {msg}"));
        let all_finite = [c.position, c.look_at, c.up]
            .iter()
            .all(|v| v.iter().all(|x| x.is_finite()));
        if !all_finite {
            return Err(cam_bad("position, look_at and up must be finite numbers"));
        }
        let max = crate::limits::MAX_ORIGIN;
        if c.position.iter().any(|x| x.abs() > max) {
            return Err(cam_bad(&format!(
                "position beyond ±{max:e}, the supported range of ray origins"
            )));
        }
        let view = Vec3::from(c.look_at) - Vec3::from(c.position);
        if view == Vec3::ZERO {
            return Err(cam_bad("position equals look_at"));
        }
        let up = Vec3::from(c.up);
        // The basis is right = view × up: it needs an up that is not along the view.
        if view.normalize().cross(up.normalize_or_zero()).length() < 1e-4 {
            return Err(cam_bad(
                "up is zero or parallel to the view direction: give an up across the view",
            ));
        }
        let camera = Camera {
            eye: c.position.into(),
            look_at: c.look_at.into(),
            up: c.up.into(),
            vfov_deg: c.fov,
            width: c.width,
            height: c.height,
        };
        let r = &f.render;
        let rln = line_of(&src, src.find("[render]").unwrap_or(0));
        if let Some(d) = r.ao_distance.filter(|d| !(d.is_finite() && *d > 0.0)) {
            return Err(Error::input(
                path,
                Some(rln),
                format!("render: ao_distance must be a positive distance, got {d}"),
            ));
        }
        let settings = Settings {
            integrator: r.integrator,
            max_bounces: r.max_bounces,
            spp: r.spp,
            seed: r.seed,
            ao_distance: r.ao_distance.unwrap_or(0.0),
        };
        if let Err(e) = settings.check() {
            return Err(Error::input(path, Some(rln), format!("render: {e}")));
        }
        let environment = environment_of(path, &src, &f, &dir, &mut b.sources)?;
        b.finish(path, camera, settings, lights, environment)
    }

    /// `lancer render MESH` (.obj, .ply, .gltf, .glb): the mesh with its materials from its
    /// default view, on a ground plane, lit by a sun and a uniform sky.
    /// The view is the file's first perspective camera where it places one (glTF), else
    /// the default view.
    pub fn from_mesh(path: &Path, width: u32, height: u32) -> Result<RenderScene> {
        Ok(RenderScene::from_mesh_with_camera(path, width, height, None)?.0)
    }

    /// [`RenderScene::from_mesh`] seen from the file's camera `camera` names (by index or
    /// name; None: its first, if any); and the file's camera used (None: the default
    /// view).
    pub fn from_mesh_with_camera(
        path: &Path,
        width: u32,
        height: u32,
        camera: Option<&str>,
    ) -> Result<(RenderScene, Option<crate::mesh::GltfCamera>)> {
        let mut b = Builder::default();
        let grey = b.material(Material::diffuse(Vec3::splat(0.7)));
        let bounds = b.add_placed_file(path, grey)?;
        if !bounds.is_empty() {
            let r = 0.5 * bounds.extent().length();
            let ground = b.material(Material::diffuse(Vec3::splat(0.5)));
            let c = Vec3::new(bounds.center().x, bounds.lo.y, bounds.center().z);
            b.start_mesh([Affine::IDENTITY]);
            b.add_shape(shapes::quad(), ground, |p| c + p * 20.0 * r, None);
        }
        let picked = crate::camera::pick_camera(&b.cameras, camera)
            .map_err(|e| Error::input(path, None, e))?;
        let from_file = picked.cloned();
        let camera = match picked {
            Some(c) => Camera::from_gltf(c, width, height),
            None => Camera::default_view(&bounds, width, height),
        };
        let settings = Settings {
            integrator: Integrator::Path,
            max_bounces: 2,
            spp: 16,
            seed: 0,
            ao_distance: 0.0,
        };
        let sky = Environment::uniform(Vec3::new(0.35, 0.45, 0.6));
        // The file's own lights (glTF), else a sun.
        let mut lights: Vec<Light> = b.gltf_lights.iter().map(Light::from_gltf).collect();
        if lights.is_empty() {
            lights.push(Light::Directional {
                direction: Vec3::new(-0.4, -1.0, -0.5).normalize(),
                irradiance: Vec3::new(2.6, 2.4, 2.1),
            });
        }
        let mut scene = b.finish(path, camera, settings, lights, Some(sky))?;
        // A camera the file's animation moves moves from frame to frame.
        if let (Some(pl), Some(c)) = (&mut scene.placements, &from_file) {
            pl.animate_camera(c);
        }
        Ok((scene, from_file))
    }
}

impl Builder {
    fn finish(
        self,
        path: &Path,
        camera: Camera,
        mut settings: Settings,
        lights: Vec<Light>,
        environment: Option<Environment>,
    ) -> Result<RenderScene> {
        let mut normals = self.normals;
        if !normals.is_empty() {
            normals.resize(self.triangles.len(), [NO_NORMAL; 3]);
        }
        if self.unfinite_uvs > 0 {
            log::warn!(
                "{}: {} triangle(s) have texture coordinates that are not finite (NaN or \
                 infinite): read as 0 there",
                path.display(),
                self.unfinite_uvs
            );
        }
        let mesh = Mesh {
            triangles: self.triangles,
            status: self.status,
            short_faces: self.short_faces,
            sources: self.sources,
        };
        // Exclusions were counted per mesh file as each was added (add_obj).
        check_traceable(path, &mesh)?;
        let placements = match self.placed {
            true => {
                let pl = place_meshes(path, &mesh, &self.mesh_starts, self.instances)?
                    .with_motions(&self.motions);
                Some(match self.animation {
                    Some((first, clip)) => pl.with_animation(first, clip),
                    None => pl,
                })
            }
            false => None,
        };
        let tangents = tangents_of(&TangentInputs {
            mesh: &mesh,
            uvs: &self.uvs,
            normals: &normals,
            given: &self.tangents,
            material_of: &self.material_of,
            materials: &self.materials,
            mesh_starts: match self.placed {
                true => &self.mesh_starts,
                false => &[],
            },
        });
        let mut scene = RenderScene {
            camera,
            settings: settings.clone(),
            mesh,
            uvs: self.uvs,
            normals,
            tangents,
            material_of: self.material_of,
            materials: self.materials,
            textures: self.textures,
            lights,
            environment,
            emitters: Vec::new(),
            emitter_cdf: Vec::new(),
            placements,
        };
        if settings.ao_distance <= 0.0 {
            settings.ao_distance = 0.1 * scene.bounds().extent().length();
            scene.settings = settings;
        }
        scene.find_emitters()?;
        Ok(scene)
    }
}

/// The meshes of `mesh` (from each start to the next) placed by `instances`.
fn place_meshes(
    path: &Path,
    mesh: &Mesh,
    starts: &[usize],
    instances: Vec<Instance>,
) -> Result<Placements> {
    let ends = starts.iter().skip(1).copied().chain([mesh.len()]);
    let meshes = (starts.iter().zip(ends).enumerate())
        .map(|(k, (&first, end))| {
            std::sync::Arc::new(Mesh {
                triangles: mesh.triangles[first..end].to_vec(),
                status: mesh.status[first..end].to_vec(),
                short_faces: 0,
                // Every file read, once (the first mesh's).
                sources: if k == 0 {
                    mesh.sources.clone()
                } else {
                    Vec::new()
                },
            })
        })
        .collect();
    let set = InstanceSet::new(meshes, instances)
        .map_err(|e| Error::input(path, None, error_message(&e)))?;
    Ok(Placements::new(
        set,
        starts.iter().map(|&s| s as u32).collect(),
    ))
}

impl RenderScene {
    /// Fills [`Self::emitters`] and [`Self::emitter_cdf`]: the included triangles of
    /// emissive materials, by number, with their world-space areas.
    fn find_emitters(&mut self) -> Result<()> {
        let emissive: Vec<u32> = (self.mesh.included().into_iter())
            .filter(|&i| {
                let m = &self.materials[self.material_of[i as usize] as usize];
                m.kind == MaterialKind::Emissive && m.emission.max_element() > 0.0
            })
            .collect();
        let numbers: Vec<u32> = match &self.placements {
            None => emissive,
            Some(pl) => {
                let set = pl.set();
                let per_mesh: Vec<Vec<u32>> = (set.meshes.iter().enumerate())
                    .map(|(k, m)| {
                        let base = pl.mesh_base()[k];
                        let range = base..base + m.len() as u32;
                        let lo = emissive.partition_point(|&i| i < range.start);
                        let hi = emissive.partition_point(|&i| i < range.end);
                        emissive[lo..hi].iter().map(|i| i - base).collect()
                    })
                    .collect();
                let n: u128 = (set.instances.iter())
                    .map(|i| per_mesh[i.mesh as usize].len() as u128)
                    .sum();
                crate::limits::check_memory(
                    &format!("{n} placed emissive triangles"),
                    n * 8,
                    "place fewer copies of emissive objects",
                )?;
                (set.instances.iter().zip(pl.first_prims()))
                    .flat_map(|(inst, &first)| {
                        per_mesh[inst.mesh as usize].iter().map(move |l| first + l)
                    })
                    .collect()
            }
        };
        let mut total = 0.0f32;
        self.emitter_cdf = (numbers.iter())
            .map(|&prim| {
                total += Triangle {
                    v: self.triangle(prim).v,
                }
                .area();
                total
            })
            .collect();
        self.emitters = numbers;
        Ok(())
    }

    /// The index of the shading data of triangle number `prim` (as the traversal numbers
    /// them).
    pub fn shade_of(&self, prim: u32) -> usize {
        match &self.placements {
            Some(pl) => pl.shade_of(prim),
            None => prim as usize,
        }
    }

    /// The texture coordinates of shading triangle `shade` at barycentric (u, v) (zero
    /// where it has none). WGSL: `s.uv0 * w + s.uv1 * u + s.uv2 * v`.
    pub fn uv_at(&self, shade: usize, u: f32, v: f32) -> Vec2 {
        let Some(uv) = self.uvs.get(shade) else {
            return Vec2::ZERO;
        };
        uv[0] * (1.0 - u - v) + uv[1] * u + uv[2] * v
    }

    /// Triangle number `prim` (as the traversal numbers them) as shading sees it: in world
    /// space, with the index of its shading data.
    pub fn triangle(&self, prim: u32) -> PlacedTriangle {
        match &self.placements {
            Some(pl) => pl.triangle(prim, &self.mesh),
            None => PlacedTriangle::unplaced(self.mesh.triangles[prim as usize].v, prim as usize),
        }
    }

    /// The shading normal of triangle `t` at the point of barycentric weights (w, u, v),
    /// world space, not normalised: its corners' normals interpolated and, for a placed
    /// triangle, moved by its instance's inverse transpose; None where it shades flat.
    /// WGSL `shading_normal` computes the same.
    pub fn shading_normal(&self, t: &PlacedTriangle, w: f32, u: f32, v: f32) -> Option<Vec3> {
        let n = self.normals.get(t.shade)?;
        if n[0] == NO_NORMAL {
            return None;
        }
        let [a, b, c] = n.map(unpack_unit);
        let s = a * w + b * u + c * v;
        match (&self.placements, t.instance) {
            (Some(pl), Some(i)) => {
                let r = pl.to_object()[i as usize]
                    .rows
                    .map(|r| Vec3::new(r[0], r[1], r[2]));
                Some(r[0] * s.x + r[1] * s.y + r[2] * s.z)
            }
            _ => Some(s),
        }
    }

    /// The tangent of triangle `t` at the point of barycentric weights (w, u, v), in world
    /// space (moved by its instance's map), not normalised: its corners' interpolated; and
    /// whether its bitangent is −(n × t) for n the normal its vertices wind around (the
    /// majority of its corners'); None where it has none. WGSL `mapped_normal` reads the
    /// same.
    pub fn tangent(&self, t: &PlacedTriangle, w: f32, u: f32, v: f32) -> Option<(Vec3, bool)> {
        let (dir, flipped) = tangents::interpolated(self.tangents.get(t.shade)?, w, u, v)?;
        match (&self.placements, t.instance) {
            // Its handedness is the winding's, which a mirroring map turns with it.
            (Some(pl), Some(i)) => {
                Some((pl.set().instances[i as usize].to_world.vector(dir), flipped))
            }
            _ => Some((dir, flipped)),
        }
    }

    /// The error bound of the point p = b0·v0 + b1·v1 + b2·v2 of triangle `t`: the
    /// interpolation's ([`point_error`](crate::render::point_error)) and, for a placed
    /// triangle, its placement's rounding ([`Placements::error`]).
    pub fn point_error(&self, t: &PlacedTriangle, p: Vec3, b: [f32; 3]) -> Vec3 {
        let e = crate::render::point_error(&t.v, b[0], b[1], b[2]);
        match (&self.placements, t.instance) {
            (Some(pl), Some(_)) => e + pl.error(t, p),
            _ => e,
        }
    }

    /// The scene's bounds in world space (with placements, the union of the instances'
    /// mapped mesh bounds).
    pub fn bounds(&self) -> Aabb {
        match &self.placements {
            Some(pl) => pl.bounds(),
            None => self.mesh.bounds(),
        }
    }

    /// Whether anything moves from frame to frame (`move`, `spin`, a glTF animation).
    pub fn moves(&self) -> bool {
        self.placements.as_ref().is_some_and(Placements::moves)
    }

    /// Sets the frames a second at which a glTF animation is played
    /// ([`Placements::set_frame_rate`]; [`DEFAULT_FRAME_RATE`](super::DEFAULT_FRAME_RATE)
    /// unless set). Refused unless positive and finite.
    pub fn set_frame_rate(&mut self, fps: f32) -> Result<()> {
        match &mut self.placements {
            Some(pl) => pl.set_frame_rate(fps),
            None => Placements::check_frame_rate(fps),
        }
    }

    /// The frames a glTF animation lasts at its frame rate (its last key's frame, rounded
    /// up), where the scene plays one.
    pub fn animation_frames(&self) -> Option<u32> {
        self.placements.as_ref()?.animation_frames()
    }

    /// The scene at frame `frame`: its placements moved to that frame (and its emitters'
    /// areas with them); the scene itself where nothing moves. Refused where a moved map is
    /// not invertible, or where the scene's arrays disagree ([`RenderScene::check_arrays`]).
    pub fn at_frame(&self, frame: u32) -> Result<RenderScene> {
        self.check_arrays()?;
        let mut scene = self.clone();
        if let Some(pl) = self.placements.as_ref().filter(|p| p.moves()) {
            scene.placements = Some(pl.at_frame(frame)?);
            scene.find_emitters()?;
            if let Some(c) = pl.camera_at(frame)? {
                let (w, h) = (self.camera.width, self.camera.height);
                scene.camera = Camera::from_gltf(&c, w, h);
            }
        }
        Ok(scene)
    }

    /// Refuses a scene assembled in code whose settings a render cannot run with
    /// ([`Settings::check`]) or whose arrays disagree ([`RenderScene::check_arrays`]); a
    /// scene read from a file always passes.
    pub fn check(&self) -> Result<()> {
        (self.settings.check()).map_err(|e| Error::Usage(format!("a scene made in code: {e}")))?;
        self.check_arrays()
    }

    /// Refuses a scene assembled in code whose arrays disagree (a scene read from a file
    /// always agrees): one status, texture-coordinate triple and material index per
    /// triangle, normals and tangents for every triangle or none, materials and textures
    /// that the indices name, whole textures, and emitters among the triangles rendered
    /// with one running area each.
    pub fn check_arrays(&self) -> Result<()> {
        self.mesh.check_arrays()?;
        let n = self.mesh.len();
        let bad = |msg: String| Err(Error::Usage(format!("a scene made in code: {msg}")));
        for (what, len, may_be_empty) in [
            ("texture coordinates (uvs)", self.uvs.len(), false),
            (
                "material indices (material_of)",
                self.material_of.len(),
                false,
            ),
            ("normals", self.normals.len(), true),
            ("tangents", self.tangents.len(), true),
        ] {
            if len != n && !(may_be_empty && len == 0) {
                return bad(format!("{len} {what} for {n} triangles"));
            }
        }
        if let Some(m) = self
            .material_of
            .iter()
            .find(|&&m| m as usize >= self.materials.len())
        {
            return bad(format!("material {m} of {}", self.materials.len()));
        }
        for (i, m) in self.materials.iter().enumerate() {
            let slots = [
                m.texture,
                m.metallic_roughness_texture,
                m.emission_texture,
                m.normal_texture,
                m.occlusion_texture,
            ];
            if let Some(t) = slots
                .into_iter()
                .flatten()
                .find(|&t| t >= self.textures.len())
            {
                return bad(format!(
                    "material {i} names texture {t} of {}",
                    self.textures.len()
                ));
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            if t.texels.len() as u64 != t.width as u64 * t.height as u64 || t.texels.is_empty() {
                return bad(format!(
                    "texture {i} is {}×{} with {} texels",
                    t.width,
                    t.height,
                    t.texels.len()
                ));
            }
        }
        if let Some(pl) = &self.placements {
            // The placed meshes are slices of `mesh`, from their bases on.
            let set = pl.set();
            set.check()?;
            let fits = pl.mesh_base().len() == set.meshes.len()
                && (pl.mesh_base().iter().zip(&set.meshes))
                    .all(|(&base, m)| base as usize + m.len() <= n);
            if !fits {
                return bad(format!(
                    "placements of {} meshes from bases {:?} in a mesh of {n} triangles",
                    set.meshes.len(),
                    pl.mesh_base()
                ));
            }
        }
        let rendered = self.triangle_count();
        if let Some(e) = self.emitters.iter().find(|&&e| e as u64 >= rendered) {
            return bad(format!("emitter {e} of {rendered} triangles"));
        }
        if self.emitter_cdf.len() != self.emitters.len() {
            return bad(format!(
                "{} running areas (emitter_cdf) for {} emitters",
                self.emitter_cdf.len(),
                self.emitters.len()
            ));
        }
        Ok(())
    }

    /// Triangles rendered: those of [`Self::mesh`], or with placements those they place.
    pub fn triangle_count(&self) -> u64 {
        match &self.placements {
            Some(pl) => pl.set().triangle_count(),
            None => self.mesh.len() as u64,
        }
    }

    /// The scene with its placements flattened: every placed triangle in one mesh in world
    /// space, numbered as before (so hits, emitters and materials keep their numbers).
    /// A scene without placements is returned as it is; one whose arrays disagree
    /// ([`RenderScene::check_arrays`]) is refused.
    pub fn flattened(self) -> Result<RenderScene> {
        let Some(pl) = &self.placements else {
            return Ok(self);
        };
        self.check_arrays()?;
        let n = pl.set().triangle_count() as u128;
        crate::limits::check_memory(
            &format!("the flattened scene ({n} triangles)"),
            n * 256,
            "trace or render it with its placements, in two levels (without --flatten; \
             `lancer build` writes one flattened BVH)",
        )?;
        let mut mesh = pl.set().flatten()?;
        mesh.sources = self.mesh.sources.clone();
        mesh.short_faces = self.mesh.short_faces;
        let (mut uvs, mut material_of) = (Vec::with_capacity(n as usize), Vec::new());
        material_of.reserve(n as usize);
        let (mut normals, mut tangents) = (Vec::new(), Vec::new());
        for (i, inst) in pl.set().instances.iter().enumerate() {
            let base = pl.mesh_base()[inst.mesh as usize] as usize;
            let range = base..base + pl.set().meshes[inst.mesh as usize].len();
            uvs.extend_from_slice(&self.uvs[range.clone()]);
            if !self.normals.is_empty() {
                // Normals move by the inverse transpose: the to-object map's rows as columns.
                let r = pl.to_object()[i].rows;
                let nm = Mat3::from_cols_array_2d(&[0, 1, 2].map(|k| [r[k][0], r[k][1], r[k][2]]));
                let own = &self.normals[range.clone()];
                normals.extend(own.iter().map(|n| map_normals(Some(nm), Some(n))));
            }
            if !self.tangents.is_empty() {
                let own = &self.tangents[range.clone()];
                let m = |v| inst.to_world.vector(v);
                tangents.extend(own.iter().map(|t| tangents::move_tangents(m, t)));
            }
            material_of.extend_from_slice(&self.material_of[range]);
        }
        Ok(RenderScene {
            mesh,
            uvs,
            normals,
            tangents,
            material_of,
            placements: None,
            ..self
        })
    }
}

/// The message of an error without the file prefix it carries, to re-attach elsewhere.
pub(super) fn error_message(e: &Error) -> String {
    match e {
        Error::Input { msg, .. } => msg.clone(),
        other => other.to_string(),
    }
}
