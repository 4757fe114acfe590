//! Alpha masks (glTF's alpha mode `MASK`): where a masked material's alpha — its `alpha`
//! times its texture's alpha channel — is below its cutoff, the surface is not there. The
//! test runs inside the traversal ([`HitMask`]), so every query skips those hits: camera,
//! bounce, shadow and AO rays alike, on the CPU and the GPU (WGSL `alpha_keeps`, the same
//! arithmetic). Stochastic transparency (glTF's `BLEND`) is the same test against a cutoff
//! drawn per hit: a hash of the triangle and the hit's barycentric coordinates, uniform in
//! [0, 1), the same bits on both devices.

use super::effects::EffectSet;
use super::sampling::pcg;
use super::scene::RenderScene;
use super::scene::TextureSlot;
use super::texture::{sample_alpha, texture_uv};
use crate::accel::HitMask;

/// The alpha masks of a scene's materials, as the traversal asks them.
pub struct AlphaMask<'a> {
    scene: &'a RenderScene,
    moved: bool,
    /// Triangles the scene renders: prims beyond are not its.
    triangles: u64,
}

impl<'a> AlphaMask<'a> {
    /// The masks of `scene`'s materials as a render simulating `fx` asks them: their
    /// textures read at moved coordinates where it simulates `texture-transforms`. A scene
    /// made in code whose arrays disagree is refused ([`RenderScene::check_arrays`]).
    pub fn new(scene: &'a RenderScene, fx: EffectSet) -> crate::Result<Self> {
        scene.check_arrays()?;
        Ok(AlphaMask::of_checked(scene, fx))
    }

    /// [`AlphaMask::new`] of a scene already checked (the renderers').
    pub(crate) fn of_checked(scene: &'a RenderScene, fx: EffectSet) -> Self {
        AlphaMask {
            scene,
            moved: fx.texture_transforms,
            triangles: scene.triangle_count(),
        }
    }
}

impl HitMask for AlphaMask<'_> {
    /// A triangle the scene does not have (a structure over another mesh) is kept.
    fn keeps(&self, prim: u32, u: f32, v: f32) -> bool {
        let scene = self.scene;
        if prim as u64 >= self.triangles {
            return true;
        }
        let shade = scene.shade_of(prim);
        let mat = &scene.materials[scene.material_of[shade] as usize];
        if mat.alpha_cutoff.is_none() && !mat.alpha_blend {
            return true;
        }
        let mut alpha = mat.alpha;
        if let Some(t) = mat.texture {
            let map = mat.uv_transforms[TextureSlot::Base as usize].filter(|_| self.moved);
            let uv = texture_uv(map, scene.uv_at(shade, u, v));
            alpha *= sample_alpha(&scene.textures[t], uv);
        }
        match mat.alpha_cutoff {
            Some(cutoff) => alpha >= cutoff,
            None => alpha > blend_threshold(prim, u, v),
        }
    }
}

/// The cutoff stochastic transparency draws for a hit on triangle `prim` at (u, v):
/// uniform in [0, 1) in steps of 2⁻²⁴. WGSL `blend_threshold`.
pub fn blend_threshold(prim: u32, u: f32, v: f32) -> f32 {
    let h = pcg(prim ^ pcg(u.to_bits() ^ pcg(v.to_bits())));
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}
