//! Mesh files as scene objects, the reader chosen by extension (OBJ with its MTL materials,
//! PLY, glTF 2.0 with its materials), and glTF's materials mapped onto lancer's: an area
//! light (emissive) where the emissive factor is not black and no emissive texture or base
//! colour texture varies it, a mirror for a perfectly smooth metal, glass where
//! KHR_materials_transmission is present, principled (glTF's own metallic-roughness, with
//! its base colour, metallic-roughness, emissive and normal textures) otherwise.

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::assemble::{
    decode_texture, error_message, map_normals, Builder, Material, NormalMap, TextureSlot,
};
use super::file::MaterialKind;
use super::tangents::move_tangents;
use crate::error::{Error, Result};
use crate::geometry::{Aabb, Triangle, NO_NORMAL};
use crate::mesh::{
    load_gltf, load_obj_scene, load_ply_scene, read_gltf, warn_exclusions, FileKind, GltfImage,
    GltfLoaded, GltfMaterial, GltfPlaced, GltfScene, GltfTexture, Instance, TriStatus,
};

impl Builder {
    /// Adds a mesh file's triangles, transformed by `xf`; `material` overrides the file's
    /// own materials, `grey` stands in where it has none. Returns the bounds of what it
    /// added.
    pub(super) fn add_mesh_file(
        &mut self,
        path: &Path,
        material: Option<u32>,
        grey: u32,
        xf: impl Fn(Vec3) -> Vec3,
        nm: Option<NormalMap>,
    ) -> Result<Aabb> {
        let first = self.triangles.len();
        match FileKind::of(path)? {
            FileKind::Obj => {
                let mut obj = load_obj_scene(path)?;
                if nm.is_none() {
                    obj.normals = Vec::new();
                }
                self.add_obj(&obj, path, material, grey, xf, nm.flatten())?;
            }
            FileKind::Ply => {
                let ply = load_ply_scene(path)?;
                let mesh = &ply.mesh;
                let id = material.unwrap_or(grey);
                for (i, (t, &s)) in mesh.triangles.iter().zip(&mesh.status).enumerate() {
                    let uv = ply.uvs.get(i).copied().unwrap_or([Vec2::ZERO; 3]);
                    let n = match nm {
                        Some(nm) => map_normals(nm, ply.normals.get(i)),
                        None => [NO_NORMAL; 3],
                    };
                    self.push(xf_triangle(t, &xf), s, uv, n, id);
                }
                let mesh = ply.mesh;
                warn_exclusions(path, &mesh);
                self.short_faces += mesh.short_faces;
                self.sources.extend(mesh.sources);
            }
            FileKind::Gltf => {
                let mut g = load_gltf(path)?;
                if !g.lights.is_empty() {
                    // A scene's lights are its [[lights]]; the file's would need its
                    // object's transform and its photometric units.
                    log::warn!(
                        "{}: its {} light(s) are not used in a scene (give them as [[lights]]); \
                         `lancer render` of the file itself uses them",
                        path.display(),
                        g.lights.len()
                    );
                }
                if nm.is_none() {
                    // Flat shading drops the file's tangents with its normals (glTF has
                    // none without normals): they are generated against the faces'.
                    g.normals = Vec::new();
                    g.tangents = Vec::new();
                }
                self.add_gltf(path, g, material, grey, xf, nm.flatten())?
            }
            FileKind::Scene => {
                return Err(Error::input(
                    path,
                    None,
                    "a scene cannot be an object's mesh: name an .obj, .ply, .gltf or .glb file",
                ))
            }
        }
        Ok(self.bounds_from(first))
    }
}

impl Builder {
    /// Adds a flattened glTF scene read from `path`, as [`Builder::add_mesh_file`] adds it.
    fn add_gltf(
        &mut self,
        path: &Path,
        g: GltfScene,
        material: Option<u32>,
        grey: u32,
        xf: impl Fn(Vec3) -> Vec3,
        nm: NormalMap,
    ) -> Result<()> {
        let mut ids = Vec::with_capacity(g.materials.len());
        if material.is_none() {
            for m in &g.materials {
                let m = gltf_material(self, path, m)?;
                ids.push(self.material(m));
            }
        }
        // Tangents move by the map's linear part (the inverse transpose's inverse
        // transpose); their handedness, read against the winding, moves with it.
        let linear = nm.map(|m| m.inverse().transpose());
        let tangent_map = |v: Vec3| linear.map_or(v, |l| l * v);
        for (i, t) in g.mesh.triangles.iter().enumerate() {
            let id = material.unwrap_or_else(|| {
                g.material_ids[i]
                    .and_then(|k| ids.get(k).copied())
                    .unwrap_or(grey)
            });
            let n = map_normals(nm, g.normals.get(i));
            self.push(xf_triangle(t, &xf), g.mesh.status[i], g.uvs[i], n, id);
            if let Some(t) = g.tangents.get(i) {
                self.give_tangents(move_tangents(tangent_map, t));
            }
        }
        warn_exclusions(path, &g.mesh);
        self.short_faces += g.mesh.short_faces;
        self.sources.extend(g.mesh.sources);
        Ok(())
    }

    /// Adds a mesh file as `render MESH` shows it, after the meshes so far, and returns the
    /// bounds of what it added: a glTF file that draws a mesh with several nodes, or whose
    /// animation moves it, as its meshes placed by its nodes (numbered as the flattened
    /// file), any other as one mesh placed once. The file is read once.
    pub(super) fn add_placed_file(&mut self, path: &Path, grey: u32) -> Result<Aabb> {
        if matches!(FileKind::of(path)?, FileKind::Gltf) {
            match read_gltf(path)? {
                GltfLoaded::Placed(g) => return self.add_gltf_placed(path, grey, g),
                GltfLoaded::Flat(g) => {
                    self.cameras = g.cameras.clone();
                    self.gltf_lights = g.lights.clone();
                    self.start_mesh([crate::geometry::Affine::IDENTITY]);
                    let first = self.triangles.len();
                    self.add_gltf(path, g, None, grey, |p| p, None)?;
                    return Ok(self.bounds_from(first));
                }
            }
        }
        self.start_mesh([crate::geometry::Affine::IDENTITY]);
        self.add_mesh_file(path, None, grey, |p| p, Some(None))
    }

    /// Bounds of the included triangles from `first` on.
    fn bounds_from(&self, first: usize) -> Aabb {
        (self.triangles[first..].iter())
            .zip(&self.status[first..])
            .filter(|(_, s)| **s == TriStatus::Ok)
            .fold(Aabb::EMPTY, |b, (t, _)| b.union(t.bbox()))
    }

    /// Adds a glTF file's meshes placed by its nodes, with their materials.
    fn add_gltf_placed(&mut self, path: &Path, grey: u32, g: GltfPlaced) -> Result<Aabb> {
        self.cameras = g.cameras.clone();
        self.gltf_lights = g.lights.clone();
        let mut ids = Vec::with_capacity(g.materials.len());
        for m in &g.materials {
            let m = gltf_material(self, path, m)?;
            ids.push(self.material(m));
        }
        let first_mesh = self.mesh_starts.len() as u32;
        let mut mesh_bounds = Vec::with_capacity(g.meshes.len());
        for m in &g.meshes {
            self.mesh_starts.push(self.triangles.len());
            for (i, t) in m.mesh.triangles.iter().enumerate() {
                let id = (m.material_ids[i])
                    .and_then(|k| ids.get(k).copied())
                    .unwrap_or(grey);
                let n = map_normals(None, m.normals.get(i));
                self.push(*t, m.mesh.status[i], m.uvs[i], n, id);
                if let Some(t) = m.tangents.get(i) {
                    self.give_tangents(*t);
                }
            }
            warn_exclusions(path, &m.mesh);
            self.short_faces += m.mesh.short_faces;
            self.sources.extend(m.mesh.sources.iter().cloned());
            mesh_bounds.push(m.mesh.bounds());
        }
        if let Some(clip) = g.animation {
            self.animation = Some((self.instances.len(), clip));
        }
        let mut bounds = Aabb::EMPTY;
        for inst in &g.instances {
            bounds = bounds.union(inst.to_world.image_box(&mesh_bounds[inst.mesh as usize]));
            self.instances.push(Instance {
                mesh: first_mesh + inst.mesh,
                to_world: inst.to_world,
            });
        }
        self.placed = true;
        Ok(bounds)
    }
}

fn xf_triangle(t: &Triangle, xf: &impl Fn(Vec3) -> Vec3) -> Triangle {
    Triangle::new(xf(t.v[0]), xf(t.v[1]), xf(t.v[2]))
}

/// lancer's material for a glTF material (see the module comment for the mapping).
fn gltf_material(b: &mut Builder, path: &Path, m: &GltfMaterial) -> Result<Material> {
    let [r, g, bl, alpha] = m.base_color;
    let base = Vec3::new(r, g, bl);
    if base.max_element() > 1.0 {
        log::warn!(
            "{}: material {:?}: base colour {base} reflects more light than arrives; clamped to 1",
            path.display(),
            m.name
        );
    }
    let base = base.min(Vec3::ONE);
    let emissive = Vec3::from(m.emissive);
    let glowing = emissive.max_element() > 0.0;
    // (A masked one is principled below: its glow where hit, its mask cutting it.)
    let masked_glow = m.alpha_cutoff.is_some() || m.alpha_blend;
    if glowing && m.emissive_texture.is_none() && m.base_color_texture.is_none() && !masked_glow {
        // A uniform glow: an area light, sampled at every diffuse hit.
        let mut mat = Material::diffuse(base);
        mat.kind = MaterialKind::Emissive;
        mat.emission = emissive;
        mat.two_sided = m.double_sided;
        return Ok(mat);
    }
    // An alpha mask (or blend) cuts every kind: by the base colour's alpha, and where the
    // base colour texture is read (principled) by its alpha too; mirror and glass read no
    // texture.
    let masked = |mut mat: Material| {
        mat.alpha = alpha.clamp(0.0, 1.0);
        mat.alpha_cutoff = m.alpha_cutoff;
        mat.alpha_blend = m.alpha_blend;
        mat
    };
    let smooth_metal = m.metallic >= 1.0 && m.roughness <= 0.0;
    if smooth_metal && m.metallic_roughness_texture.is_none() && !glowing {
        // A perfectly smooth metal: a mirror tinted by the base colour, followed by every
        // integrator (GGX's narrowest lobe would be found by light samples alone where
        // the path stops: the direct integrator, the last bounce).
        let mut mat = Material::diffuse(base);
        mat.kind = MaterialKind::Mirror;
        return Ok(masked(mat));
    }
    if m.transmission > 0.0 {
        let mut mat = Material::diffuse(base);
        mat.kind = MaterialKind::Glass;
        mat.ior = m.ior.clamp(1.0, 4.0);
        if mat.ior != m.ior {
            log::warn!(
                "{}: material {:?}: ior {} outside [1, 4]; clamped to {}",
                path.display(),
                m.name,
                m.ior,
                mat.ior
            );
        }
        return Ok(masked(mat));
    }
    if !m.other_coordinates.is_empty() {
        log::warn!(
            "{}: material {:?}: the {} texture(s) read another set of texture coordinates \
             than the first; lancer reads them at the first's",
            path.display(),
            m.name,
            m.other_coordinates.join(", ")
        );
    }
    let mut mat = masked(Material::principled(base, m.metallic, m.roughness));
    // Emission where hit (not sampled as a light): the factor times the texture.
    mat.emission = if glowing { emissive } else { Vec3::ZERO };
    mat.two_sided = true;
    let mut image = |what: &str, t: Option<&GltfTexture>, srgb: bool| -> Result<_> {
        let Some(t) = t else {
            return Ok(None);
        };
        let index = t.image;
        let key = PathBuf::from(format!("{}#image{index}/{srgb}", path.display()));
        let texture = b.texture_with(key, || {
            let decoded = match &t.bytes {
                GltfImage::Bytes(bytes) => decode_texture(bytes, srgb),
                GltfImage::File(f) => crate::input::read(f)
                    .map_err(|e| e.to_string())
                    .and_then(|bytes| decode_texture(&bytes, srgb)),
            };
            decoded.map_err(|e| {
                Error::input(
                    path,
                    None,
                    format!(
                        "material {:?}: {what} texture (image {index}) cannot be read: {e}",
                        m.name
                    ),
                )
            })
        });
        Ok(Some(texture.map_err(|e| {
            Error::input(path, None, error_message(&e))
        })?))
    };
    mat.texture = image("base colour", m.base_color_texture.as_ref(), true)?;
    mat.metallic_roughness_texture = image(
        "metallic-roughness",
        m.metallic_roughness_texture.as_ref(),
        false,
    )?;
    if glowing {
        mat.emission_texture = image("emissive", m.emissive_texture.as_ref(), true)?;
    }
    if let Some((t, scale)) = &m.normal_texture {
        mat.normal_texture = image("normal", Some(t), false)?;
        mat.normal_scale = *scale;
    }
    if let Some((t, strength)) = &m.occlusion_texture {
        mat.occlusion_texture = image("occlusion", Some(t), false)?;
        mat.occlusion_strength = strength.clamp(0.0, 1.0);
    }
    // Each texture's own coordinates, where they differ (one image, decoded once, may be
    // read at several: an atlas).
    let slots = [
        (TextureSlot::Base, m.base_color_texture.as_ref()),
        (
            TextureSlot::MetallicRoughness,
            m.metallic_roughness_texture.as_ref(),
        ),
        (TextureSlot::Emission, m.emissive_texture.as_ref()),
        (TextureSlot::Normal, m.normal_texture.as_ref().map(|n| &n.0)),
        (
            TextureSlot::Occlusion,
            m.occlusion_texture.as_ref().map(|o| &o.0),
        ),
    ];
    for (slot, t) in slots {
        if mat.texture_in(slot).is_some() {
            mat.uv_transforms[slot as usize] = t.and_then(|t| t.uv_transform);
        }
    }
    Ok(mat)
}
