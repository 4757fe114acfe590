//! A glTF asset that uses what DamagedHelmet uses (scenes/panel.glb, written by
//! scripts/make_panel.py): every texture of its metallic-roughness material reaches the
//! renderer; its emission glows only where its emissive texture is lit (the helmet rendered
//! as a white blob when the emissive factor lit the whole surface); the GPU renders it as
//! the CPU does; alpha mode MASK cuts it away (all of it under a low base colour alpha),
//! BLEND lets through the share of rays its alpha says.

mod common;

use std::path::PathBuf;

use common::alike::{assert_alike, assert_gpu_renders_as_cpu};
use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::accel::{Mask, Query, RayStats};
use lancer::render::{
    render, AlphaMask, EffectSet, MaterialKind, RenderOptions, RenderScene, TextureSlot,
};
use lancer::{AccelKind, Device, LayoutKind, Robustness};

fn panel() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/panel.glb")
}

#[test]
fn every_texture_of_a_helmet_like_material_is_used() {
    let scene = RenderScene::from_mesh(&panel(), 32, 24).unwrap();
    let m = &scene.materials[scene.material_of[0] as usize];
    assert_eq!(m.kind, MaterialKind::Principled);
    assert!(m.texture.is_some() && m.metallic_roughness_texture.is_some());
    assert!(m.emission_texture.is_some() && m.normal_texture.is_some());
    assert_eq!(m.emission, Vec3::new(4.0, 3.0, 1.5));
    assert!(
        scene.emitters.is_empty(),
        "textured emission is not an area light"
    );
    let fx = EffectSet::of(&scene);
    assert!(
        fx.microfacet && fx.textures && fx.normal_maps && fx.shading_normals,
        "{fx}"
    );
}

/// The panel alone in the dark, seen from the front: only its emission lights the image.
fn in_the_dark(dir: &Scratch) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 0.2, 3.2]
look_at = [0.0, 0.0, 0.0]
fov = 40.0
width = 48
height = 48

[render]
integrator = "direct"
spp = 4

[[objects]]
mesh = {:?}
"#,
        panel().to_str().unwrap()
    );
    RenderScene::from_file(&dir.write("dark.toml", text)).unwrap()
}

#[test]
fn emission_glows_only_where_the_emissive_texture_is_lit() {
    let dir = Scratch::new();
    let scene = in_the_dark(&dir);
    assert!(scene.lights.is_empty() && scene.environment.is_none());
    let glowing = |options: &RenderOptions| {
        let px = render(&scene, &Device::cpu(), options)
            .unwrap()
            .image
            .pixels;
        px.iter().filter(|c| c.max_element() > 0.05).count()
    };
    let lit = glowing(&RenderOptions::default());
    // Without textures the factor glows over the whole sphere: the test can fail.
    let mut flat = EffectSet::of(&scene);
    flat.textures = false;
    let blob = glowing(&RenderOptions {
        effects: Some(flat),
        ..RenderOptions::default()
    });
    println!("{lit} pixels glow with the emissive texture, {blob} without it");
    assert!(lit > 20, "the lit panels show: {lit} pixels");
    assert!(
        lit * 4 < blob,
        "a band of panels, not the sphere: {lit} vs {blob}"
    );
}

#[test]
fn the_gpu_renders_the_panel_as_the_cpu_does() {
    let scene = RenderScene::from_mesh(&panel(), 40, 30).unwrap();
    let options = RenderOptions {
        spp: Some(2),
        ..RenderOptions::default()
    };
    assert_gpu_renders_as_cpu("panel.glb, CPU vs GPU", &scene, &options);
}

/// The panel's JSON with its first material changed by `edit`, as a .gltf beside its
/// buffer in `dir`; its path.
fn edited_panel(dir: &Scratch, name: &str, edit: impl Fn(&mut serde_json::Value)) -> PathBuf {
    let glb = std::fs::read(panel()).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[20 + json_len + 8..];
    std::fs::write(dir.path("panel.bin"), bin).unwrap();
    doc["buffers"][0]["uri"] = "panel.bin".into();
    edit(&mut doc["materials"][0]);
    dir.write(name, serde_json::to_vec(&doc).unwrap())
}

#[test]
fn alpha_modes_mask_and_blend_cut_the_panel() {
    let dir = Scratch::new();
    let options = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    let pixels = |path: &PathBuf| {
        let scene = RenderScene::from_mesh(path, 24, 16).unwrap();
        let fx = EffectSet::of(&scene);
        let px = render(&scene, &Device::cpu(), &options)
            .unwrap()
            .image
            .pixels;
        (scene, fx, px)
    };
    let (_, fx, opaque) = pixels(&panel());
    assert!(!fx.alpha_mask);
    // MASK with the base colour's alpha 0.3 under the default cutoff 0.5: the whole panel
    // is cut away (its textures are opaque RGB), leaving the background.
    let cut = edited_panel(&dir, "cut.gltf", |m| {
        m["alphaMode"] = "MASK".into();
        m["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([1.0, 1.0, 1.0, 0.3]);
    });
    let (scene, fx, _) = pixels(&cut);
    let m = &scene.materials[scene.material_of[0] as usize];
    assert_eq!((m.alpha, m.alpha_cutoff), (0.3, Some(0.5)));
    assert!(fx.alpha_mask, "{fx}");
    // Camera rays through the scene's BVH (the panel and lancer's ground): with the mask,
    // none stops on the panel; without it, many do.
    let accel = lancer::accel::build(
        AccelKind::Bvh(LayoutKind::DfsSign),
        &scene.mesh,
        &Default::default(),
    )
    .unwrap();
    let mask = AlphaMask::new(&scene, EffectSet::of(&scene)).unwrap();
    let frame = scene.camera.frame();
    let on_panel = |mask: Mask<'_>| {
        let mut n = 0;
        for y in 0..scene.camera.height {
            for x in 0..scene.camera.width {
                let r = frame.ray(x, y, 0.5, 0.5);
                let mut stats = RayStats::default();
                let h = accel.intersect_masked(
                    &r,
                    Query::Closest,
                    &Robustness::default(),
                    mask,
                    &mut stats,
                );
                n += (h.is_hit() && scene.material_of[h.prim as usize] == scene.material_of[0])
                    as usize;
            }
        }
        n
    };
    let (with, without) = (on_panel(Some(&mask)), on_panel(None));
    println!("camera rays on the panel: {without} unmasked, {with} masked");
    assert!(
        without > 40 && with == 0,
        "{without} unmasked, {with} masked"
    );
    // Under its own alphaCutoff 0.2 nothing is cut: the opaque image, bit for bit.
    let kept = edited_panel(&dir, "kept.gltf", |m| {
        m["alphaMode"] = "MASK".into();
        m["alphaCutoff"] = 0.2.into();
        m["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([1.0, 1.0, 1.0, 0.3]);
    });
    let (_, fx, px) = pixels(&kept);
    assert!(fx.alpha_mask);
    assert!(px == opaque, "a panel above its cutoff changed");
    // BLEND: stochastic transparency. At the factor's alpha 1 every hit stays (the opaque
    // image, bit for bit); at 0.3 a camera ray that crosses the (closed) panel stops on
    // its near side or, past it, its far side: 1 − 0.7² = 51 % of them.
    let blend = edited_panel(&dir, "blend.gltf", |m| m["alphaMode"] = "BLEND".into());
    let (scene, fx, px) = pixels(&blend);
    assert!(scene.materials[scene.material_of[0] as usize].alpha_blend && fx.alpha_mask);
    assert!(px == opaque, "an opaque blend changed");
    let faint = edited_panel(&dir, "faint.gltf", |m| {
        m["alphaMode"] = "BLEND".into();
        m["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([1.0, 1.0, 1.0, 0.3]);
    });
    let (scene, _, _) = pixels(&faint);
    let mask = AlphaMask::new(&scene, EffectSet::of(&scene)).unwrap();
    let accel = lancer::accel::build(
        AccelKind::Bvh(LayoutKind::DfsSign),
        &scene.mesh,
        &Default::default(),
    )
    .unwrap();
    let frame = scene.camera.frame();
    let (mut on, mut all) = (0, 0);
    for y in 0..scene.camera.height {
        for x in 0..scene.camera.width {
            for k in 0..16 {
                let r = frame.ray(x, y, (k % 4) as f32 / 4.0, (k / 4) as f32 / 4.0);
                let q = |m: Mask<'_>| {
                    let h = accel.intersect_masked(
                        &r,
                        Query::Closest,
                        &Robustness::default(),
                        m,
                        &mut RayStats::default(),
                    );
                    h.is_hit() && scene.material_of[h.prim as usize] == scene.material_of[0]
                };
                if q(None) {
                    all += 1;
                    on += q(Some(&mask)) as usize;
                }
            }
        }
    }
    let (p, want) = (on as f64 / all as f64, 1.0 - 0.7 * 0.7);
    println!("BLEND at alpha 0.3: {on} of {all} camera rays on the panel stop there ({p:.3})");
    assert!(
        (p - want).abs() < 5.0 * (want * (1.0 - want) / all as f64).sqrt(),
        "{p}"
    );
}

#[test]
fn an_occlusion_texture_feeds_the_occlusion_aov() {
    let dir = Scratch::new();
    // The panel's metallic-roughness image as its occlusion texture too (glTF's packed
    // occlusion-roughness-metallic), at strength 0.5.
    let ao = edited_panel(&dir, "ao.gltf", |m| {
        let mr = m["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"].clone();
        m["occlusionTexture"] = serde_json::json!({ "index": mr, "strength": 0.5 });
    });
    let scene = RenderScene::from_mesh(&ao, 24, 16).unwrap();
    let m = &scene.materials[scene.material_of[0] as usize];
    assert!(m.occlusion_texture.is_some());
    assert_eq!(m.occlusion_strength, 0.5);
    let options = RenderOptions {
        spp: Some(1),
        aovs: true,
        ..RenderOptions::default()
    };
    let aovs = render(&scene, &Device::cpu(), &options)
        .unwrap()
        .aovs
        .unwrap();
    let on_panel: Vec<f32> = (aovs.occlusion.iter())
        .filter(|&&o| o != 1.0 && o != 0.0)
        .copied()
        .collect();
    println!("{} panel pixels with occlusion below 1", on_panel.len());
    assert!(on_panel.len() > 20 && on_panel.iter().all(|&o| (0.5..1.0).contains(&o)));
}

#[test]
fn texture_transforms_move_each_texture_on_both_devices() {
    let dir = Scratch::new();
    let plain = in_the_dark(&dir);
    assert!(!EffectSet::of(&plain).texture_transforms);
    // The emissive texture moved a quarter along v (its band of lit panels moves), the
    // normal map half a turn along u: each read at its own coordinates (lancer's v runs
    // up: glTF's offset down is −0.25 there).
    let moved = edited_panel(&dir, "moved.gltf", |m| {
        let t =
            |offset: [f32; 2]| serde_json::json!({ "KHR_texture_transform": { "offset": offset } });
        m["emissiveTexture"]["extensions"] = t([0.0, 0.25]);
        m["normalTexture"]["extensions"] = t([0.5, 0.0]);
    });
    let text = std::fs::read_to_string(dir.path("dark.toml")).unwrap();
    let panel_path = format!("{:?}", panel().to_str().unwrap());
    let text = text.replace(&panel_path, &format!("{:?}", moved.to_str().unwrap()));
    let scene = RenderScene::from_file(&dir.write("moved.toml", text)).unwrap();
    let m = &scene.materials[scene.material_of[0] as usize];
    let rows = |slot: TextureSlot| m.uv_transforms[slot as usize];
    assert_eq!(
        rows(TextureSlot::Emission),
        Some([[1.0, 0.0, 0.0], [0.0, 1.0, -0.25]])
    );
    assert_eq!(
        rows(TextureSlot::Normal),
        Some([[1.0, 0.0, 0.5], [0.0, 1.0, 0.0]])
    );
    assert_eq!(rows(TextureSlot::Base), None);
    // Each image is decoded once, however many coordinates read it.
    assert_eq!(scene.textures.len(), plain.textures.len());
    let fx = EffectSet::of(&scene);
    assert!(fx.texture_transforms, "{fx}");
    let options = RenderOptions::default();
    let glow = |scene: &RenderScene, options: &RenderOptions| {
        render(scene, &Device::cpu(), options).unwrap().image.pixels
    };
    let (a, b) = (glow(&plain, &options), glow(&scene, &options));
    let lit = |px: &[Vec3]| {
        px.iter()
            .map(|c| c.max_element() > 0.05)
            .collect::<Vec<_>>()
    };
    let moved_pixels = (lit(&a).iter())
        .zip(lit(&b))
        .filter(|(x, y)| **x != *y)
        .count();
    // Without the effect the file renders as the plain panel does, bit for bit.
    let mut unmoved = fx;
    unmoved.texture_transforms = false;
    let c = glow(
        &scene,
        &RenderOptions {
            effects: Some(unmoved),
            ..RenderOptions::default()
        },
    );
    println!("{moved_pixels} pixels glow or go dark where the emissive texture moved");
    assert!(moved_pixels > 20, "{moved_pixels}");
    assert_eq!(a, c);
    let gpu = render(&scene, gpu_device(), &options).unwrap().image.pixels;
    assert_alike("moved textures, CPU vs GPU", &b, &gpu);
}
