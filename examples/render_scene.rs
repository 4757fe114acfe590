//! Render a scene file to a PNG.
//!
//! `cargo run --release --example render_scene [-- OUT.png [SCENE.toml]]`
//!
//! Reads `scenes/cornell.toml` (or the scene named), renders it small and quickly — 64×64
//! pixels, 4 samples per pixel — on a hardware GPU where one opens and on the CPU otherwise,
//! and writes the image to the temporary folder (or OUT.png).

use std::path::PathBuf;
use std::time::Instant;

use lancer::render::render;
use lancer::{Device, DeviceChoice, RenderOptions, RenderScene};

fn main() -> lancer::Result<()> {
    let mut args = std::env::args_os().skip(1);
    let out = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("lancer-render-scene.png"));
    // The scene file: camera, objects (meshes with their materials), lights, settings. Files
    // it names (meshes, MTL, textures) are found beside it.
    let scene_path = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml"));
    let mut scene = RenderScene::from_file(&scene_path)?;
    println!(
        "scene: {} ({} triangles)",
        scene_path.display(),
        scene.mesh.len()
    );

    // Smaller than the file asks for, so the example takes a moment.
    (scene.camera.width, scene.camera.height) = (64, 64);
    let options = RenderOptions {
        spp: Some(4),
        ..RenderOptions::default()
    };

    // A hardware GPU when one opens, else the CPU (and why).
    let device = Device::open(DeviceChoice::Auto)?;
    match device.fallback() {
        Some(why) => println!("device: {device} ({why})"),
        None => println!("device: {device}"),
    }

    let start = Instant::now();
    let rendered = render(&scene, &device, &options)?;
    println!(
        "rendered {}×{} at {} samples per pixel in {:.2} s",
        rendered.image.width,
        rendered.image.height,
        rendered.samples,
        start.elapsed().as_secs_f64()
    );
    // PNG (8-bit sRGB) or EXR (linear), by the extension; written atomically.
    rendered.image.save(&out)?;
    println!("wrote {}", out.display());
    Ok(())
}
