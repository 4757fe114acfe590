//! Alpha masks (glTF's alpha mode `MASK`): where a masked material's alpha — its `alpha`
//! times its texture's alpha channel — is below its cutoff, the surface is not there. The
//! test runs inside the traversal ([`HitMask`]), so every query skips those hits: camera,
//! bounce, shadow and AO rays alike, on the CPU and the GPU (WGSL `alpha_keeps`, the same
//! arithmetic).

use super::scene::RenderScene;
use super::texture::sample_alpha;
use crate::accel::HitMask;

/// The alpha masks of a scene's materials, as the traversal asks them.
pub struct AlphaMask<'a> {
    scene: &'a RenderScene,
}

impl<'a> AlphaMask<'a> {
    /// The masks of `scene`'s materials.
    pub fn new(scene: &'a RenderScene) -> Self {
        AlphaMask { scene }
    }
}

impl HitMask for AlphaMask<'_> {
    fn keeps(&self, prim: u32, u: f32, v: f32) -> bool {
        let scene = self.scene;
        let shade = scene.shade_of(prim);
        let mat = &scene.materials[scene.material_of[shade] as usize];
        let Some(cutoff) = mat.alpha_cutoff else {
            return true;
        };
        let mut alpha = mat.alpha;
        if let Some(t) = mat.texture {
            alpha *= sample_alpha(&scene.textures[t], scene.uv_at(shade, u, v));
        }
        alpha >= cutoff
    }
}
