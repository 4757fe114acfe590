//! The environment light: white furnace tests (a white diffuse sphere and a perfect
//! mirror under a sky of radiance 1 render 1 on the CPU and the GPU, with a uniform sky and
//! with a constant map, whose samples follow the map's cells rather than the sphere), a
//! map turned with the camera shows the same sky, the GPU renders a map scene as the CPU
//! does, the effect is compiled in only where a scene has an environment, and bad
//! `[environment]` tables are refused by line.

mod common;

use std::path::PathBuf;

use common::alike::assert_gpu_renders_as_cpu;
use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::render::{render, EffectSet, RenderOptions, RenderScene};
use lancer::Device;

fn image(scene: &RenderScene, device: &Device) -> Vec<Vec3> {
    render(scene, device, &RenderOptions::default())
        .unwrap()
        .image
        .pixels
}

/// The furnace at 16 spp.
fn furnace(dir: &Scratch, material: &str, environment: &str) -> RenderScene {
    common::furnace::furnace(dir, material, environment, 16)
}

/// The mean of the pixels and the largest distance of one from 1.
fn mean_and_worst(px: &[Vec3]) -> (f64, f32) {
    let mean = px
        .iter()
        .map(|c| c.x as f64 + c.y as f64 + c.z as f64)
        .sum::<f64>()
        / (3 * px.len()) as f64;
    let worst = (px.iter())
        .map(|c| (*c - Vec3::ONE).abs().max_element())
        .fold(0.0, f32::max);
    (mean, worst)
}

#[test]
fn white_furnace_a_white_sphere_and_a_perfect_mirror_vanish_under_a_white_sky() {
    let dir = Scratch::new();
    let map = dir.exr("white.exr", 16, 8, |_, _| [1.0; 3]);
    let skies = [
        ("uniform", "radiance = [1.0, 1.0, 1.0]".to_string()),
        ("map", format!("map = {:?}", map.to_str().unwrap())),
    ];
    let diffuse = "type = \"diffuse\"\nalbedo = [1.0, 1.0, 1.0]";
    let mirror = "type = \"mirror\"\nalbedo = [1.0, 1.0, 1.0]";
    for (sky, env) in &skies {
        for (what, material) in [("diffuse", diffuse), ("mirror", mirror)] {
            let scene = furnace(&dir, material, env);
            assert!(EffectSet::of(&scene).environment);
            for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
                let px = image(&scene, device);
                let (mean, worst) = mean_and_worst(&px);
                println!("{sky} sky, {what} sphere ({name}): mean {mean:.5}, worst pixel off by {worst:.4}");
                if what == "mirror" {
                    // Every sample reflects once into the sky: exactly 1.
                    assert!(
                        worst < 1e-5,
                        "{sky}, mirror, {name}: a pixel off by {worst}"
                    );
                } else {
                    assert!(
                        (mean - 1.0).abs() < 0.01,
                        "{sky}, diffuse, {name}: mean {mean}"
                    );
                    assert!(
                        worst < 0.25,
                        "{sky}, diffuse, {name}: a pixel off by {worst}"
                    );
                }
            }
        }
    }
    // The furnace can fail: a grey sphere is seen.
    let grey = furnace(
        &dir,
        "type = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]",
        &skies[0].1,
    );
    let (mean, _) = mean_and_worst(&image(&grey, &Device::cpu()));
    assert!(mean < 0.9, "a grey sphere vanishes too: mean {mean}");
}

/// A patterned sky around a small sphere, seen from `eye` toward the origin,
/// with the map and the sphere turned by `turn` degrees about Y.
fn turned(dir: &Scratch, eye: Vec3, turn: f32) -> RenderScene {
    // Colours that change with the azimuth and the elevation, and a bright spot.
    let sky = dir.exr("sky.exr", 64, 32, |x, y| {
        let spot = if (x, y) == (40, 12) { 30.0 } else { 0.0 };
        [
            x as f32 / 64.0 + spot,
            y as f32 / 32.0,
            0.3 + 0.2 * ((x / 8) % 2) as f32,
        ]
    });
    let text = format!(
        r#"
[camera]
position = [{}, {}, {}]
look_at = [0.0, 0.3, 0.0]
fov = 70.0
width = 48
height = 32

[render]
integrator = "path"
max_bounces = 2
spp = 8

[environment]
map = {:?}
rotate = [0.0, {turn}, 0.0]

[[objects]]
shape = "sphere"
scale = 0.3
rotate = [0.0, {turn}, 0.0]
"#,
        eye.x,
        eye.y,
        eye.z,
        sky.to_str().unwrap()
    );
    RenderScene::from_file(&dir.write(&format!("turned-{turn}.toml"), text)).unwrap()
}

#[test]
fn a_map_turned_with_the_camera_shows_the_same_sky() {
    let dir = Scratch::new();
    let eye = Vec3::new(0.0, 0.5, 3.0);
    let a = turned(&dir, eye, 0.0);
    let r = glam::Mat3::from_rotation_y(90f32.to_radians());
    let b = turned(&dir, r * eye, 90.0);
    let (pa, pb) = (image(&a, &Device::cpu()), image(&b, &Device::cpu()));
    // Pixels that see the sky: the same within the rotation's rounding.
    let f = a.camera.frame();
    let mut sky = 0;
    let mut worst = 0.0f32;
    for (i, (x, y)) in pa.iter().zip(&pb).enumerate() {
        let (px, py) = (i as u32 % 48, i as u32 / 48);
        let ray = f.ray(px, py, 0.5, 0.5);
        // Well away from the sphere (radius 0.3 about the origin, seen from 3 away).
        let to_centre = -ray.origin;
        let off_axis = (to_centre - ray.dir * to_centre.dot(ray.dir)).length();
        if off_axis > 0.6 {
            sky += 1;
            worst = worst.max(((*x - *y).abs() / x.max(Vec3::splat(0.05))).max_element());
        }
    }
    println!("{sky} sky pixels; worst relative difference {worst:.5}");
    assert!(sky > 1000);
    assert!(worst < 0.02, "the turned sky differs by {worst}");
    // Not the same sky unturned: the test can fail.
    let c = turned(&dir, r * eye, 0.0);
    let pc = image(&c, &Device::cpu());
    let changed = (pa.iter().zip(&pc))
        .filter(|(x, y)| (**x - **y).abs().max_element() > 0.05)
        .count();
    assert!(
        changed > 200,
        "the camera turned alone changes {changed} pixels"
    );
}

#[test]
fn the_gpu_renders_a_map_scene_as_the_cpu_does() {
    let mut scene =
        RenderScene::from_file(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/sky.toml"))
            .unwrap();
    scene.camera.width = 48;
    scene.camera.height = 36;
    let options = RenderOptions {
        spp: Some(4),
        ..RenderOptions::default()
    };
    // The map's lookups are polynomials, where lavapipe may fuse a multiply-add.
    assert_gpu_renders_as_cpu("sky.toml, CPU vs GPU", &scene, &options);
}

#[test]
fn the_environment_is_an_effect_only_where_a_scene_has_one() {
    let dir = Scratch::new();
    let with = furnace(&dir, "type = \"diffuse\"", "radiance = [0.2, 0.3, 0.4]");
    assert!(EffectSet::of(&with).environment && EffectSet::of(&with).shadows);
    let black = furnace(&dir, "type = \"diffuse\"", "radiance = [0.0, 0.0, 0.0]");
    assert!(black.environment.is_none());
    assert!(!EffectSet::of(&black).environment);
    // [render] background is the uniform environment's shorthand.
    let text = std::fs::read_to_string(dir.0.path().join("furnace.toml")).unwrap();
    let text = text
        .replace("[environment]\nradiance = [0.0, 0.0, 0.0]\n", "")
        .replace("spp = 16", "spp = 16\nbackground = [0.2, 0.3, 0.4]");
    let short = RenderScene::from_file(&dir.write("short.toml", text)).unwrap();
    assert_eq!(short.environment, with.environment);
}

#[test]
fn bad_environment_tables_are_refused_by_line() {
    let dir = Scratch::new();
    let nan = dir.exr("nan.exr", 4, 2, |x, _| {
        [if x == 2 { f32::NAN } else { 1.0 }, 1.0, 1.0]
    });
    let base = furnace(&dir, "type = \"diffuse\"", "radiance = [1.0, 1.0, 1.0]");
    drop(base);
    let text = std::fs::read_to_string(dir.0.path().join("furnace.toml")).unwrap();
    let cases = [
        (
            "radiance = [1.0, 1.0, 1.0]\nmap = \"sky.exr\"",
            "give 'radiance",
        ),
        ("radiance = [1.0, -1.0, 1.0]", "radiance must be finite"),
        ("radiance = [1.0, 1.0, 1.0]\nscale = 2.0", "go with a 'map'"),
        ("map = \"missing.exr\"", "missing.exr"),
        ("map = \"furnace.toml\"", "cannot read the environment map"),
        (
            &format!("map = {:?}", nan.to_str().unwrap()),
            "texel (2, 0)",
        ),
        ("map = \"nan.exr\"\nscale = -1.0", "scale must be finite"),
        ("radiance = [1.0, 1.0, 1.0]\nsun = 1.0", "unknown field"),
    ];
    for (table, want) in cases {
        let t = text.replace("radiance = [1.0, 1.0, 1.0]", table);
        let p = dir.write("bad.toml", t);
        let e = RenderScene::from_file(&p).unwrap_err().to_string();
        println!("{e}");
        assert!(e.contains(want), "{table}: {e}");
        assert!(
            e.contains("bad.toml:") || e.contains(".exr") || e.contains("furnace.toml"),
            "{table}: {e}"
        );
    }
    let t = text.replace("spp = 16", "spp = 16\nbackground = [1.0, 1.0, 1.0]");
    let e = RenderScene::from_file(&dir.write("both.toml", t))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not both") && e.contains("both.toml:"), "{e}");
}

#[test]
fn render_takes_an_environment_for_a_mesh_and_never_writes_over_the_map() {
    let dir = Scratch::new();
    let quad = dir.write(
        "quad.obj",
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n",
    );
    let sky = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/sky.hdr");
    let lancer = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(args)
            .args([
                "--width", "24", "--height", "16", "--spp", "2", "--device", "cpu",
            ])
            .output()
            .unwrap()
    };
    let (q, s) = (quad.to_str().unwrap(), sky.to_str().unwrap());
    let png = |name: &str| dir.0.path().join(name);
    let mean = |p: &PathBuf| {
        let img = image::open(p).unwrap().to_rgb8();
        img.pixels()
            .map(|p| p.0.iter().map(|&c| c as f64).sum::<f64>())
            .sum::<f64>()
            / img.pixels().len() as f64
    };
    for (name, extra) in [
        (
            "sky.png",
            vec!["--environment", s, "--environment-rotate", "0,90,0"],
        ),
        ("black.png", vec!["--environment", "0,0,0"]),
        ("default.png", vec![]),
    ] {
        let out = png(name);
        let o = lancer(&[&["render", q, "-o", out.to_str().unwrap()], &extra[..]].concat());
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let (lit, black, default) = (
        mean(&png("sky.png")),
        mean(&png("black.png")),
        mean(&png("default.png")),
    );
    println!("mean pixel: sky map {lit:.1}, black {black:.1}, default sky {default:.1}");
    assert!(black < lit && (lit - default).abs() > 5.0);
    // The map is an input: never an output.
    let map = dir.exr("map.exr", 8, 4, |x, _| [x as f32 / 8.0, 0.5, 0.5]);
    let before = std::fs::read(&map).unwrap();
    let m = map.to_str().unwrap();
    let o = lancer(&["render", q, "-o", m, "--environment", m]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("is an input"), "{err}");
    assert_eq!(std::fs::read(&map).unwrap(), before);
    let o = lancer(&[
        "render",
        q,
        "-o",
        png("x.png").to_str().unwrap(),
        "--environment",
        "1,-1,1",
    ]);
    assert_eq!(o.status.code(), Some(2));
}
