//! The effects a scene calls for. The set decides which code the render kernel keeps
//! (WGSL `override` constants of one shader source) and which the CPU renderer runs.

use super::scene::{Integrator, Light, MaterialKind, RenderScene};
use crate::geometry::{NO_NORMAL, NO_TANGENT};

/// Which effects a render simulates; code for the others is compiled out of the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EffectSet {
    /// Shadow rays toward lights (any light).
    pub shadows: bool,
    /// Area lights sampled at every diffuse or principled hit (emissive triangles).
    pub soft_shadows: bool,
    /// Mirror reflection.
    pub mirror: bool,
    /// Refraction through glass.
    pub refraction: bool,
    /// Diffuse bounces (path integrator with max_bounces ≥ 1).
    pub indirect: bool,
    /// Albedo textures.
    pub textures: bool,
    /// Ambient occlusion (ao integrator).
    pub ao: bool,
    /// Shading normals interpolated from the vertices' (smooth surfaces).
    pub shading_normals: bool,
    /// Light from the environment: seen by rays that leave the scene, and sampled at
    /// every diffuse or principled hit (multiple importance sampling with the bounce).
    pub environment: bool,
    /// Spot lights (a point light's falloff about an axis).
    pub spot_lights: bool,
    /// Tangent-space normal maps (which bring shading normals with them).
    pub normal_maps: bool,
    /// glTF metallic-roughness surfaces (principled: GGX microfacets over a Lambert
    /// base, and their emission); without it they are diffuse.
    pub microfacet: bool,
    /// Alpha masks: hits where a masked material's alpha is below its cutoff (or, blended,
    /// below a cutoff drawn per hit) are skipped in the traversal (every ray: camera,
    /// bounce, shadow and AO rays alike).
    pub alpha_mask: bool,
    /// Textures read at moved coordinates (glTF `KHR_texture_transform` where a texture's
    /// differs from its material's interpolated set's): without it every texture is read
    /// at the interpolated coordinates.
    pub texture_transforms: bool,
}

impl EffectSet {
    /// Every effect on: the unspecialised kernel.
    pub const ALL: EffectSet = EffectSet {
        shadows: true,
        soft_shadows: true,
        mirror: true,
        refraction: true,
        indirect: true,
        textures: true,
        ao: true,
        shading_normals: true,
        environment: true,
        spot_lights: true,
        normal_maps: true,
        microfacet: true,
        alpha_mask: true,
        texture_transforms: true,
    };

    /// What `scene` needs, and nothing more.
    pub fn of(scene: &RenderScene) -> EffectSet {
        let s = &scene.settings;
        // The materials of the triangles that are in the BVH (only those can be hit).
        let included = scene.mesh.included();
        // (A scene made in code whose arrays disagree names fewer: `RenderScene::check`
        // refuses it before any render.)
        let used: Vec<_> = (included.iter())
            .filter_map(|&i| scene.material_of.get(i as usize))
            .filter_map(|&m| scene.materials.get(m as usize))
            .collect();
        let kind_used = |k: MaterialKind| used.iter().any(|m| m.kind == k);
        let ao = s.integrator == Integrator::Ao;
        // Seen by rays that leave the scene under every integrator (AO's camera rays too).
        let environment = scene.environment.is_some();
        let normal_maps = (included.iter()).any(|&i| {
            scene
                .tangents
                .get(i as usize)
                .is_some_and(|t| t[0] != NO_TANGENT)
        });
        EffectSet {
            shadows: !ao && (!scene.lights.is_empty() || !scene.emitters.is_empty() || environment),
            soft_shadows: !ao && !scene.emitters.is_empty(),
            mirror: !ao && kind_used(MaterialKind::Mirror),
            refraction: !ao && kind_used(MaterialKind::Glass),
            indirect: s.integrator == Integrator::Path && s.max_bounces >= 1,
            textures: !ao && used.iter().any(|m| m.textured()),
            ao,
            shading_normals: normal_maps
                || (included.iter()).any(|&i| {
                    scene
                        .normals
                        .get(i as usize)
                        .is_some_and(|n| n[0] != NO_NORMAL)
                }),
            normal_maps,
            environment,
            spot_lights: !ao && (scene.lights.iter()).any(|l| matches!(l, Light::Spot { .. })),
            microfacet: !ao && kind_used(MaterialKind::Principled),
            // Geometry, not shading: AO rays pass through the holes too.
            alpha_mask: used
                .iter()
                .any(|m| m.alpha_cutoff.is_some() || m.alpha_blend),
            // Whatever reads the texture (shading, normal maps, alpha masks) reads it there.
            texture_transforms: used.iter().any(|m| m.moves_textures()),
        }
    }

    /// (name, on) for printing and for the WGSL override constants.
    pub fn flags(&self) -> [(&'static str, bool); 14] {
        [
            ("SHADOWS", self.shadows),
            ("SOFT_SHADOWS", self.soft_shadows),
            ("MIRROR", self.mirror),
            ("REFRACTION", self.refraction),
            ("INDIRECT", self.indirect),
            ("TEXTURES", self.textures),
            ("AO", self.ao),
            ("SHADING_NORMALS", self.shading_normals),
            ("ENVIRONMENT", self.environment),
            ("SPOT_LIGHTS", self.spot_lights),
            ("NORMAL_MAPS", self.normal_maps),
            ("MICROFACET", self.microfacet),
            ("ALPHA_MASK", self.alpha_mask),
            ("TEXTURE_TRANSFORMS", self.texture_transforms),
        ]
    }
}

impl EffectSet {
    /// For each effect in the set, its name (as [`Display`](std::fmt::Display) prints
    /// it) and the set without it: what `bench render` times to price each effect.
    pub fn each_without(&self) -> Vec<(String, EffectSet)> {
        type Field = fn(&mut EffectSet) -> &mut bool;
        let fields: [(&str, Field); 14] = [
            ("shadows", |f| &mut f.shadows),
            ("soft-shadows", |f| &mut f.soft_shadows),
            ("mirror", |f| &mut f.mirror),
            ("refraction", |f| &mut f.refraction),
            ("indirect", |f| &mut f.indirect),
            ("textures", |f| &mut f.textures),
            ("ao", |f| &mut f.ao),
            ("shading-normals", |f| &mut f.shading_normals),
            ("environment", |f| &mut f.environment),
            ("spot-lights", |f| &mut f.spot_lights),
            ("normal-maps", |f| &mut f.normal_maps),
            ("microfacet", |f| &mut f.microfacet),
            ("alpha-mask", |f| &mut f.alpha_mask),
            ("texture-transforms", |f| &mut f.texture_transforms),
        ];
        let mut out = Vec::new();
        for (name, field) in fields {
            let mut without = *self;
            if std::mem::replace(field(&mut without), false) {
                out.push((name.to_string(), without));
            }
        }
        out
    }
}

impl std::fmt::Display for EffectSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let on: Vec<String> = (self.flags().iter())
            .filter(|x| x.1)
            .map(|x| x.0.to_ascii_lowercase().replace('_', "-"))
            .collect();
        if on.is_empty() {
            write!(f, "none (direct light only)")
        } else {
            write!(f, "{}", on.join(" "))
        }
    }
}
