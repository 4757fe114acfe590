//! How a surface scatters light: Lambert's diffuse reflection, and glTF 2.0's
//! metallic-roughness model (its specification's reference BRDF, Appendix B): a GGX
//! (Trowbridge–Reitz) specular lobe with Smith's height-correlated masking-shadowing and
//! Schlick's Fresnel over a Lambert base. Sampled by the visible normals (Heitz 2018,
//! "Sampling the GGX Distribution of Visible Normals") or the cosine, one lobe chosen by
//! its Fresnel-weighted share. Shared, operation for operation, with
//! shaders/lib/bsdf.wgsl, so the CPU and the GPU draw the same directions.

use std::f32::consts::{FRAC_1_PI, PI};

use glam::Vec3;

use super::sampling::{basis, cosine_direction, Rng};
use super::trig::sin_cos_turns;
use crate::geometry::{cross, dot, normalize};

/// The reflectance at normal incidence of glTF's dielectric (index 1.5). WGSL
/// `DIELECTRIC_F0`.
pub const DIELECTRIC_F0: f32 = 0.04;

/// The smallest GGX α (roughness²) simulated: a smoother surface is this one, whose lobe
/// is still a finite function in f32 (its peak 1/(π α²) ≈ 3·10⁵). WGSL `ALPHA_MIN`.
pub const ALPHA_MIN: f32 = 1e-3;

/// Rec. 709 luminance weights, which share the lobes out. WGSL `LUMINANCE`.
pub const LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// A surface's scattering at one point, its textures already read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflection of this albedo.
    Diffuse(Vec3),
    /// glTF metallic-roughness.
    Principled(Principled),
}

/// glTF's metallic-roughness at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Principled {
    /// Base colour, linear RGB.
    pub base: Vec3,
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// GGX α: the perceptual roughness squared, at least [`ALPHA_MIN`].
    pub alpha: f32,
}

/// One scattered direction, with the throughput it carries (f·cos/pdf) and its density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The direction light arrives from (unit).
    pub dir: Vec3,
    /// f(wo, dir)·cos θ / pdf.
    pub weight: Vec3,
    /// The density the direction was drawn with, per steradian.
    pub pdf: f32,
}

fn luminance(c: Vec3) -> f32 {
    c.x * LUMINANCE[0] + c.y * LUMINANCE[1] + c.z * LUMINANCE[2]
}

/// (1 − c)⁵, Schlick's weight.
fn schlick_weight(c: f32) -> f32 {
    let m = (1.0 - c).max(0.0);
    let m2 = m * m;
    m2 * m2 * m
}

impl Principled {
    /// The surface of `base` colour, `metallic` and perceptual `roughness` (glTF's factors
    /// times its textures), each clamped to [0, 1].
    pub fn new(base: Vec3, metallic: f32, roughness: f32) -> Principled {
        let r = roughness.clamp(0.0, 1.0);
        Principled {
            base: base.clamp(Vec3::ZERO, Vec3::ONE),
            metallic: metallic.clamp(0.0, 1.0),
            alpha: (r * r).max(ALPHA_MIN),
        }
    }

    /// The reflectance at normal incidence: 0.04 for the dielectric, the base colour for
    /// the metal, mixed by metalness.
    pub fn f0(&self) -> Vec3 {
        Vec3::splat(DIELECTRIC_F0) * (1.0 - self.metallic) + self.base * self.metallic
    }

    /// The probability of sampling the specular lobe for a view at cosine `co` to the
    /// normal: its Fresnel reflectance's share of the two lobes' weights.
    pub fn specular_probability(&self, co: f32) -> f32 {
        let m5 = schlick_weight(co);
        let f0 = self.f0();
        let fs = luminance(f0 + (Vec3::ONE - f0) * m5);
        let fd = (1.0 - self.metallic)
            * (1.0 - (DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * m5))
            * luminance(self.base);
        if fs + fd > 0.0 {
            fs / (fs + fd)
        } else {
            1.0
        }
    }

    /// (f(wo, wi)·cos θi, pdf(wi)) about unit normal `n`; zero for either direction
    /// below the surface.
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let co = dot(n, wo);
        let ci = dot(n, wi);
        if co <= 0.0 || ci <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let h = normalize(wo + wi);
        let noh = dot(n, h);
        let voh = dot(wo, h);
        // sin²θh from the cross product: 1 − cos² loses the narrow lobe's peak in f32.
        let nh = cross(n, h);
        let sin2 = dot(nh, nh);
        let a2 = self.alpha * self.alpha;
        let k = noh * noh * a2 + sin2;
        let d = a2 / (PI * k * k);
        let vis = 0.5
            / (ci * (co * co * (1.0 - a2) + a2).sqrt() + co * (ci * ci * (1.0 - a2) + a2).sqrt());
        let m5 = schlick_weight(voh);
        let f0 = self.f0();
        let fresnel = f0 + (Vec3::ONE - f0) * m5;
        let kd = (1.0 - self.metallic) * (1.0 - (DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * m5));
        let f = fresnel * (d * vis) + self.base * (kd * FRAC_1_PI);
        // The visible normals' density of h, taken to wi: G1(wo)·D(h) / (4 cos θo).
        let g1 = 2.0 * co / (co + (a2 + (1.0 - a2) * co * co).sqrt());
        let spec_pdf = g1 * d / (4.0 * co);
        let ps = self.specular_probability(co);
        (f * ci, ps * spec_pdf + (1.0 - ps) * ci * FRAC_1_PI)
    }

    /// A normal drawn from the GGX distribution of normals visible from `wo` (unit, above
    /// `n`), by the two random numbers `u1`, `u2`.
    pub fn visible_normal(&self, n: Vec3, wo: Vec3, u1: f32, u2: f32) -> Vec3 {
        let (t, b) = basis(n);
        let a = self.alpha;
        // The view in the frame where the lobe is a hemisphere.
        let vh = normalize(Vec3::new(
            a * dot(wo, t),
            a * dot(wo, b),
            dot(wo, n).max(0.0),
        ));
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            let l = lensq.sqrt();
            Vec3::new(-vh.y / l, vh.x / l, 0.0)
        } else {
            Vec3::new(1.0, 0.0, 0.0)
        };
        let t2 = cross(vh, t1);
        let r = u1.sqrt();
        let (s, c) = sin_cos_turns(u2);
        let p1 = r * c;
        let sh = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - sh) * (1.0 - p1 * p1).max(0.0).sqrt() + sh * (r * s);
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let ne = normalize(Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)));
        t * ne.x + b * ne.y + n * ne.z
    }
}

impl Bsdf {
    /// (f(wo, wi)·cos θi, pdf(wi)) about unit normal `n` (wo: toward the viewer, wi:
    /// toward the light, both unit); zero below the surface.
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self {
            Bsdf::Diffuse(albedo) => {
                let c = dot(n, wi);
                if c <= 0.0 {
                    return (Vec3::ZERO, 0.0);
                }
                (*albedo * (c * FRAC_1_PI), c * FRAC_1_PI)
            }
            Bsdf::Principled(p) => p.eval(n, wo, wi),
        }
    }

    /// A direction scattered from `wo` about `n`, by the random numbers of `rng`; None
    /// where the sample carries no light (below the surface).
    pub fn sample(&self, n: Vec3, wo: Vec3, rng: &mut Rng) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse(albedo) => {
                let dir = cosine_direction(n, rng);
                let pdf = dot(n, dir) * FRAC_1_PI;
                (pdf > 0.0).then_some(BsdfSample {
                    dir,
                    weight: *albedo,
                    pdf,
                })
            }
            Bsdf::Principled(p) => {
                let dir = if rng.next_f32() < p.specular_probability(dot(n, wo)) {
                    let (u1, u2) = (rng.next_f32(), rng.next_f32());
                    let h = p.visible_normal(n, wo, u1, u2);
                    normalize(h * (2.0 * dot(wo, h)) - wo)
                } else {
                    cosine_direction(n, rng)
                };
                let (fcos, pdf) = p.eval(n, wo, dir);
                (pdf > 0.0).then(|| BsdfSample {
                    dir,
                    weight: fcos / pdf,
                    pdf,
                })
            }
        }
    }
}
