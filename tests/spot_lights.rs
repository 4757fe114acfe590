//! Spot lights: a spot over a floor lights it as the glTF falloff predicts (full within the
//! inner angle, nothing beyond the outer one) on the CPU and the GPU alike; glTF
//! `KHR_lights_punctual` lights are read with their nodes' maps and light `render MESH` in
//! place of the default sun; bad spot tables are refused by line.

mod common;

use std::path::PathBuf;

use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::render::{render, EffectSet, Light, RenderOptions, RenderScene};
use lancer::Device;

const SPOT_HEIGHT: f32 = 2.0;
const INTENSITY: f32 = 8.0;
const ALBEDO: f32 = 0.5;

/// A floor seen from straight above, under a spot light `light` (a TOML table body).
fn floor_under(dir: &Scratch, light: &str) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 6.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov = 60.0
width = 40
height = 40

[render]
integrator = "direct"
spp = 16

[materials.floor]
type = "diffuse"
albedo = [{ALBEDO}, {ALBEDO}, {ALBEDO}]

[[objects]]
shape = "quad"
scale = 20.0
material = "floor"

[[lights]]
{light}
"#
    );
    RenderScene::from_file(&dir.write("spot.toml", text)).unwrap()
}

#[test]
fn a_spot_lights_the_floor_as_its_falloff_predicts_on_both_devices() {
    let dir = Scratch::new();
    let spot = format!(
        "type = \"spot\"\nposition = [0.0, {SPOT_HEIGHT}, 0.0]\ndirection = [0.0, -1.0, 0.0]\n\
         intensity = {INTENSITY}\ninner_angle = 20.0\nouter_angle = 30.0"
    );
    let scene = floor_under(&dir, &spot);
    let f = scene.camera.frame();
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        let px = render(&scene, device, &RenderOptions::default())
            .unwrap()
            .image
            .pixels;
        let (mut full, mut dark, mut between) = (0, 0, 0);
        for (i, c) in px.iter().enumerate() {
            let ray = f.ray(i as u32 % 40, i as u32 / 40, 0.5, 0.5);
            // Where the pixel's centre ray meets the floor, and its angle off the spot's axis.
            let q = ray.origin + ray.dir * (-ray.origin.y / ray.dir.y);
            let r = (q.x * q.x + q.z * q.z).sqrt();
            let angle = r.atan2(SPOT_HEIGHT).to_degrees();
            let d2 = r * r + SPOT_HEIGHT * SPOT_HEIGHT;
            let lambert =
                ALBEDO / std::f32::consts::PI * INTENSITY * (SPOT_HEIGHT / d2.sqrt()) / d2;
            if angle < 18.0 {
                assert!(
                    (c.x - lambert).abs() < 0.02 * lambert,
                    "{name}: {c} against {lambert} at {angle:.1}°"
                );
                full += 1;
            } else if angle > 32.0 {
                assert_eq!(c.x, 0.0, "{name}: lit at {angle:.1}°, beyond the cone");
                dark += 1;
            } else if (22.0..28.0).contains(&angle) {
                assert!(
                    c.x > 0.0 && c.x < lambert,
                    "{name}: {c} at {angle:.1}° in the falloff"
                );
                between += 1;
            }
        }
        println!("{name}: {full} pixels in full light, {between} in the falloff, {dark} dark");
        assert!(full > 40 && dark > 400 && between > 40);
    }
    // The effect is compiled in only where a spot is, and off, it lights nothing.
    let fx = EffectSet::of(&scene);
    assert!(fx.spot_lights);
    let off = EffectSet {
        spot_lights: false,
        ..fx
    };
    for device in [&Device::cpu(), gpu_device()] {
        let opts = RenderOptions {
            effects: Some(off),
            ..RenderOptions::default()
        };
        let px = render(&scene, device, &opts).unwrap().image.pixels;
        assert!(
            px.iter().all(|c| *c == Vec3::ZERO),
            "spot lights off still light"
        );
    }
    // The test can fail: a point light of the same intensity lights beyond the cone.
    let point =
        format!("type = \"point\"\nposition = [0.0, {SPOT_HEIGHT}, 0.0]\nintensity = {INTENSITY}");
    let px = render(
        &floor_under(&dir, &point),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap()
    .image
    .pixels;
    assert!(px[0].x > 0.0, "a point light leaves the corner dark");
    assert!(!EffectSet::of(&floor_under(&dir, &point)).spot_lights);
}

#[test]
fn bad_spot_tables_are_refused_by_line() {
    let dir = Scratch::new();
    let base = "type = \"spot\"\nposition = [0.0, 2.0, 0.0]\ndirection = [0.0, -1.0, 0.0]";
    let cases = [
        (
            "type = \"spot\"\nposition = [0.0, 2.0, 0.0]".to_string(),
            "needs 'position' and 'direction'",
        ),
        (
            format!("{base}\ninner_angle = 30.0\nouter_angle = 20.0"),
            "inner_angle < outer_angle",
        ),
        (format!("{base}\nouter_angle = 120.0"), "≤ 90 degrees"),
        (
            "type = \"point\"\nposition = [0.0, 2.0, 0.0]\nouter_angle = 20.0".to_string(),
            "are for spot lights",
        ),
    ];
    for (table, want) in cases {
        let scene = format!(
            "[camera]\nposition = [0.0, 6.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
             [[objects]]\nshape = \"quad\"\n\n[[lights]]\n{table}\n"
        );
        let e = RenderScene::from_file(&dir.write("bad.toml", scene))
            .unwrap_err()
            .to_string();
        println!("{e}");
        assert!(e.contains(want) && e.contains("bad.toml:"), "{table}: {e}");
    }
}

/// A glTF quad on y = 0 with three lights: a point light at (0, 3, 0) of 683 cd, a spot
/// turned to shine down −Y from (1, 2, 0), and a directional one with a `range` (warned).
fn gltf_with_lights(dir: &Scratch) -> PathBuf {
    let m = common::writers::Indexed {
        verts: vec![
            [-2.0, 0.0, 2.0],
            [2.0, 0.0, 2.0],
            [2.0, 0.0, -2.0],
            [-2.0, 0.0, -2.0],
        ],
        faces: vec![vec![0, 1, 2], vec![0, 2, 3]],
    };
    let bin = common::writers::gltf_buffer(&m);
    let mut doc = common::writers::gltf_json(&m, Some(common::writers::data_uri(&bin)));
    let h = std::f32::consts::FRAC_1_SQRT_2;
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
    doc["extensions"] = serde_json::json!({ "KHR_lights_punctual": { "lights": [
        { "type": "point", "name": "Bulb", "intensity": 683.0, "color": [1.0, 0.5, 0.25] },
        { "type": "spot", "intensity": 1366.0, "spot": { "innerConeAngle": 0.2, "outerConeAngle": 0.5 } },
        { "type": "directional", "intensity": 2.0, "range": 10.0 }
    ] } });
    doc["nodes"] = serde_json::json!([
        { "mesh": 0 },
        { "extensions": { "KHR_lights_punctual": { "light": 0 } }, "translation": [0, 3, 0] },
        // −Z turned to −Y: a quarter turn about X.
        { "extensions": { "KHR_lights_punctual": { "light": 1 } }, "translation": [1, 2, 0],
          "rotation": [-h, 0, 0, h] },
        { "extensions": { "KHR_lights_punctual": { "light": 2 } } }
    ]);
    doc["scenes"] = serde_json::json!([{ "nodes": [0, 1, 2, 3] }]);
    dir.write("lights.gltf", serde_json::to_vec(&doc).unwrap())
}

#[test]
fn gltf_lights_are_read_in_place_and_light_the_file_instead_of_the_sun() {
    let dir = Scratch::new();
    let g = gltf_with_lights(&dir);
    let loaded = lancer::mesh::load_gltf(&g).unwrap();
    assert_eq!(loaded.lights.len(), 3, "{:?}", loaded.lights);
    let near = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    let bulb = &loaded.lights[0];
    assert_eq!(bulb.name.as_deref(), Some("Bulb"));
    assert!(near(bulb.position, Vec3::new(0.0, 3.0, 0.0)));
    assert!(near(bulb.photometric, Vec3::new(683.0, 341.5, 170.75)));
    let spot = &loaded.lights[1];
    assert!(near(spot.position, Vec3::new(1.0, 2.0, 0.0)));
    assert!(near(spot.direction, -Vec3::Y), "{:?}", spot.direction);
    let scene = RenderScene::from_mesh(&g, 32, 32).unwrap();
    // The file's lights in W/sr and W/m² (÷ 683), and no sun.
    assert_eq!(scene.lights.len(), 3);
    match scene.lights[0] {
        Light::Point {
            position,
            intensity,
        } => {
            assert!(near(position, Vec3::new(0.0, 3.0, 0.0)));
            assert!(near(intensity, Vec3::new(1.0, 0.5, 0.25)));
        }
        l => panic!("{l:?}"),
    }
    assert!(matches!(scene.lights[1], Light::Spot { direction, .. } if near(direction, -Vec3::Y)));
    assert!(
        matches!(scene.lights[2], Light::Directional { direction, .. } if near(direction, -Vec3::Z))
    );
    // Lit on both devices, the same.
    let opts = RenderOptions::default();
    let cpu = render(&scene, &Device::cpu(), &opts).unwrap().image.pixels;
    let gpu = render(&scene, gpu_device(), &opts).unwrap().image.pixels;
    let same = cpu
        .iter()
        .zip(&gpu)
        .filter(|(a, b)| (**a - **b).abs().max_element() < 1e-4)
        .count();
    assert!(
        same * 100 >= cpu.len() * 98,
        "{same} of {} pixels agree",
        cpu.len()
    );
}
