//! Tiles: a render with a crop is the full render's pixels in the crop, bit for bit, on the
//! CPU and the GPU (the random numbers are the full image's); EXR tiles record where they
//! sit, and `merge` joins them into the full render bit for bit, refusing overlaps, gaps and
//! tiles of other renders; bad crops are refused with exit code 2.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::gpu_device;
use lancer::render::{merge_tiles, render, Crop, ExrImage, Image, RenderOptions, RenderScene};
use lancer::Device;

const W: u32 = 40;
const H: u32 = 30;

fn cornell() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml")
}

fn scene() -> RenderScene {
    let mut s = RenderScene::from_file(&cornell()).unwrap();
    (s.camera.width, s.camera.height) = (W, H);
    s
}

/// Four tiles of unequal sizes covering the image (a split that is no power of two).
fn quarters() -> [Crop; 4] {
    let (xs, ys) = (17, 11);
    [
        Crop {
            x0: 0,
            y0: 0,
            x1: xs,
            y1: ys,
        },
        Crop {
            x0: xs,
            y0: 0,
            x1: W,
            y1: ys,
        },
        Crop {
            x0: 0,
            y0: ys,
            x1: xs,
            y1: H,
        },
        Crop {
            x0: xs,
            y0: ys,
            x1: W,
            y1: H,
        },
    ]
}

fn render_crop(device: &Device, crop: Option<Crop>) -> Image {
    let options = RenderOptions {
        spp: Some(2),
        crop,
        ..RenderOptions::default()
    };
    let r = render(&scene(), device, &options).unwrap();
    assert_eq!(r.cpu_pixels, 0, "pixels rendered again on the CPU");
    r.image
}

fn bits(img: &ExrImage) -> Vec<(String, Vec<u32>)> {
    (img.channels.iter())
        .map(|(n, v)| (n.clone(), v.iter().map(|x| x.to_bits()).collect()))
        .collect()
}

/// Tiles equal the full render's pixels in their bounds; written as EXR, read back and
/// merged they equal the full render, bit for bit.
fn tiles_make_the_full_render(device: &Device, what: &str) {
    let full = render_crop(device, None);
    assert_eq!(full.tile, None);
    let dir = tempfile::tempdir().unwrap();
    let mut read = Vec::new();
    for (k, c) in quarters().into_iter().enumerate() {
        let tile = render_crop(device, Some(c));
        assert_eq!((tile.width, tile.height), (c.width(), c.height()));
        let t = tile.tile.expect("a tile knows where it sits");
        assert_eq!((t.bounds, t.full_width, t.full_height), (c, W, H));
        for i in 0..c.pixels() {
            let (x, y) = c.pixel(i);
            let want = full.pixels[(y * W + x) as usize];
            assert_eq!(
                tile.pixels[i].to_array().map(f32::to_bits),
                want.to_array().map(f32::to_bits),
                "{what}: tile {k} pixel ({x}, {y})"
            );
        }
        let p = dir.path().join(format!("tile{k}.exr"));
        tile.save(&p).unwrap();
        let back = ExrImage::read(&p).unwrap();
        assert_eq!(back.tile, t, "{what}: tile {k}'s windows read back");
        read.push((p, back));
    }
    // Any order.
    read.reverse();
    let merged = merge_tiles(&read).unwrap();
    assert_eq!(bits(&merged), bits(&full.to_exr()), "{what}: merged ≠ full");
    println!("{what}: 4 tiles ≡ full render, merged ≡ full render");
}

#[test]
fn cpu_tiles_merge_into_the_full_render() {
    tiles_make_the_full_render(&Device::cpu(), "cpu");
}

#[test]
fn gpu_tiles_merge_into_the_full_render() {
    tiles_make_the_full_render(gpu_device(), "gpu");
}

fn lancer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn size_args() -> Vec<String> {
    ["--width", &W.to_string(), "--height", &H.to_string()]
        .map(String::from)
        .into()
}

/// Runs `lancer` and expects exit code 2 with one line containing `want`.
fn refused(args: &[&str], want: &str) {
    let out = lancer(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    let last = err.lines().last().unwrap_or_default();
    assert!(last.contains(want), "{args:?}: '{last}' lacks '{want}'");
}

#[test]
fn the_command_line_renders_and_merges_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell();
    let render_args = |out: &Path, crop: Option<Crop>| {
        let mut a: Vec<String> = ["render", s(&scene), "-o", s(out), "--spp", "1"]
            .map(String::from)
            .into();
        a.extend(size_args());
        a.extend(["--device", "cpu"].map(String::from));
        if let Some(c) = crop {
            a.push("--crop".into());
            a.extend([c.x0, c.y0, c.x1, c.y1].map(|x| x.to_string()));
        }
        a
    };
    let run = |args: Vec<String>| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = lancer(&args);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let full = dir.path().join("full.exr");
    run(render_args(&full, None));
    let mut tiles = Vec::new();
    for (k, c) in quarters().into_iter().enumerate() {
        let p = dir.path().join(format!("t{k}.exr"));
        run(render_args(&p, Some(c)));
        tiles.push(p);
    }
    let merged = dir.path().join("merged.exr");
    let mut args = vec!["merge"];
    args.extend(tiles.iter().map(|p| s(p)));
    args.extend(["-o", s(&merged)]);
    let out = lancer(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (want, b) = (
        ExrImage::read(&full).unwrap(),
        ExrImage::read(&merged).unwrap(),
    );
    assert_eq!(bits(&want), bits(&b), "merged ≠ full");
    assert_eq!(want.tile, b.tile);

    // Refusals: gaps, overlaps, tiles of other renders, writing over a tile, not EXR.
    let (t0, t1, t2, t3) = (s(&tiles[0]), s(&tiles[1]), s(&tiles[2]), s(&tiles[3]));
    let out = s(&merged);
    refused(
        &["merge", t0, t1, t2, "-o", out],
        "no tile covers pixel (17, 11), the tiles cover",
    );
    refused(&["merge", t0, t1, t2, t3, t0, "-o", out], "overlaps");
    refused(&["merge", t0, t1, t2, t3, "-o", t2], "is an input");
    refused(&["merge", t0, t1, t2, t3, "-o", "m.png"], ".exr");
    let other = dir.path().join("other.exr");
    let mut a = render_args(&other, Some(quarters()[3]));
    assert_eq!(a[6], "--width");
    a[7] = (W + 1).to_string();
    run(a);
    refused(
        &["merge", t0, t1, t2, s(&other), "-o", out],
        "different renders",
    );
    let mut extra = ExrImage::read(&tiles[3]).unwrap();
    let n = extra.channels[0].1.len();
    extra.channels.push(("depth.Z".into(), vec![0.0; n]));
    let extra_path = dir.path().join("extra.exr");
    extra.write(&extra_path).unwrap();
    refused(
        &["merge", t0, t1, t2, s(&extra_path), "-o", out],
        "has channels [B, G, R, depth.Z]",
    );
    // A small tile of a huge image: refused from the headers, before the 30001² image is
    // allocated (14 GB).
    let mut huge = ExrImage::read(&tiles[0]).unwrap();
    (huge.tile.full_width, huge.tile.full_height) = (30_001, 30_001);
    let huge_path = dir.path().join("huge.exr");
    huge.write(&huge_path).unwrap();
    refused(
        &["merge", s(&huge_path), "-o", out],
        "no tile covers pixel (17, 0), the tiles cover 187 of the 30001×30001 image's 900060001 pixels",
    );
    let junk = dir.path().join("junk.exr");
    std::fs::write(&junk, b"not an exr").unwrap();
    refused(
        &["merge", t0, s(&junk), "-o", out],
        "not a readable OpenEXR",
    );
    // The failed merges left the good output alone.
    assert_eq!(bits(&ExrImage::read(&merged).unwrap()), bits(&want));
}

#[test]
fn bad_crops_are_refused() {
    let path = cornell();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let base: Vec<String> = ["render", s(&path), "-o", s(&out), "--device", "cpu"]
        .map(String::from)
        .into_iter()
        .chain(size_args())
        .collect();
    let with = |crop: &[&'static str]| {
        let mut a: Vec<&str> = base.iter().map(String::as_str).collect();
        a.push("--crop");
        a.extend(crop);
        a
    };
    refused(&with(&["5", "5", "5", "9"]), "is empty");
    refused(&with(&["9", "5", "5", "9"]), "is empty");
    refused(&with(&["0", "0", "41", "30"]), "outside the 40×30 image");
    refused(&with(&["0", "0", "40", "31"]), "outside the 40×30 image");
    refused(&with(&["0", "0", "40"]), "4 values required");
    assert!(!out.exists(), "a refused crop wrote an image");
    // The library refuses them too (no panic, no image).
    let options = RenderOptions {
        crop: Some(Crop {
            x0: 0,
            y0: 0,
            x1: W + 1,
            y1: H,
        }),
        ..RenderOptions::default()
    };
    let e = render(&scene(), &Device::cpu(), &options).unwrap_err();
    assert_eq!(e.exit_code(), 2, "{e}");
}
