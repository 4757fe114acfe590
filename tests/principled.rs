//! glTF's metallic-roughness (`type = "principled"`): the BRDF is the specification's
//! (an f64 oracle written from its definitions agrees with `eval`), its samples' weights
//! average to the directional albedo quadrature of the oracle gives, white furnace tests
//! on the CPU and the GPU (a smooth metal of F0 = 1 vanishes under a white sky; a rough one
//! loses exactly the single-scattering energy the oracle predicts), the GPU renders a
//! textured principled scene as the CPU does, the effect is compiled in only where a scene
//! has such a surface, and bad materials are refused by line.

mod common;

use std::f64::consts::PI;

use common::alike::assert_alike;
use common::gpu_device;
use common::scratch::Scratch;
use glam::{DVec3, Vec3};
use lancer::render::{render, Bsdf, EffectSet, Principled, RenderOptions, RenderScene, Rng};
use lancer::Device;

/// glTF 2.0's reference BRDF (Appendix B) in f64, as the specification composes it:
/// mix(dielectric, metal, metallic), the dielectric a Fresnel mix (F0 = 0.04) of a Lambert
/// base and the specular lobe, the metal the lobe times Schlick's Fresnel of the base
/// colour; the lobe D·G2/(4 cos θo cos θi) with Trowbridge–Reitz's D in θh and Smith's
/// height-correlated G2 = 1/(1 + Λ(wo) + Λ(wi)). Normal +z.
fn oracle(p: &Principled, wo: DVec3, wi: DVec3) -> DVec3 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return DVec3::ZERO;
    }
    let a = p.alpha as f64;
    let h = (wo + wi).normalize();
    let tan2 = |c: f64| (1.0 - c * c) / (c * c);
    let d = a * a / (PI * h.z.powi(4) * (a * a + tan2(h.z)).powi(2));
    let lambda = |c: f64| (-1.0 + (1.0 + a * a * tan2(c)).sqrt()) / 2.0;
    let g2 = 1.0 / (1.0 + lambda(wo.z) + lambda(wi.z));
    let specular = d * g2 / (4.0 * wo.z * wi.z);
    let m5 = (1.0 - wo.dot(h)).powi(5);
    let base = p.base.as_dvec3();
    let metal = specular * (base + (DVec3::ONE - base) * m5);
    let fd = 0.04 + 0.96 * m5;
    let dielectric = base / PI * (1.0 - fd) + DVec3::splat(specular * fd);
    let m = p.metallic as f64;
    dielectric * (1.0 - m) + metal * m
}

/// The unit direction at polar angle θ (from +z) and azimuth φ.
fn polar(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// ∫ f(wo, wi) cos θi dωi over the hemisphere: the midpoint rule in (cos θi, φ).
fn albedo_quadrature(p: &Principled, wo: DVec3) -> DVec3 {
    let (nz, nphi) = (400, 400);
    let mut sum = DVec3::ZERO;
    for j in 0..nz {
        let z = (j as f64 + 0.5) / nz as f64;
        for i in 0..nphi {
            let phi = (i as f64 + 0.5) / nphi as f64 * 2.0 * PI;
            sum += oracle(p, wo, polar(z.acos(), phi)) * z;
        }
    }
    sum * (2.0 * PI / (nz * nphi) as f64)
}

fn materials() -> Vec<(&'static str, Principled)> {
    vec![
        (
            "rough metal",
            Principled::new(Vec3::new(0.95, 0.64, 0.54), 1.0, 0.8),
        ),
        (
            "glossy metal",
            Principled::new(Vec3::new(0.9, 0.9, 0.9), 1.0, 0.45),
        ),
        (
            "plastic",
            Principled::new(Vec3::new(0.8, 0.2, 0.1), 0.0, 0.6),
        ),
        (
            "half metal",
            Principled::new(Vec3::new(0.3, 0.6, 0.9), 0.5, 0.9),
        ),
    ]
}

#[test]
fn eval_is_the_specifications_brdf() {
    let mut rng = Rng::new(3, 5, 7);
    let mut worst = 0.0f64;
    for (name, p) in materials() {
        for _ in 0..2000 {
            let wo = polar((rng.next_f32() as f64 * 0.97).acos(), 0.0);
            let wi = polar(
                (rng.next_f32() as f64 * 0.97 + 0.01).acos(),
                rng.next_f32() as f64 * 2.0 * PI,
            );
            let (fcos, _) = p.eval(Vec3::Z, wo.as_vec3(), wi.as_vec3());
            let want = oracle(&p, wo, wi) * wi.z;
            let rel = ((fcos.as_dvec3() - want).abs() / want.max(DVec3::splat(1e-3))).max_element();
            assert!(rel < 1e-3, "{name}: wo {wo}, wi {wi}: {fcos} vs {want}");
            worst = worst.max(rel);
        }
    }
    println!("eval against the f64 oracle: worst relative difference {worst:.2e}");
    // Below the surface: nothing.
    let p = materials()[0].1;
    assert_eq!(p.eval(Vec3::Z, Vec3::Z, -Vec3::Z), (Vec3::ZERO, 0.0));
}

#[test]
fn sample_weights_average_to_the_directional_albedo() {
    const N: u32 = 200_000;
    for (name, p) in materials() {
        for deg in [0.0f64, 45.0, 75.0] {
            let wo = polar(deg.to_radians(), 0.0);
            let want = albedo_quadrature(&p, wo);
            let bsdf = Bsdf::Principled(p);
            let mut rng = Rng::new(1, deg as u32, 2);
            let (mut sum, mut sq) = (DVec3::ZERO, DVec3::ZERO);
            for _ in 0..N {
                if let Some(s) = bsdf.sample(Vec3::Z, wo.as_vec3(), &mut rng) {
                    let w = s.weight.as_dvec3();
                    sum += w;
                    sq += w * w;
                }
            }
            let mean = sum / N as f64;
            let se = ((sq / N as f64 - mean * mean) / N as f64).max(DVec3::ZERO);
            let se = DVec3::new(se.x.sqrt(), se.y.sqrt(), se.z.sqrt());
            println!(
                "{name}, view at {deg}°: sampled albedo {mean:.4} ± {se:.4}, quadrature {want:.4}"
            );
            // Five standard errors, plus the quadrature's own error.
            let tol = se * 5.0 + DVec3::splat(2e-3);
            assert!(
                (mean - want).abs().cmple(tol).all(),
                "{name} at {deg}°: {mean} vs {want}"
            );
            // Energy is never made: at most 1 (a metal's lobe loses some to masking).
            assert!(want.max_element() <= 1.0 + 1e-3, "{name}: {want}");
        }
    }
}

fn image(
    scene: &RenderScene,
    device: &Device,
    options: &RenderOptions,
) -> lancer::render::Rendered {
    render(scene, device, options).unwrap()
}

/// The furnace (a lone flat-faceted sphere of `material`) under a white sky, at 64 spp.
fn furnace(dir: &Scratch, material: &str) -> RenderScene {
    common::furnace::furnace(dir, material, "radiance = [1.0, 1.0, 1.0]", 64)
}

/// Pixels whose neighbours all hit the sphere (sample 0's depth finite): no sky in them.
fn inside(depth: &[f32], w: usize) -> Vec<usize> {
    (0..depth.len())
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            x > 0 && y > 0 && x + 1 < w && y + 1 < depth.len() / w && {
                let around = [i, i - 1, i + 1, i - w, i + w];
                around.iter().all(|&k| depth[k].is_finite())
            }
        })
        .collect()
}

#[test]
fn white_furnace_smooth_metal_vanishes_and_rough_metal_loses_its_single_scattering_energy() {
    let dir = Scratch::new();
    let options = RenderOptions {
        aovs: true,
        ..RenderOptions::default()
    };
    let smooth = furnace(
        &dir,
        "type = \"principled\"\nbase_color = [1.0, 1.0, 1.0]\nmetallic = 1.0\nroughness = 0.0",
    );
    let rough = furnace(
        &dir,
        "type = \"principled\"\nbase_color = [1.0, 1.0, 1.0]\nmetallic = 1.0\nroughness = 1.0",
    );
    assert!(EffectSet::of(&smooth).microfacet);
    let white = Principled::new(Vec3::ONE, 1.0, 1.0);
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        // F0 = 1 and a lobe narrower than a pixel: every sample reflects into the sky.
        // Within noise: multiple importance sampling shares the lobe's tails with the sky's
        // samples, a few per cent of a pixel at 64 spp.
        let r = image(&smooth, device, &options);
        let px = &r.image.pixels;
        let mean = px.iter().map(|c| c.x as f64).sum::<f64>() / px.len() as f64;
        let pix = inside(&r.aovs.as_ref().unwrap().depth, 32);
        let worst = (pix.iter())
            .map(|&i| (px[i] - Vec3::ONE).abs().max_element())
            .fold(0.0, f32::max);
        println!("smooth metal ({name}): mean {mean:.5}, worst pixel inside off by {worst:.5}");
        assert!(
            (mean - 1.0).abs() < 2e-3,
            "{name}: smooth metal mean {mean}"
        );
        assert!(worst < 0.05, "{name}: a smooth-metal pixel off by {worst}");

        // α = 1: what the lobe loses to masking is lost; the sphere's pixel at view
        // cosine μ is the lobe's directional albedo E(μ), from the oracle.
        let r = image(&rough, device, &options);
        let aovs = r.aovs.as_ref().unwrap();
        let cam = rough.camera.frame();
        let pix = inside(&aovs.depth, 32);
        assert!(pix.len() > 300, "{} pixels inside the sphere", pix.len());
        let (mut got, mut want) = (0.0f64, 0.0f64);
        for &i in &pix {
            let ray = cam.ray((i % 32) as u32, (i / 32) as u32, 0.5, 0.5);
            let mu = (-ray.dir.normalize()).dot(aovs.normal[i]).clamp(0.0, 1.0) as f64;
            want += albedo_quadrature(&white, DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu)).x;
            got += r.image.pixels[i].x as f64;
        }
        let (got, want) = (got / pix.len() as f64, want / pix.len() as f64);
        println!(
            "rough metal ({name}): mean {got:.4} over {} pixels, the oracle's E(μ) {want:.4}",
            pix.len()
        );
        assert!(
            (got - want).abs() < 0.01,
            "{name}: rough metal {got} vs {want}"
        );
        // The furnace can fail: the rough lobe visibly loses energy.
        assert!(got < 0.95, "{name}: the rough metal vanishes too ({got})");
    }
}

/// A floor with base colour and metallic-roughness textures, a smooth glossy metal sphere,
/// a plastic box with an emission texture, an area light, a point light and a sky map.
fn textured(dir: &Scratch) -> RenderScene {
    dir.png("base.png", 8, 8, |x, y| {
        if (x + y) % 2 == 0 {
            [230, 200, 150]
        } else {
            [60, 90, 160]
        }
    });
    // Green: roughness, blue: metalness, in stripes.
    dir.png("mr.png", 8, 8, |x, _| {
        [0, 40 + 25 * x as u8, if x < 4 { 255 } else { 0 }]
    });
    dir.png("glow.png", 4, 4, |x, y| {
        [(x * 60) as u8, (y * 60) as u8, 128]
    });
    dir.exr("sky.exr", 32, 16, |x, y| {
        [0.3 + x as f32 / 32.0, 0.5, 1.0 - y as f32 / 16.0]
    });
    let text = r#"
[camera]
position = [0.0, 1.2, 4.0]
look_at = [0.0, 0.4, 0.0]
fov = 45.0
width = 48
height = 36

[render]
integrator = "path"
max_bounces = 3
spp = 4

[environment]
map = "sky.exr"
scale = 0.5

[materials.floor]
type = "principled"
texture = "base.png"
metallic_roughness_texture = "mr.png"
metallic = 1.0
roughness = 1.0

[materials.ball]
type = "principled"
base_color = [0.95, 0.8, 0.5]
metallic = 1.0
roughness = 0.3

[materials.box]
type = "principled"
base_color = [0.2, 0.5, 0.3]
roughness = 0.5
emission = [2.0, 2.0, 2.0]
emission_texture = "glow.png"

[materials.lamp]
type = "emissive"
emission = [6.0, 6.0, 6.0]

[[objects]]
shape = "quad"
scale = 6.0
material = "floor"

[[objects]]
shape = "sphere"
segments = 16
translate = [-0.6, 0.5, 0.0]
scale = 0.5
material = "ball"

[[objects]]
shape = "box"
translate = [0.7, 0.35, 0.2]
scale = 0.7
rotate = [0.0, 30.0, 0.0]
material = "box"

[[objects]]
shape = "quad"
translate = [0.0, 2.5, 0.0]
rotate = [180.0, 0.0, 0.0]
material = "lamp"

[[lights]]
type = "point"
position = [2.0, 3.0, 2.0]
intensity = 4.0
"#;
    RenderScene::from_file(&dir.write("textured.toml", text)).unwrap()
}

#[test]
fn the_gpu_renders_a_textured_principled_scene_as_the_cpu_does() {
    let dir = Scratch::new();
    let scene = textured(&dir);
    let fx = EffectSet::of(&scene);
    assert!(
        fx.microfacet && fx.textures && fx.soft_shadows && fx.environment && fx.shading_normals
    );
    let options = RenderOptions::default();
    let cpu = image(&scene, &Device::cpu(), &options).image.pixels;
    let gpu = image(&scene, gpu_device(), &options).image.pixels;
    assert_alike("textured principled scene, CPU vs GPU", &cpu, &gpu);
    // Something to compare: lit, varied pixels.
    let lit = cpu.iter().filter(|c| c.max_element() > 0.05).count();
    assert!(lit * 2 > cpu.len(), "only {lit} pixels lit");
}

#[test]
fn microfacets_are_an_effect_only_where_a_scene_has_a_principled_surface() {
    let dir = Scratch::new();
    let scene = textured(&dir);
    let mut without = EffectSet::of(&scene);
    assert!(without.microfacet);
    without.microfacet = false;
    let diffuse = furnace(&dir, "type = \"diffuse\"");
    assert!(!EffectSet::of(&diffuse).microfacet);
    // Compiled out, a principled surface is its base colour's Lambert: another image.
    let on = image(&scene, &Device::cpu(), &RenderOptions::default())
        .image
        .pixels;
    let options = RenderOptions {
        effects: Some(without),
        ..RenderOptions::default()
    };
    let off = image(&scene, &Device::cpu(), &options).image.pixels;
    let changed = (on.iter().zip(&off))
        .filter(|(a, b)| (**a - **b).abs().max_element() > 0.05)
        .count();
    assert!(changed > 200, "microfacets change {changed} pixels");
}

#[test]
fn bad_principled_materials_are_refused_by_line() {
    let dir = Scratch::new();
    let good = "type = \"principled\"\nbase_color = [0.5, 0.5, 0.5]";
    let _ = furnace(&dir, good);
    let text = std::fs::read_to_string(dir.path("furnace.toml")).unwrap();
    let cases = [
        (
            "type = \"principled\"\nalbedo = [0.5, 0.5, 0.5]",
            "not 'albedo'",
        ),
        (
            "type = \"principled\"\nmetallic = 1.5",
            "metallic must be in [0, 1]",
        ),
        (
            "type = \"principled\"\nroughness = -0.1",
            "roughness must be in [0, 1]",
        ),
        (
            "type = \"diffuse\"\nmetallic = 0.5",
            "'metallic' applies to principled",
        ),
        (
            "type = \"glass\"\nemission_texture = \"a.png\"",
            "'emission_texture' applies",
        ),
        (
            "type = \"principled\"\nmetallic_roughness_texture = \"none.png\"",
            "none.png",
        ),
        (
            "type = \"principled\"\nemission = [1.0, -1.0, 0.0]",
            "emission must be finite",
        ),
    ];
    for (material, want) in cases {
        let t = text.replace(good, material);
        let e = RenderScene::from_file(&dir.write("bad.toml", t))
            .unwrap_err()
            .to_string();
        println!("{e}");
        assert!(
            e.contains(want) && e.contains("bad.toml:"),
            "{material}: {e}"
        );
    }
}
