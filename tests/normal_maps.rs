//! Tangent-space normal maps: a constant map tilts a lit quad's shading exactly as the
//! frame of its texture coordinates says (turning the coordinates turns the tilt), on the
//! CPU and the GPU; the effect is compiled in only where a material has a map; a mirrored
//! copy keeps its bumps the right way out (placed = flattened); bad keys are refused.

mod common;

use std::f32::consts::FRAC_1_PI;

use common::alike::assert_alike;
use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::render::{render, EffectSet, RenderOptions, RenderScene};
use lancer::Device;

/// A 2 × 2 quad in the XZ plane facing +Y, with texture coordinates `uv(x, z)` at its
/// corners.
fn quad_obj(dir: &Scratch, name: &str, uv: impl Fn(f32, f32) -> (f32, f32)) {
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut text = String::new();
    for (x, z) in corners {
        text += &format!("v {x} 0 {z}\n");
    }
    for (x, z) in corners {
        let (u, v) = uv(x, z);
        text += &format!("vt {u} {v}\n");
    }
    text += "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\n";
    dir.write(name, text);
}

/// [`quad_obj`] with the normal +Y at every corner (shading normals).
fn smooth_quad_obj(dir: &Scratch, name: &str, uv: impl Fn(f32, f32) -> (f32, f32)) {
    quad_obj(dir, name, uv);
    let text = std::fs::read_to_string(dir.path(name)).unwrap();
    let text = text.replace(
        "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\n",
        "vn 0 1 0\nf 1/1/1 3/3/1 2/2/1\nf 1/1/1 4/4/1 3/3/1\n",
    );
    dir.write(name, text);
}

/// The quad `mesh` seen from above, of a white diffuse material with the normal map
/// `map`, lit by a directional light arriving from `from` (unit), direct light only.
fn lit_quad(dir: &Scratch, mesh: &str, map: &str, from: Vec3) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 3.0, 0.3]
look_at = [0.0, 0.0, 0.0]
fov = 20.0
width = 16
height = 16

[render]
integrator = "direct"
spp = 1

[materials.bumpy]
type = "diffuse"
albedo = [1.0, 1.0, 1.0]
normal_texture = "{map}"

[[objects]]
mesh = "{mesh}"
material = "bumpy"

[[lights]]
type = "directional"
direction = [{}, {}, {}]
intensity = 2.0
"#,
        -from.x, -from.y, -from.z
    );
    RenderScene::from_file(&dir.write("quad.toml", text)).unwrap()
}

/// A texel's tangent-space normal as the renderer reads it: 8 bits, linear, ×2 − 1.
fn decoded(texel: [u8; 3]) -> Vec3 {
    Vec3::from(texel.map(|c| c as f32 / 255.0)) * 2.0 - Vec3::ONE
}

#[test]
fn a_constant_map_tilts_the_shading_along_the_texture_frame() {
    let dir = Scratch::new();
    // Tilted 30° toward +u: (sin 30°, 0, cos 30°) in 8 bits.
    let texel = [191, 128, 238];
    dir.png("tilt.png", 4, 4, |_, _| texel);
    dir.png("flat.png", 4, 4, |_, _| [128, 128, 255]);
    let c = decoded(texel);
    // u along +x and v along −z; then u along −z and v along −x (turned 90°).
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    quad_obj(&dir, "turned.obj", |x, z| {
        ((1.0 - z) / 2.0, (1.0 - x) / 2.0)
    });
    let light = Vec3::new(1.0, 1.0, -0.5).normalize();
    for (mesh, t, b) in [
        ("plain.obj", Vec3::X, -Vec3::Z),
        ("turned.obj", -Vec3::Z, -Vec3::X),
    ] {
        let scene = lit_quad(&dir, mesh, "tilt.png", light);
        let fx = EffectSet::of(&scene);
        assert!(fx.normal_maps && fx.shading_normals, "{mesh}: {fx}");
        let n = (t * c.x + b * c.y + Vec3::Y * c.z).normalize();
        let want = 2.0 * FRAC_1_PI * n.dot(light);
        for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
            let px = render(&scene, device, &RenderOptions::default())
                .unwrap()
                .image
                .pixels;
            let worst = (px.iter())
                .map(|p| ((p.x - want) / want).abs())
                .fold(0.0, f32::max);
            println!(
                "{mesh} ({name}): want {want:.5}, got {:.5}, worst {worst:.1e}",
                px[0].x
            );
            assert!(worst < 1e-4, "{mesh} ({name}): {} vs {want}", px[0].x);
        }
    }
    // The test can fail: the two frames tilt the normal different ways, and a flat map
    // (128, 128, 255) leaves it almost upright.
    let a = render(
        &lit_quad(&dir, "plain.obj", "tilt.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let b = render(
        &lit_quad(&dir, "turned.obj", "tilt.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let f = render(
        &lit_quad(&dir, "plain.obj", "flat.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let (a, b, f) = (
        a.image.pixels[0].x,
        b.image.pixels[0].x,
        f.image.pixels[0].x,
    );
    let upright = 2.0 * FRAC_1_PI * light.y;
    println!("tilted toward +x {a:.4}, toward −z {b:.4}, flat {f:.4}, unmapped {upright:.4}");
    assert!((a - b).abs() > 0.05 && (f - upright).abs() < 0.01 * upright);
}

#[test]
fn normal_maps_are_an_effect_only_where_a_material_has_one() {
    let dir = Scratch::new();
    dir.png("tilt.png", 4, 4, |_, _| [191, 128, 238]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let light = Vec3::new(1.0, 1.0, 0.0).normalize();
    let scene = lit_quad(&dir, "plain.obj", "tilt.png", light);
    let mut without = EffectSet::of(&scene);
    assert!(without.normal_maps);
    without.normal_maps = false;
    let options = RenderOptions {
        effects: Some(without),
        ..RenderOptions::default()
    };
    let on = render(&scene, &Device::cpu(), &RenderOptions::default()).unwrap();
    let off = render(&scene, &Device::cpu(), &options).unwrap();
    assert!(
        (on.image.pixels[0] - off.image.pixels[0])
            .abs()
            .max_element()
            > 0.05
    );
    // Without a map, no tangents and no effect.
    let text = std::fs::read_to_string(dir.path("quad.toml")).unwrap();
    let text = text.replace("normal_texture = \"tilt.png\"\n", "");
    let bare = RenderScene::from_file(&dir.write("bare.toml", text)).unwrap();
    assert!(bare.tangents.is_empty());
    assert!(!EffectSet::of(&bare).normal_maps && !EffectSet::of(&bare).shading_normals);
}

#[test]
fn a_mirrored_copy_keeps_its_bumps_the_right_way_out() {
    let dir = Scratch::new();
    // Bumps in every direction.
    dir.png("bumps.png", 8, 8, |x, y| {
        [(60 + 20 * x) as u8, (200 - 18 * y) as u8, 220]
    });
    quad_obj(&dir, "flat.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    smooth_quad_obj(&dir, "smooth.obj", |x, z| {
        ((x + 1.0) / 2.0, (1.0 - z) / 2.0)
    });
    let text = r#"
[camera]
position = [0.0, 3.0, 2.0]
look_at = [0.0, 0.0, 0.0]
fov = 50.0
width = 40
height = 24

[render]
integrator = "direct"
spp = 2

[materials.bumpy]
type = "principled"
base_color = [0.8, 0.8, 0.8]
roughness = 0.4
normal_texture = "bumps.png"
normal_scale = 0.8

[[objects]]
mesh = "MESH"
material = "bumpy"

[[objects.copies]]
translate = [-1.2, 0.0, 0.0]

[[objects.copies]]
scale = [-1.0, 1.0, 1.0]
translate = [1.2, 0.0, 0.0]

[[lights]]
type = "point"
position = [1.0, 2.0, 1.0]
intensity = 3.0
"#;
    for mesh in ["flat.obj", "smooth.obj"] {
        let t = text.replace("MESH", mesh);
        let placed = RenderScene::from_file(&dir.write("copies.toml", t)).unwrap();
        assert!(placed.placements.is_some());
        let flat = placed.clone().flattened().unwrap();
        let options = RenderOptions::default();
        let a = render(&placed, &Device::cpu(), &options)
            .unwrap()
            .image
            .pixels;
        let b = render(&flat, &Device::cpu(), &options)
            .unwrap()
            .image
            .pixels;
        let g = render(&placed, gpu_device(), &options)
            .unwrap()
            .image
            .pixels;
        let lit = a.iter().filter(|c| c.max_element() > 0.02).count();
        assert!(lit > 300, "{mesh}: {lit} pixels lit");
        // The flattened scene's tangents are computed in world space, the placed scene's
        // moved by the copy's map; the mirror turns the winding, and the interpolated
        // normal's side against it decides the handedness.
        assert_alike(&format!("{mesh}, placed vs flattened"), &a, &b);
        assert_alike(&format!("{mesh}, CPU vs GPU"), &a, &g);
    }
}

#[test]
fn normal_map_keys_are_checked() {
    let dir = Scratch::new();
    dir.png("tilt.png", 2, 2, |_, _| [128, 128, 255]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let _ = lit_quad(&dir, "plain.obj", "tilt.png", Vec3::Y);
    let text = std::fs::read_to_string(dir.path("quad.toml")).unwrap();
    for (from, to, want) in [
        (
            "type = \"diffuse\"",
            "type = \"mirror\"",
            "'normal_texture' applies to diffuse and principled",
        ),
        (
            "normal_texture = \"tilt.png\"",
            "normal_texture = \"gone.png\"",
            "gone.png",
        ),
        (
            "albedo = [1.0, 1.0, 1.0]",
            "albedo = [1.0, 1.0, 1.0]\nnormal_scale = nan",
            "normal_scale must be finite",
        ),
    ] {
        let t = text.replace(from, to);
        let e = RenderScene::from_file(&dir.write("bad.toml", t))
            .unwrap_err()
            .to_string();
        println!("{e}");
        assert!(e.contains(want) && e.contains("bad.toml:"), "{to}: {e}");
    }
}

#[test]
fn a_map_that_leans_below_the_surface_falls_back_to_the_untilted_normal() {
    let dir = Scratch::new();
    // (1, 0, −0.5): under the surface seen from its front; (0.6, 0, 0.8): above it.
    dir.png("under.png", 4, 4, |_, _| [255, 128, 64]);
    dir.png("above.png", 4, 4, |_, _| [204, 128, 230]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let options = RenderOptions {
        aovs: true,
        ..RenderOptions::default()
    };
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        let under = lit_quad(&dir, "plain.obj", "under.png", Vec3::Y);
        let r = render(&under, device, &options).unwrap();
        let normals = r.aovs.unwrap().normal;
        assert!(
            normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-6),
            "{name}: {:?}",
            normals[0]
        );
        // A tilt above the surface is kept (the test can fail).
        let above = lit_quad(&dir, "plain.obj", "above.png", Vec3::Y);
        let n = render(&above, device, &options)
            .unwrap()
            .aovs
            .unwrap()
            .normal[0];
        println!("{name}: under → {}, above → {n}", normals[0]);
        assert!(n.x > 0.5 && n.y > 0.5, "{name}: {n}");
    }
}
