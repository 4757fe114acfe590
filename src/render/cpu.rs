//! The CPU renderer: the integrator of shaders/kernels/render.wgsl, operation for
//! operation, over a CPU acceleration structure (a layout's twin). It is the reference the
//! GPU images are tested against.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::alpha::AlphaMask;
use super::aov::FirstHit;
use super::bsdf::{Bsdf, Principled};
use super::crop::Crop;
use super::effects::EffectSet;
use super::sampling::{cosine_direction, offset_origin, Rng};
use super::scene::{
    Integrator, Light, Material, MaterialKind, PlacedTriangle, RenderScene, TextureSlot,
};
use super::texture::{sample_texture, texture_uv};
use crate::accel::{Accel, HitMask, Mask, Query, RayStats};
use crate::camera::{CameraFrame, PRIMARY_TMAX};
use crate::geometry::{cross, dot, normalize};
use crate::geometry::{Hit, Ray, RayOffset, Robustness};

/// Whether a ray along `dir` meets the triangle's front (its winding's side), and the
/// triangle's unit normal turned toward where the ray comes from.
fn facing(v: &[Vec3; 3], dir: Vec3) -> (bool, Vec3) {
    let ng = normalize(cross(v[1] - v[0], v[2] - v[0]));
    let front = dot(ng, dir) < 0.0;
    (front, if front { ng } else { -ng })
}

/// A shading normal `s` (not normalised; None: flat) turned to the side of `n` (the
/// geometric normal facing where the ray comes from), or `n` itself where `s` has no
/// direction. WGSL `turned`.
fn turned(s: Option<Vec3>, n: Vec3) -> Vec3 {
    match s {
        Some(s) if dot(s, s) > 0.0 => {
            let s = normalize(s);
            if dot(s, n) < 0.0 {
                -s
            } else {
                s
            }
        }
        _ => n,
    }
}

/// Whether a direction `d` leaving a surface of geometric normal `n` (facing the side it
/// was hit from) stays on the side `toward` says (true: n's side): with shading normals,
/// light never passes through the geometric surface; without them, `d` was chosen about
/// `n` and is on its side already.
fn keeps_side(fx: EffectSet, d: Vec3, n: Vec3, toward: bool) -> bool {
    !fx.shading_normals || (dot(d, n) > 0.0) == toward
}

/// The weight multiple importance sampling gives a sample drawn with density `a` where
/// another strategy would draw it with density `b` (Veach's power heuristic, β = 2).
/// WGSL `power_heuristic`.
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    // As a ratio, so that no square overflows (a light's density grows as d²).
    if a >= b {
        let r = b / a;
        1.0 / (1.0 + r * r)
    } else {
        let r = a / b;
        r * r / (1.0 + r * r)
    }
}

/// The CPU renderer of one scene over one acceleration structure.
pub(crate) struct CpuRenderer<'a> {
    scene: &'a RenderScene,
    accel: &'a dyn Accel,
    robustness: Robustness,
    frame: CameraFrame,
    /// Total emitter area (the last CDF entry).
    emit_total: f32,
    /// The epsilon of [`RayOffset::Fixed`]: FIXED_OFFSET of the scene's diagonal.
    fixed_offset: f32,
    /// The materials' alpha masks, asked in the traversal where the effect is on: reading
    /// textures where they are ([0]) and where they are moved to ([1], the
    /// `texture-transforms` effect).
    alpha: [AlphaMask<'a>; 2],
}

impl<'a> CpuRenderer<'a> {
    /// A renderer of `scene` tracing through `accel` with the given robustness settings.
    pub fn new(scene: &'a RenderScene, accel: &'a dyn Accel, robustness: Robustness) -> Self {
        CpuRenderer {
            scene,
            accel,
            robustness,
            frame: scene.camera.frame(),
            emit_total: scene.emitter_cdf.last().copied().unwrap_or(0.0),
            // The scene's bounds are a pass over every triangle: only when the knob needs them.
            fixed_offset: if robustness.ray_offset == RayOffset::Fixed {
                scene.fixed_offset()
            } else {
                0.0
            },
            alpha: [false, true].map(|moved| {
                let fx = EffectSet {
                    texture_transforms: moved,
                    ..EffectSet::ALL
                };
                AlphaMask::of_checked(scene, fx)
            }),
        }
    }

    /// The alpha masks where the effect is on.
    fn mask(&self, fx: EffectSet) -> Mask<'_> {
        let alpha = &self.alpha[usize::from(fx.texture_transforms)];
        fx.alpha_mask.then_some(alpha as &dyn HitMask)
    }

    fn closest(&self, fx: EffectSet, r: &Ray) -> Hit {
        let mut stats = RayStats::default();
        let mask = self.mask(fx);
        (self.accel).intersect_masked(r, Query::Closest, &self.robustness, mask, &mut stats)
    }

    fn occluded(&self, fx: EffectSet, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let r = Ray::new(origin, dir, 0.0, tmax);
        let mut stats = RayStats::default();
        let mask = self.mask(fx);
        (self.accel)
            .intersect_masked(&r, Query::Any, &self.robustness, mask, &mut stats)
            .is_hit()
    }

    /// The origin of a secondary ray leaving p (error bound `err`) to the side n points to,
    /// by the robustness setting's offset.
    fn leave(&self, p: Vec3, err: Vec3, n: Vec3) -> Vec3 {
        match self.robustness.ray_offset {
            RayOffset::ErrorBound => offset_origin(p, err, n),
            RayOffset::Fixed => p + n * self.fixed_offset,
            RayOffset::None => p,
        }
    }

    /// Light reflected toward `wo` at p (error bound `err`, geometric normal n facing the
    /// viewer, shading normal ns) by `bsdf` from every light; none from below n.
    /// `bounces`: a bounce sampled from the BSDF follows, so the area lights' and the
    /// environment's samples are weighted by multiple importance sampling against it.
    fn direct(
        &self,
        fx: EffectSet,
        (p, err): (Vec3, Vec3),
        (n, ns): (Vec3, Vec3),
        (bsdf, wo): (&Bsdf, Vec3),
        bounces: bool,
        rng: &mut Rng,
    ) -> Vec3 {
        let o = self.leave(p, err, n);
        let mut sum = Vec3::ZERO;
        for l in &self.scene.lights {
            match *l {
                Light::Point {
                    position,
                    intensity,
                } => {
                    let d = position - p;
                    let d2 = dot(d, d);
                    let wi = d / d2.sqrt();
                    let c = dot(ns, wi);
                    let lit = c > 0.0 && keeps_side(fx, d, n, true);
                    if lit && !(fx.shadows && self.occluded(fx, o, position - o, 1.0)) {
                        sum += intensity * bsdf.eval(ns, wo, wi).0 / d2;
                    }
                }
                Light::Spot { .. } if !fx.spot_lights => {}
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    scale,
                    offset,
                } => {
                    let d = position - p;
                    let d2 = dot(d, d);
                    let wi = d / d2.sqrt();
                    let c = dot(ns, wi);
                    let falloff = Light::spot_falloff(-dot(direction, wi), scale, offset);
                    let lit = c > 0.0 && falloff > 0.0 && keeps_side(fx, d, n, true);
                    if lit && !(fx.shadows && self.occluded(fx, o, position - o, 1.0)) {
                        sum += intensity * bsdf.eval(ns, wo, wi).0 * (falloff / d2);
                    }
                }
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    let c = -dot(ns, direction);
                    let lit = c > 0.0 && keeps_side(fx, -direction, n, true);
                    if lit && !(fx.shadows && self.occluded(fx, o, -direction, PRIMARY_TMAX)) {
                        sum += irradiance * bsdf.eval(ns, wo, -direction).0;
                    }
                }
            }
        }
        if fx.soft_shadows && !self.scene.emitters.is_empty() {
            // One emitter, chosen in proportion to area, one uniform point on it.
            let target = rng.next_f32() * self.emit_total;
            let cdf = &self.scene.emitter_cdf;
            let (mut lo, mut hi) = (0usize, cdf.len() - 1);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if cdf[mid] > target {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            let tri = self.scene.triangle(self.scene.emitters[lo]);
            let su = rng.next_f32().sqrt();
            let b0 = 1.0 - su;
            let b1 = rng.next_f32() * su;
            let b2 = 1.0 - b0 - b1;
            let q = tri.v[0] * b0 + tri.v[1] * b1 + tri.v[2] * b2;
            let q_err = self.scene.point_error(&tri, q, [b0, b1, b2]);
            let nl = normalize(cross(tri.v[1] - tri.v[0], tri.v[2] - tri.v[0]));
            let d = q - p;
            let d2 = dot(d, d);
            let wi = d / d2.sqrt();
            let cs = dot(ns, wi);
            let mat = &self.scene.materials[self.scene.material_of[tri.shade] as usize];
            // One-sided lights emit from their front (the winding's normal) only.
            let cl = if mat.two_sided {
                dot(nl, wi).abs()
            } else {
                -dot(nl, wi)
            };
            if cs > 0.0 && cl > 0.0 && keeps_side(fx, d, n, true) {
                let toward = if dot(nl, d) > 0.0 { -nl } else { nl };
                let qt = self.leave(q, q_err, toward);
                if !(fx.shadows && self.occluded(fx, o, qt - o, 1.0)) {
                    let (fcos, pdf) = bsdf.eval(ns, wo, wi);
                    let w = if bounces {
                        power_heuristic(d2 / (cl * self.emit_total), pdf)
                    } else {
                        1.0
                    };
                    sum += mat.emission * fcos * (cl / d2 * self.emit_total * w);
                }
            }
        }
        if let Some(env) = (self.scene.environment.as_ref()).filter(|_| fx.environment) {
            let (u1, u2) = (rng.next_f32(), rng.next_f32());
            if let Some(e) = env.sample(u1, u2) {
                let c = dot(ns, e.dir);
                if c > 0.0 && keeps_side(fx, e.dir, n, true) {
                    let (fcos, pdf) = bsdf.eval(ns, wo, e.dir);
                    let w = if bounces {
                        power_heuristic(e.pdf, pdf)
                    } else {
                        1.0
                    };
                    let l = env.eval(e.dir) * fcos * (w / e.pdf);
                    if !(fx.shadows && self.occluded(fx, o, e.dir, PRIMARY_TMAX)) {
                        sum += l;
                    }
                }
            }
        }
        sum
    }

    /// The camera ray of sample `sample` of pixel (x, y) and the random numbers that follow
    /// its jitter.
    fn camera_ray(&self, seed: u32, x: u32, y: u32, sample: u32) -> (Ray, Rng) {
        let pixel = y * self.scene.camera.width + x;
        let mut rng = Rng::new(seed, pixel, sample);
        let (jx, jy) = (rng.next_f32(), rng.next_f32());
        (self.frame.ray(x, y, jx, jy), rng)
    }

    /// The texture in `slot` of the hit triangle's material at a hit, where textures are
    /// simulated.
    fn texture_at(
        &self,
        fx: EffectSet,
        slot: TextureSlot,
        shade: usize,
        hit: &Hit,
    ) -> Option<Vec3> {
        let mat = &self.scene.materials[self.scene.material_of[shade] as usize];
        let t = mat.texture_in(slot).filter(|_| fx.textures)?;
        let uv = self.slot_uv(fx, mat, slot, self.scene.uv_at(shade, hit.u, hit.v));
        Some(sample_texture(&self.scene.textures[t], uv))
    }

    /// Where `mat`'s texture in `slot` is read at interpolated coordinates `uv` (moved
    /// where texture transforms are simulated). WGSL `slot_uv`.
    fn slot_uv(&self, fx: EffectSet, mat: &Material, slot: TextureSlot, uv: Vec2) -> Vec2 {
        let map = mat.uv_transforms[slot as usize].filter(|_| fx.texture_transforms);
        texture_uv(map, uv)
    }

    /// The reflectance at a hit: the material's albedo, times its texture there (when
    /// textures are simulated).
    fn albedo(&self, fx: EffectSet, shade: usize, hit: &Hit) -> Vec3 {
        let mat = &self.scene.materials[self.scene.material_of[shade] as usize];
        match self.texture_at(fx, TextureSlot::Base, shade, hit) {
            Some(t) => t * mat.albedo,
            None => mat.albedo,
        }
    }

    /// How a diffuse or principled surface scatters at a hit (principled is diffuse where
    /// microfacets are not simulated).
    fn bsdf(&self, fx: EffectSet, shade: usize, hit: &Hit) -> Bsdf {
        let mat = &self.scene.materials[self.scene.material_of[shade] as usize];
        let albedo = self.albedo(fx, shade, hit);
        if !(fx.microfacet && mat.kind == MaterialKind::Principled) {
            return Bsdf::Diffuse(albedo);
        }
        let (mut metallic, mut roughness) = (mat.metallic, mat.roughness);
        if let Some(mr) = self.texture_at(fx, TextureSlot::MetallicRoughness, shade, hit) {
            roughness *= mr.y;
            metallic *= mr.z;
        }
        Bsdf::Principled(Principled::new(albedo, metallic, roughness))
    }

    /// A principled surface's emitted radiance at a hit: its emission times its emission
    /// texture.
    fn emission(&self, fx: EffectSet, shade: usize, hit: &Hit) -> Vec3 {
        let mat = &self.scene.materials[self.scene.material_of[shade] as usize];
        match self.texture_at(fx, TextureSlot::Emission, shade, hit) {
            Some(t) => mat.emission * t,
            None => mat.emission,
        }
    }

    /// The normal shading uses at a hit whose geometric normal, facing where the ray comes
    /// from, is `n`: the scene's shading normal (where shading normals are simulated) tilted
    /// by the material's normal map (where normal maps are), turned to n's side as the
    /// untilted normal is (glTF's rule for back faces), or the untilted normal where the
    /// tilt would lean below the surface; `n` itself where the effect is off or the
    /// triangle shades flat. WGSL `shading_side`.
    fn shading_side(&self, fx: EffectSet, tri: &PlacedTriangle, hit: &Hit, n: Vec3) -> Vec3 {
        if !fx.shading_normals {
            return n;
        }
        let w = 1.0 - hit.u - hit.v;
        let s = self.scene.shading_normal(tri, w, hit.u, hit.v);
        match self.mapped_normal(fx, tri, hit, s) {
            Some((m, front)) => {
                let m = if dot(front, n) < 0.0 { -m } else { m };
                if dot(m, m) > 0.0 && dot(m, n) > 0.0 {
                    normalize(m)
                } else {
                    turned(Some(front), n)
                }
            }
            None => turned(s, n),
        }
    }

    /// The normal map's normal at a hit (not normalised) and the unit normal `front` of the
    /// frame it tilts (the interpolated `s`, else the winding's); None where normal maps
    /// are not simulated or the triangle has no map or no tangent. WGSL `mapped_normal`.
    fn mapped_normal(
        &self,
        fx: EffectSet,
        tri: &PlacedTriangle,
        hit: &Hit,
        s: Option<Vec3>,
    ) -> Option<(Vec3, Vec3)> {
        if !fx.normal_maps {
            return None;
        }
        let mat = &self.scene.materials[self.scene.material_of[tri.shade] as usize];
        let map = mat.normal_texture?;
        let (t, flipped) = self.scene.tangent(tri, 1.0 - hit.u - hit.v, hit.u, hit.v)?;
        // The frame: the normal (interpolated, else the winding's), the tangent made
        // perpendicular to it, and their cross product turned by the handedness, which is
        // the winding's: turned again where the interpolated normal faces the other way
        // (a mirrored copy's, or a file's wound inward).
        let wn = cross(tri.v[1] - tri.v[0], tri.v[2] - tri.v[0]);
        let (n, flipped) = match s {
            Some(s) if dot(s, s) > 0.0 => (normalize(s), flipped != (dot(s, wn) < 0.0)),
            _ => (normalize(wn), flipped),
        };
        let t = t - n * dot(n, t);
        let t2 = dot(t, t);
        if t2.is_nan() || t2 <= 0.0 {
            return None;
        }
        let t = normalize(t);
        let b = cross(n, t) * if flipped { -1.0 } else { 1.0 };
        let uv = self.scene.uv_at(tri.shade, hit.u, hit.v);
        let uv = self.slot_uv(fx, mat, TextureSlot::Normal, uv);
        let c = sample_texture(&self.scene.textures[map], uv) * 2.0 - Vec3::ONE;
        let m = t * (c.x * mat.normal_scale) + b * (c.y * mat.normal_scale) + n * c.z;
        Some((m, n))
    }

    /// The AOVs of pixel (x, y): the first hit of its camera ray in sample 0.
    pub fn first_hit(&self, fx: EffectSet, seed: u32, x: u32, y: u32) -> FirstHit {
        let (ray, _) = self.camera_ray(seed, x, y, 0);
        let hit = self.closest(fx, &ray);
        if !hit.is_hit() {
            return FirstHit::MISS;
        }
        let tri = self.scene.triangle(hit.prim);
        let n = facing(&tri.v, ray.dir).1;
        FirstHit {
            depth: hit.t,
            normal: self.shading_side(fx, &tri, &hit, n),
            albedo: self.albedo(fx, tri.shade, &hit),
            occlusion: self.occlusion(fx, tri.shade, &hit),
        }
    }

    /// The material's occlusion texture at a hit, 1 + strength · (red − 1) (1 without one,
    /// or where textures are not simulated). WGSL `surface_occlusion`.
    fn occlusion(&self, fx: EffectSet, shade: usize, hit: &Hit) -> f32 {
        let mat = &self.scene.materials[self.scene.material_of[shade] as usize];
        match self.texture_at(fx, TextureSlot::Occlusion, shade, hit) {
            Some(t) => 1.0 + mat.occlusion_strength * (t.x - 1.0),
            None => 1.0,
        }
    }

    /// One sample of the radiance along the camera ray of a pixel, simulating `fx`, with
    /// the random numbers of (seed, pixel, sample).
    pub fn sample(&self, fx: EffectSet, seed: u32, x: u32, y: u32, sample: u32) -> Vec3 {
        let s = &self.scene.settings;
        let (mut ray, mut rng) = self.camera_ray(seed, x, y, sample);
        let mut radiance = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        // The density the last diffuse or principled bounce drew the ray's direction
        // with; 0 for a camera ray or a specular bounce (which no light sample can draw).
        let mut bounce_pdf = 0.0f32;
        let nee = fx.soft_shadows && !self.scene.emitters.is_empty();
        for bounce in 0..=s.max_bounces {
            let hit = self.closest(fx, &ray);
            if !hit.is_hit() {
                if let Some(env) = (self.scene.environment.as_ref()).filter(|_| fx.environment) {
                    let w = if bounce_pdf > 0.0 {
                        power_heuristic(bounce_pdf, env.pdf(ray.dir))
                    } else {
                        1.0
                    };
                    radiance += beta * env.eval(ray.dir) * w;
                }
                break;
            }
            let tri = self.scene.triangle(hit.prim);
            let mat = &self.scene.materials[self.scene.material_of[tri.shade] as usize];
            let w = 1.0 - hit.u - hit.v;
            let p = tri.v[0] * w + tri.v[1] * hit.u + tri.v[2] * hit.v;
            let p_err = self.scene.point_error(&tri, p, [w, hit.u, hit.v]);
            let (front, n) = facing(&tri.v, ray.dir);
            let ns = self.shading_side(fx, &tri, &hit, n);
            if mat.kind == MaterialKind::Emissive {
                if front || mat.two_sided {
                    // Multiple importance sampling with the light sample of the last hit.
                    let w = if nee && bounce_pdf > 0.0 {
                        let cl = dot(n, ray.dir).abs() / dot(ray.dir, ray.dir).sqrt();
                        let d2 = hit.t * hit.t * dot(ray.dir, ray.dir);
                        power_heuristic(bounce_pdf, d2 / (cl * self.emit_total))
                    } else {
                        1.0
                    };
                    radiance += beta * mat.emission * w;
                }
                break;
            }
            if fx.ao && s.integrator == Integrator::Ao {
                let d = cosine_direction(ns, &mut rng);
                let open = keeps_side(fx, d, n, true);
                if open && !self.occluded(fx, self.leave(p, p_err, n), d, s.ao_distance) {
                    radiance += beta;
                }
                break;
            }
            let last = bounce == s.max_bounces;
            let mirror = fx.mirror && mat.kind == MaterialKind::Mirror;
            let glass = fx.refraction && mat.kind == MaterialKind::Glass;
            let d = ray.dir;
            let reflected = d - ns * (2.0 * dot(d, ns));
            if (mirror || glass) && last {
                break;
            }
            if mirror {
                if !keeps_side(fx, reflected, n, true) {
                    break;
                }
                beta *= mat.albedo;
                ray = Ray::new(self.leave(p, p_err, n), reflected, 0.0, PRIMARY_TMAX);
                bounce_pdf = 0.0;
                continue;
            }
            if glass {
                let cos_i = -dot(d, ns);
                let eta = if front { 1.0 / mat.ior } else { mat.ior };
                let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
                let r0 = (1.0 - mat.ior) / (1.0 + mat.ior);
                let r0 = r0 * r0;
                let m = 1.0 - cos_i;
                let fresnel = r0 + (1.0 - r0) * (m * m * m * m * m);
                let u = rng.next_f32();
                beta *= mat.albedo;
                bounce_pdf = 0.0;
                if sin2_t >= 1.0 || u < fresnel {
                    if !keeps_side(fx, reflected, n, true) {
                        break;
                    }
                    ray = Ray::new(self.leave(p, p_err, n), reflected, 0.0, PRIMARY_TMAX);
                } else {
                    let cos_t = (1.0 - sin2_t).sqrt();
                    let t = d * eta + ns * (eta * cos_i - cos_t);
                    if !keeps_side(fx, t, n, false) {
                        break;
                    }
                    ray = Ray::new(self.leave(p, p_err, -n), t, 0.0, PRIMARY_TMAX);
                }
                continue;
            }
            // Diffuse or principled.
            let bsdf = self.bsdf(fx, tri.shade, &hit);
            let wo = -d;
            let mut ns = ns;
            if let Bsdf::Principled(_) = bsdf {
                if front || mat.two_sided {
                    radiance += beta * self.emission(fx, tri.shade, &hit);
                }
                // A view below the shading normal sees the geometric one.
                if dot(ns, wo) <= 0.0 {
                    ns = n;
                }
            }
            let bounces = fx.indirect && s.integrator == Integrator::Path && !last;
            let light = self.direct(fx, (p, p_err), (n, ns), (&bsdf, wo), bounces, &mut rng);
            radiance += beta * light;
            if !bounces {
                break;
            }
            let Some(b) = bsdf.sample(ns, wo, &mut rng) else {
                break;
            };
            if !keeps_side(fx, b.dir, n, true) {
                break;
            }
            beta *= b.weight;
            ray = Ray::new(self.leave(p, p_err, n), b.dir, 0.0, PRIMARY_TMAX);
            bounce_pdf = b.pdf;
        }
        radiance
    }

    /// Adds samples [first, first + count) of every pixel of `crop` to `accum` (row-major
    /// in the crop), with the full image's random numbers.
    pub fn accumulate(
        &self,
        fx: EffectSet,
        seed: u32,
        crop: Crop,
        accum: &mut [Vec3],
        first: u32,
        count: u32,
    ) {
        accum.par_iter_mut().enumerate().for_each(|(i, a)| {
            let (x, y) = crop.pixel(i);
            for s in first..first + count {
                *a += self.sample(fx, seed, x, y, s);
            }
        });
    }
}
