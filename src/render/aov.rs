//! Arbitrary output variables: what a denoiser takes beside the noisy image, from the first
//! hit of each pixel's camera ray in sample 0 (the same ray on the CPU and the GPU).

use glam::Vec3;

/// Which AOVs to write (the renderer computes all four when any is asked for).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovSet {
    /// Distance along the camera ray to the first hit (`depth.Z`; +∞ for a miss).
    pub depth: bool,
    /// The first hit's shading normal, facing the camera (`normal.X/Y/Z`; 0 for a miss).
    pub normal: bool,
    /// The first hit's reflectance, textured where the material is (`albedo.R/G/B`; 0 for a
    /// miss).
    pub albedo: bool,
    /// The first hit's ambient occlusion from its material's occlusion texture (glTF's
    /// `occlusionTexture`; `occlusion.Y`; 1 without one, 0 for a miss).
    pub occlusion: bool,
}

impl AovSet {
    /// True when any AOV is asked for.
    pub fn any(&self) -> bool {
        self.depth || self.normal || self.albedo || self.occlusion
    }
}

/// The AOVs of a render, one value per pixel (of the crop), row-major.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    /// First-hit distance (+∞ for a miss).
    pub depth: Vec<f32>,
    /// First-hit shading normal (zero for a miss).
    pub normal: Vec<Vec3>,
    /// First-hit albedo (zero for a miss).
    pub albedo: Vec<Vec3>,
    /// First-hit occlusion texture (1 without one, zero for a miss).
    pub occlusion: Vec<f32>,
}

/// One pixel's AOVs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstHit {
    /// Distance to the hit (+∞ for a miss).
    pub depth: f32,
    /// Shading normal (zero for a miss).
    pub normal: Vec3,
    /// Albedo (zero for a miss).
    pub albedo: Vec3,
    /// The material's occlusion texture there (1 without one, zero for a miss).
    pub occlusion: f32,
}

impl FirstHit {
    /// A camera ray that hit nothing.
    pub const MISS: FirstHit = FirstHit {
        depth: f32::INFINITY,
        normal: Vec3::ZERO,
        albedo: Vec3::ZERO,
        occlusion: 0.0,
    };
}

impl Aovs {
    /// Gathers per-pixel first hits.
    pub fn of(hits: &[FirstHit]) -> Aovs {
        Aovs {
            depth: hits.iter().map(|h| h.depth).collect(),
            normal: hits.iter().map(|h| h.normal).collect(),
            albedo: hits.iter().map(|h| h.albedo).collect(),
            occlusion: hits.iter().map(|h| h.occlusion).collect(),
        }
    }

    /// The EXR channels of the AOVs in `set`: `depth.Z`, `normal.X/Y/Z`, `albedo.R/G/B`,
    /// `occlusion.Y`.
    pub fn channels(&self, set: AovSet) -> Vec<(String, Vec<f32>)> {
        let mut out = Vec::new();
        if set.depth {
            out.push(("depth.Z".to_string(), self.depth.clone()));
        }
        let mut three = |on: bool, name: &str, v: &[Vec3], names: [&str; 3]| {
            if on {
                for (k, c) in names.iter().enumerate() {
                    out.push((format!("{name}.{c}"), v.iter().map(|p| p[k]).collect()));
                }
            }
        };
        three(set.normal, "normal", &self.normal, ["X", "Y", "Z"]);
        three(set.albedo, "albedo", &self.albedo, ["R", "G", "B"]);
        if set.occlusion {
            out.push(("occlusion.Y".to_string(), self.occlusion.clone()));
        }
        out
    }
}
