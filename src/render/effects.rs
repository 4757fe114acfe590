//! The effects a scene calls for. The set decides which code the render kernel keeps
//! (WGSL `override` constants of one shader source) and which the CPU renderer runs.

use super::scene::{Integrator, MaterialKind, RenderScene};
use crate::geometry::NO_NORMAL;

/// Which effects a render simulates; code for the others is compiled out of the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EffectSet {
    /// Shadow rays toward lights (any light).
    pub shadows: bool,
    /// Area lights sampled at every diffuse hit (emissive triangles).
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
    };

    /// What `scene` needs, and nothing more.
    pub fn of(scene: &RenderScene) -> EffectSet {
        let s = &scene.settings;
        // The materials of the triangles that are in the BVH (only those can be hit).
        let included = scene.mesh.included();
        let used: Vec<_> = (included.iter())
            .map(|&i| &scene.materials[scene.material_of[i as usize] as usize])
            .collect();
        let kind_used = |k: MaterialKind| used.iter().any(|m| m.kind == k);
        let ao = s.integrator == Integrator::Ao;
        EffectSet {
            shadows: !ao && (!scene.lights.is_empty() || !scene.emitters.is_empty()),
            soft_shadows: !ao && !scene.emitters.is_empty(),
            mirror: !ao && kind_used(MaterialKind::Mirror),
            refraction: !ao && kind_used(MaterialKind::Glass),
            indirect: s.integrator == Integrator::Path && s.max_bounces >= 1,
            textures: !ao && used.iter().any(|m| m.texture.is_some()),
            ao,
            shading_normals: (included.iter()).any(|&i| {
                scene
                    .normals
                    .get(i as usize)
                    .is_some_and(|n| n[0] != NO_NORMAL)
            }),
        }
    }

    /// (name, on) for printing and for the WGSL override constants.
    pub fn flags(&self) -> [(&'static str, bool); 8] {
        [
            ("SHADOWS", self.shadows),
            ("SOFT_SHADOWS", self.soft_shadows),
            ("MIRROR", self.mirror),
            ("REFRACTION", self.refraction),
            ("INDIRECT", self.indirect),
            ("TEXTURES", self.textures),
            ("AO", self.ao),
            ("SHADING_NORMALS", self.shading_normals),
        ]
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
