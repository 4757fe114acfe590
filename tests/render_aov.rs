//! Image outputs for denoisers and grading: AOVs (first-hit depth, normal, albedo, occlusion
//! of sample 0's camera rays) equal on the CPU and the GPU, depth equal to the primary ray's
//! closest hit t, occlusion the material's occlusion texture, AOVs of tiles merging into the
//! full render's; 16-bit PNGs.

mod common;

use std::path::PathBuf;

use common::gpu_device;
use lancer::accel::{build, AccelKind};
use lancer::render::{
    merge_tiles, render, AovSet, Aovs, Crop, RenderOptions, RenderScene, Rendered, Rng,
};
use lancer::{Device, Query, RayStats, Robustness};

fn scene(name: &str) -> RenderScene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
    let mut s = RenderScene::from_file(&p).unwrap();
    (s.camera.width, s.camera.height) = (48, 36);
    s
}

fn with_aovs(s: &RenderScene, device: &Device, crop: Option<Crop>) -> Rendered {
    let options = RenderOptions {
        spp: Some(1),
        aovs: true,
        crop,
        ..RenderOptions::default()
    };
    let r = render(s, device, &options).unwrap();
    assert_eq!(r.cpu_pixels, 0, "pixels rendered again on the CPU");
    r
}

const ALL: AovSet = AovSet {
    depth: true,
    normal: true,
    albedo: true,
    occlusion: true,
};

fn bits(a: &Aovs) -> Vec<(String, Vec<u32>)> {
    (a.channels(ALL).into_iter())
        .map(|(n, v)| (n, v.iter().map(|x| x.to_bits()).collect()))
        .collect()
}

#[test]
fn aovs_are_the_same_on_the_cpu_and_the_gpu() {
    // textured: texture lookups in the albedo; glass-mirror: mirror and glass first hits.
    for name in ["textured", "glass-mirror"] {
        let s = scene(name);
        let cpu = with_aovs(&s, &Device::cpu(), None).aovs.unwrap();
        let gpu = with_aovs(&s, gpu_device(), None).aovs.unwrap();
        let (c, g) = (bits(&cpu), bits(&gpu));
        for ((name_c, vc), (_, vg)) in c.iter().zip(&g) {
            let differ = vc.iter().zip(vg).filter(|(a, b)| a != b).count();
            println!("{name} {name_c}: {differ} of {} values differ", vc.len());
        }
        assert_eq!(c, g, "{name}: CPU and GPU AOVs differ");
        // Something to compare: hits and misses, several normals and albedos.
        let hits = cpu.depth.iter().filter(|d| d.is_finite()).count();
        assert!(hits > 100 && hits < cpu.depth.len(), "{name}: {hits} hits");
        let mut normals: Vec<[u32; 3]> = (cpu.normal.iter())
            .map(|n| n.to_array().map(f32::to_bits))
            .collect();
        normals.sort();
        normals.dedup();
        assert!(normals.len() >= 3, "{name}: {} normals", normals.len());
        for (d, n) in cpu.depth.iter().zip(&cpu.normal) {
            assert_eq!(
                d.is_finite(),
                n.length() > 0.0,
                "{name}: a miss has no normal"
            );
            if d.is_finite() {
                assert!((n.length() - 1.0).abs() < 1e-5, "{name}: unit normals");
            }
        }
    }
}

#[test]
fn the_occlusion_aov_is_the_materials_occlusion_texture() {
    let dir = common::scratch::Scratch::new();
    // Red falls from 255 on the left to 0 on the right; green and blue must not matter.
    dir.png("ao.png", 16, 4, |x, _| [(255 - 17 * x) as u8, 40, 200]);
    let text = r#"
[camera]
position = [0.0, 3.0, 0.01]
look_at = [0.0, 0.0, 0.0]
fov = 40.0
width = 24
height = 16

[materials.ao]
type = "principled"
occlusion_texture = "ao.png"
occlusion_strength = 0.5

[materials.plain]
type = "diffuse"

[[objects]]
shape = "quad"
material = "ao"

[[objects]]
shape = "box"
material = "plain"
scale = 0.5
translate = [0.0, 0.25, 0.0]
"#;
    let s = RenderScene::from_file(&dir.write("ao.toml", text)).unwrap();
    let cpu = with_aovs(&s, &Device::cpu(), None).aovs.unwrap();
    let gpu = with_aovs(&s, gpu_device(), None).aovs.unwrap();
    assert_eq!(bits(&cpu), bits(&gpu), "CPU and GPU AOVs differ");
    // On the quad: 1 + 0.5 (red − 1), so in [0.5, 1], varying across it; on the box (no
    // texture) exactly 1; a miss 0.
    let (mut lo, mut hi, mut ones, mut misses) = (f32::MAX, f32::MIN, 0, 0);
    for (d, &o) in cpu.depth.iter().zip(&cpu.occlusion) {
        if !d.is_finite() {
            assert_eq!(o, 0.0);
            misses += 1;
        } else if o == 1.0 {
            ones += 1;
        } else {
            (lo, hi) = (lo.min(o), hi.max(o));
        }
    }
    println!("occlusion on the quad in [{lo}, {hi}], {ones} pixels of 1, {misses} misses");
    assert!(lo >= 0.5 && hi <= 1.0 && hi - lo > 0.3, "[{lo}, {hi}]");
    assert!(ones > 4 && misses > 4, "{ones} ones, {misses} misses");
}

#[test]
fn depth_is_the_primary_rays_closest_hit_t() {
    let s = scene("glass-mirror");
    let aovs = with_aovs(&s, &Device::cpu(), None).aovs.unwrap();
    let bvh = build(
        AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        &s.mesh,
        &Default::default(),
    )
    .unwrap();
    let (w, h) = (s.camera.width, s.camera.height);
    let frame = s.camera.frame();
    for y in 0..h {
        for x in 0..w {
            let pixel = y * w + x;
            let mut rng = Rng::new(s.settings.seed, pixel, 0);
            let (jx, jy) = (rng.next_f32(), rng.next_f32());
            let ray = frame.ray(x, y, jx, jy);
            let hit = bvh.intersect(
                &ray,
                Query::Closest,
                &Robustness::default(),
                &mut RayStats::default(),
            );
            let want = if hit.is_hit() { hit.t } else { f32::INFINITY };
            let got = aovs.depth[pixel as usize];
            assert_eq!(got.to_bits(), want.to_bits(), "pixel ({x}, {y})");
        }
    }
}

#[test]
fn tiles_carry_their_aovs_into_the_merge() {
    let s = scene("textured");
    let device = Device::cpu();
    let full = with_aovs(&s, &device, None);
    let mut want = full.image.to_exr();
    want.channels.extend(full.aovs.unwrap().channels(ALL));
    want.channels.sort_by(|a, b| a.0.cmp(&b.0));
    let halves = [
        Crop {
            x0: 0,
            y0: 0,
            x1: 48,
            y1: 20,
        },
        Crop {
            x0: 0,
            y0: 20,
            x1: 48,
            y1: 36,
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let tiles: Vec<_> = halves
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let r = with_aovs(&s, &device, Some(*c));
            let mut exr = r.image.to_exr();
            exr.channels.extend(r.aovs.unwrap().channels(ALL));
            let p = dir.path().join(format!("t{k}.exr"));
            exr.write(&p).unwrap();
            (p.clone(), lancer::render::ExrImage::read(&p).unwrap())
        })
        .collect();
    let merged = merge_tiles(&tiles).unwrap();
    assert_eq!(merged.channels.len(), 11);
    for ((n, a), (m, b)) in merged.channels.iter().zip(&want.channels) {
        assert_eq!(n, m);
        let (a, b): (Vec<u32>, Vec<u32>) = (
            a.iter().map(|x| x.to_bits()).collect(),
            b.iter().map(|x| x.to_bits()).collect(),
        );
        assert_eq!(a, b, "channel {n}");
    }
}

#[test]
fn png_16_bit_holds_the_8_bit_image_and_more() {
    let s = scene("cornell");
    let img = render(&s, &Device::cpu(), &RenderOptions::default())
        .unwrap()
        .image;
    let dir = tempfile::tempdir().unwrap();
    let (p8, p16) = (dir.path().join("a.png"), dir.path().join("b.png"));
    img.save(&p8).unwrap();
    img.save_png16(&p16).unwrap();
    let a = image::open(&p8).unwrap();
    let b = image::open(&p16).unwrap();
    assert!(
        matches!(b, image::DynamicImage::ImageRgb16(_)),
        "{:?}",
        b.color()
    );
    let (a, b) = (a.to_rgb8(), b.to_rgb16());
    let mut finer = 0;
    for (c8, c16) in a.pixels().zip(b.pixels()) {
        for k in 0..3 {
            let (v8, v16) = (c8[k] as i32, c16[k] as i32);
            // Both round the same sRGB value: to 1/255 and to 1/65535 (257 × 1/255).
            assert!((v16 - 257 * v8).abs() <= 129, "{v8} vs {v16}");
            finer += (v16 % 257 != 0) as usize;
        }
    }
    assert!(finer > 100, "16 bits add no precision ({finer} values)");
}
