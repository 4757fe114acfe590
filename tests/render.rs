//! The renderer: GPU (lavapipe in CI) against the CPU reference on every scene in scenes/,
//! effect specialisation (a specialised kernel renders what the all-effects kernel does;
//! switching an effect the scene uses off changes the image), the subgroup traversal mode
//! (the per-ray kernel's image, bit for bit, or a fallback to per ray), and scene-file errors.

mod common;

use std::path::PathBuf;

use common::gpu_device;
use glam::Vec3;
use lancer::accel::bvh::layouts::LayoutKind;
use lancer::accel::AccelKind;
use lancer::gpu::BvhMemory;
use lancer::render::{render, to_rgb8, EffectSet, RenderOptions, RenderScene};
use lancer::render::{Crop, Rendered};
use lancer::{Device, TraversalMode};

fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// Every scene file, small: 64×48 (keeps CI fast).
fn scenes() -> Vec<(String, RenderScene)> {
    let mut out = Vec::new();
    let mut paths: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    for p in paths {
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        let needs_shared = std::fs::read_to_string(&p)
            .unwrap()
            .contains("shared/models");
        if needs_shared && !scenes_dir().join("../../shared/models").exists() {
            assert!(std::env::var("CI").is_err(), "{name} needs ../shared in CI");
            eprintln!("skipping {name}: ../shared/models not present (outside CI)");
            continue;
        }
        let mut s = RenderScene::from_file(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
        s.camera.width = 64;
        s.camera.height = 48;
        out.push((name, s));
    }
    assert!(
        out.len() >= 5,
        "expected the shipped scenes, found {}",
        out.len()
    );
    out
}

/// The mean of samples 0..spp, simulating `fx`, with the BVH in `memory` on a GPU.
fn image_on(
    device: &Device,
    s: &RenderScene,
    fx: EffectSet,
    spp: u32,
    memory: BvhMemory,
) -> Vec<Vec3> {
    let options = RenderOptions {
        spp: Some(spp),
        effects: Some(fx),
        memory,
        ..RenderOptions::default()
    };
    render(s, device, &options).unwrap().image.pixels
}

fn cpu_image(s: &RenderScene, fx: EffectSet, spp: u32) -> Vec<Vec3> {
    image_on(&Device::cpu(), s, fx, spp, BvhMemory::default())
}

fn gpu_image(s: &RenderScene, fx: EffectSet, spp: u32) -> Vec<Vec3> {
    gpu_image_in(s, fx, spp, BvhMemory::default())
}

fn gpu_image_in(s: &RenderScene, fx: EffectSet, spp: u32, memory: BvhMemory) -> Vec<Vec3> {
    image_on(gpu_device(), s, fx, spp, memory)
}

/// Per-pixel difference in display terms: the largest channel difference after clipping
/// to [0, 1] (what a PNG shows).
fn diffs(a: &[Vec3], b: &[Vec3]) -> Vec<f32> {
    let clip = |c: Vec3| c.clamp(Vec3::ZERO, Vec3::ONE);
    a.iter()
        .zip(b)
        .map(|(x, y)| (clip(*x) - clip(*y)).abs().max_element())
        .collect()
}

fn write_failure(name: &str, s: &RenderScene, got: &[Vec3], want: &[Vec3]) {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("render-failures");
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (s.camera.width, s.camera.height);
    let d: Vec<Vec3> = diffs(got, want)
        .iter()
        .map(|&x| Vec3::splat(x * 4.0))
        .collect();
    for (tag, px) in [("actual", got), ("expected", want), ("difference", &d[..])] {
        to_rgb8(px, w, h)
            .save(dir.join(format!("{name}-{tag}.png")))
            .unwrap();
    }
    eprintln!(
        "wrote {}/{name}-{{actual,expected,difference}}.png",
        dir.display()
    );
}

/// GPU ≡ CPU tolerance. Both run the same operations on the same random numbers, so most
/// pixels agree exactly; a path may still branch differently where the two differ by an
/// ulp (a GPU may fuse a multiply-add), so a small share of pixels may differ by more.
const PIXEL_TOL: f32 = 2.0 / 255.0;
const MAX_OUTLIER_SHARE: f64 = 0.02;
const MAX_MEAN: f64 = 0.004;

/// Asserts that the GPU image of `s` is the CPU's within the tolerance, printing the
/// differences (and writing PNGs of both on failure).
fn assert_gpu_matches_cpu(name: &str, s: &RenderScene, gpu: &[Vec3], cpu: &[Vec3]) {
    let fx = EffectSet::of(s);
    let d = diffs(gpu, cpu);
    let max = d.iter().cloned().fold(0.0, f32::max);
    let mean = d.iter().map(|&x| x as f64).sum::<f64>() / d.len() as f64;
    let outliers = d.iter().filter(|&&x| x > PIXEL_TOL).count();
    println!(
        "{name}: effects [{fx}]  max diff {max:.4}  mean {mean:.6}  pixels over {PIXEL_TOL:.4}: {outliers}/{}",
        d.len()
    );
    let ok = (outliers as f64) <= MAX_OUTLIER_SHARE * d.len() as f64 && mean <= MAX_MEAN;
    if !ok {
        write_failure(name, s, gpu, cpu);
    }
    assert!(ok, "{name}: GPU and CPU images differ beyond the tolerance");
    // Not a black or constant image: the comparison means something.
    let lum: Vec<f32> = cpu.iter().map(|c| c.x + c.y + c.z).collect();
    let spread =
        lum.iter().cloned().fold(0.0, f32::max) - lum.iter().cloned().fold(f32::MAX, f32::min);
    assert!(spread > 0.1, "{name}: the reference image is flat");
}

#[test]
fn gpu_renders_match_the_cpu_reference() {
    for (name, s) in scenes() {
        let fx = EffectSet::of(&s);
        let cpu = cpu_image(&s, fx, 2);
        let gpu = gpu_image(&s, fx, 2);
        assert_gpu_matches_cpu(&name, &s, &gpu, &cpu);
    }
}

#[test]
fn a_render_of_several_dispatches_matches_the_cpu() {
    // 300×220 = 66,000 pixels: two dispatches of the render kernel (at most 65,536 pixels
    // each), the second reading its parameters at a dynamic offset.
    let (name, mut s) = scenes().into_iter().find(|(n, _)| n == "cornell").unwrap();
    (s.camera.width, s.camera.height) = (300, 220);
    let fx = EffectSet::of(&s);
    assert_gpu_matches_cpu(&name, &s, &gpu_image(&s, fx, 1), &cpu_image(&s, fx, 1));
}

#[test]
fn both_bvh_memories_render_the_same_image() {
    // The same words read through buffers or textures: the same numbers, bit for bit.
    for (name, s) in scenes() {
        let fx = EffectSet::of(&s);
        assert_eq!(
            gpu_image_in(&s, fx, 1, BvhMemory::Buffers),
            gpu_image_in(&s, fx, 1, BvhMemory::Textures),
            "{name}: BVH in buffers vs textures"
        );
        println!("{name}: buffers ≡ textures");
    }
}

/// Shading triangles (80 bytes each) beyond one storage binding render in both memories: on
/// a device whose recorded binding limit is shrunk below the teapot's, textures hold them and
/// buffers are bound in parts (so are the BVH's triangles); both render the CPU's image, bit
/// for bit the same. A buffer beyond `max_buffer_size` is refused, naming the limit.
#[test]
fn shading_triangles_beyond_a_storage_binding_render_in_both_memories() {
    gpu_device(); // fails with the install hint when there is no adapter
    let Some(path) = common::model("teapot.obj") else {
        return;
    };
    let s = RenderScene::from_mesh(&path, 32, 24).unwrap();
    let shade_bytes = s.mesh.len() as u64 * 80;
    let small = |buffer: u64| {
        let mut ctx = lancer::gpu::GpuContext::new().unwrap();
        ctx.limits.max_storage_buffer_binding_size = shade_bytes / 2;
        ctx.limits.max_buffer_size = buffer;
        Device::gpu(ctx)
    };
    let device = small(u64::MAX);
    let fx = EffectSet::of(&s);
    let options = |memory| RenderOptions {
        spp: Some(1),
        effects: Some(fx),
        memory,
        ..RenderOptions::default()
    };
    let image = |memory| render(&s, &device, &options(memory)).unwrap().image.pixels;
    let textures = image(BvhMemory::Textures);
    assert_gpu_matches_cpu(
        "teapot, small bindings",
        &s,
        &textures,
        &cpu_image(&s, fx, 1),
    );
    assert_same(
        &image(BvhMemory::Buffers),
        &textures,
        "buffer parts ≠ textures",
    );
    let Err(e) = render(&s, &small(shade_bytes / 2), &options(BvhMemory::Buffers)) else {
        panic!("a buffer beyond max_buffer_size was made");
    };
    let e = e.to_string();
    assert!(e.contains("max_buffer_size"), "{e}");
}

/// Where the device's memory is the host's (lavapipe), a render reads the layout's arrays
/// and the shading triangles in place: the bunny (69,451 triangles) renders what a device
/// that copies them renders, bit for bit, in both memories; on lavapipe arrays are imported,
/// a texture's only where its allocation has room (arrays of at least `ROOM_MIN_BYTES`).
#[test]
fn renders_reading_arrays_in_place_are_the_copied_renders() {
    use std::sync::Arc;
    gpu_device(); // fails with the install hint when there is no adapter
    let Some(path) = common::model("stanford-bunny.obj") else {
        return;
    };
    let s = RenderScene::from_mesh(&path, 32, 24).unwrap();
    let ctx = lancer::gpu::GpuContext::new().unwrap();
    let mut copying = ctx.clone();
    copying.import_host_memory = false;
    let bvh = lancer::accel::bvh::build(&s.mesh, &Default::default());
    let layout: Arc<dyn lancer::accel::GpuForm> =
        lancer::accel::bvh::layouts::flatten(LayoutKind::Cwbvh, &bvh, &s.mesh).into();
    let a = layout.arrays();
    // Arrays of at least ROOM_MIN_BYTES have room; the shading triangles (5.6 MB) do.
    let roomy = [
        a.room()[0] > a.nodes.len(),
        a.room()[1] > a.tris.len(),
        true,
    ];
    assert!(roomy[1], "the bunny's triangles have room");
    let mut imported = 0;
    for (c, import) in [(&ctx, ctx.import_host_memory), (&copying, false)] {
        for memory in [BvhMemory::Textures, BvhMemory::Buffers] {
            let full = Crop::full(32, 24);
            let mode = TraversalMode::PerRay;
            let r =
                lancer::render::GpuRenderer::new_shared(c, &s, &layout, memory, full, false, mode)
                    .unwrap();
            let in_place = r.in_place();
            // Imported only where asked, a texture only where its array has room (and starts
            // on the driver's alignment, which depends on the allocator).
            for k in 0..3 {
                assert!(
                    import || !in_place[k],
                    "{memory:?}: imported when told not to"
                );
                let textures = memory == BvhMemory::Textures;
                assert!(
                    roomy[k] || !in_place[k] || !textures,
                    "{memory:?}: past the room"
                );
                imported += in_place[k] as usize;
            }
        }
    }
    // Mesa 22's lavapipe (CI's) asks 16-byte image alignment, which every allocation meets;
    // later ones ask more, met here by chance (see tests/gpu_vs_cpu.rs).
    if ctx.adapter.name.contains("llvmpipe") && ctx.adapter.driver.contains("Mesa 22.") {
        assert!(imported > 0, "lavapipe read nothing in place");
    }
    let (imports, copies) = (Device::gpu(ctx), Device::gpu(copying));
    let fx = EffectSet::of(&s);
    for memory in [BvhMemory::Textures, BvhMemory::Buffers] {
        let options = RenderOptions {
            spp: Some(2),
            effects: Some(fx),
            memory,
            ..RenderOptions::default()
        };
        let image = |d: &Device| render(&s, d, &options).unwrap().image.pixels;
        assert_same(&image(&imports), &image(&copies), &format!("{memory:?}"));
    }
}

/// Texels (textures and the environment map, always in a storage buffer) beyond one storage
/// binding are bound in parts: `principled.toml` (a 64² checker under a 128 × 64 sky) on a
/// device whose recorded binding limit is shrunk to 16 KiB renders what an unshrunk device
/// renders, bit for bit (the checked module reads a word of a wrong part as zero). And
/// `copies.toml`'s two levels, in buffer memory at 4 KiB, render what textures render.
#[test]
fn textures_environment_and_two_levels_beyond_a_storage_binding_render() {
    gpu_device(); // fails with the install hint when there is no adapter
    let shrunk = |binding: u64| {
        let mut ctx = lancer::gpu::GpuContext::new().unwrap();
        ctx.limits.max_storage_buffer_binding_size = binding;
        Device::gpu(ctx)
    };
    // Small images: the other arrays bound in one part each stay under the storage
    // buffers a stage.
    let scene = |name: &str, (w, h)| {
        let path = scenes_dir().join(format!("{name}.toml"));
        let mut s = RenderScene::from_file(&path).unwrap();
        (s.camera.width, s.camera.height) = (w, h);
        s
    };
    let s = scene("principled", (32, 24));
    let texel_bytes: usize = s.textures.iter().map(|t| t.texels.len() * 16).sum();
    assert!(
        texel_bytes > 2 * 16384,
        "{texel_bytes} bytes of texture texels"
    );
    let fx = EffectSet::of(&s);
    let whole = gpu_image(&s, fx, 1);
    let parts = image_on(&shrunk(16384), &s, fx, 1, BvhMemory::Textures);
    assert_same(&parts, &whole, "principled: texels in parts");
    assert_gpu_matches_cpu(
        "principled, texels in parts",
        &s,
        &parts,
        &cpu_image(&s, fx, 1),
    );

    let s = scene("copies", (16, 12));
    assert!(
        s.placements.is_some(),
        "copies.toml is placed in two levels"
    );
    let fx = EffectSet::of(&s);
    let textures = gpu_image_in(&s, fx, 1, BvhMemory::Textures);
    let buffers = image_on(&shrunk(4096), &s, fx, 1, BvhMemory::Buffers);
    assert_same(&buffers, &textures, "copies: two levels in buffer parts");
}

/// An accumulator (the sums, and with AOVs two more entries a pixel) beyond one storage
/// binding is bound in parts: `cornell.toml` at 32 × 24 with AOVs (36 KiB) on a device whose
/// recorded binding limit is shrunk to 4 KiB renders the image and AOVs an unshrunk device
/// renders, bit for bit.
#[test]
fn an_accumulator_beyond_a_storage_binding_renders() {
    gpu_device(); // fails with the install hint when there is no adapter
    let mut s = RenderScene::from_file(&scenes_dir().join("cornell.toml")).unwrap();
    (s.camera.width, s.camera.height) = (32, 24);
    let mut ctx = lancer::gpu::GpuContext::new().unwrap();
    ctx.limits.max_storage_buffer_binding_size = 4096;
    let options = RenderOptions {
        spp: Some(2),
        aovs: true,
        ..RenderOptions::default()
    };
    let whole = render(&s, gpu_device(), &options).unwrap();
    let parts = render(&s, &Device::gpu(ctx), &options).unwrap();
    assert_same(
        &parts.image.pixels,
        &whole.image.pixels,
        "cornell: accumulator in parts",
    );
    let (a, b) = (parts.aovs.unwrap(), whole.aovs.unwrap());
    assert!(a.depth.iter().any(|d| d.is_finite()), "no AOV hit");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.depth), bits(&b.depth), "depth AOV in parts");
    assert_same(&a.normal, &b.normal, "normal AOV in parts");
    assert_same(&a.albedo, &b.albedo, "albedo AOV in parts");
}

/// Two images equal bit for bit; the failure counts the pixels that differ.
fn assert_same(a: &[Vec3], b: &[Vec3], what: &str) {
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(
        a.len() == b.len() && differ == 0,
        "{what}: {differ} of {} pixels differ",
        a.len()
    );
}

/// A GPU render of `s` (one sample) traversing in `mode` through `layout`, cropped where
/// `crop` says.
fn gpu_render_in_mode(
    s: &RenderScene,
    layout: LayoutKind,
    mode: TraversalMode,
    crop: Option<Crop>,
) -> Rendered {
    let options = RenderOptions {
        spp: Some(1),
        accel: Some(AccelKind::Bvh(layout)),
        crop,
        mode,
        ..RenderOptions::default()
    };
    render(s, gpu_device(), &options).unwrap()
}

#[test]
fn subgroup_renders_are_the_per_ray_renders_bit_for_bit() {
    // Each lane does the per-ray kernel's operations in its order, only the rays of a
    // subgroup are traced together: the same image, bit for bit, on every scene (path,
    // AO, mirrors, glass, textures, soft shadows). lavapipe has subgroups, so the mode must
    // run, not fall back.
    // Every layout with a subgroup traversal (the render kernel's lanes mix closest-hit
    // path rays with any-hit shadow rays).
    for layout in [LayoutKind::DfsSign, LayoutKind::Cwbvh, LayoutKind::Threaded] {
        for (name, s) in scenes() {
            let name = format!("{name} {layout}");
            let per_ray = gpu_render_in_mode(&s, layout, TraversalMode::PerRay, None);
            let together = gpu_render_in_mode(&s, layout, TraversalMode::Subgroup, None);
            assert_eq!(per_ray.mode, TraversalMode::PerRay, "{name}");
            // Two levels (a scene with copies) have no subgroup traversal: per ray.
            let want = match s.placements {
                Some(_) => TraversalMode::PerRay,
                None => TraversalMode::Subgroup,
            };
            assert_eq!(together.mode, want, "{name}");
            assert_eq!(together.cpu_pixels, 0, "{name}: pixels retraced on the CPU");
            let differ = (per_ray.image.pixels.iter())
                .zip(&together.image.pixels)
                .filter(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits))
                .count();
            println!("{name}: subgroup ≡ per-ray ({differ} pixels differ)");
            assert_eq!(differ, 0, "{name}: subgroup and per-ray images differ");
        }
    }
    // A crop of 23×17 pixels: its last subgroup has lanes with no pixel, which go along
    // with no ray.
    let (name, s) = scenes().into_iter().find(|(n, _)| n == "cornell").unwrap();
    let crop = Some(Crop {
        x0: 5,
        y0: 7,
        x1: 28,
        y1: 24,
    });
    let per_ray = gpu_render_in_mode(&s, LayoutKind::DfsSign, TraversalMode::PerRay, crop);
    let together = gpu_render_in_mode(&s, LayoutKind::DfsSign, TraversalMode::Subgroup, crop);
    assert_eq!(together.mode, TraversalMode::Subgroup);
    assert_eq!(per_ray.image.pixels.len(), 23 * 17, "{name}");
    assert_eq!(
        together.image.pixels, per_ray.image.pixels,
        "{name} cropped"
    );
}

#[test]
fn a_layout_without_subgroup_traversal_renders_per_ray() {
    // bvh4 has no subgroup traversal: asked for one, the renderer says it runs per ray and
    // renders that layout's per-ray image.
    let (name, s) = scenes().into_iter().find(|(n, _)| n == "cornell").unwrap();
    let asked = gpu_render_in_mode(&s, LayoutKind::Bvh4, TraversalMode::Subgroup, None);
    let per_ray = gpu_render_in_mode(&s, LayoutKind::Bvh4, TraversalMode::PerRay, None);
    assert_eq!(asked.mode, TraversalMode::PerRay, "{name}");
    assert_eq!(asked.image.pixels, per_ray.image.pixels, "{name}");
}

#[test]
fn specialised_kernels_render_what_the_all_effects_kernel_renders() {
    for (name, s) in scenes() {
        let fx = EffectSet::of(&s);
        // CPU: the same flags must give the same numbers, bit for bit.
        assert_eq!(
            cpu_image(&s, fx, 1),
            cpu_image(&s, EffectSet::ALL, 1),
            "{name}: CPU, specialised vs all effects"
        );
        let a = gpu_image(&s, fx, 1);
        let b = gpu_image(&s, EffectSet::ALL, 1);
        let d = diffs(&a, &b);
        let outliers = d.iter().filter(|&&x| x > PIXEL_TOL).count();
        println!("{name}: specialised [{fx}] vs all effects: {outliers} pixels over tolerance");
        assert!(
            (outliers as f64) <= MAX_OUTLIER_SHARE * d.len() as f64,
            "{name}: GPU, specialised vs all effects"
        );
    }
}

/// Turning off an effect the scene calls for changes the image, on both devices.
#[test]
fn each_effect_changes_the_scene_that_calls_for_it() {
    let all = scenes();
    let find = |n: &str| all.iter().find(|x| x.0 == n).unwrap();
    type Off = fn(&mut EffectSet);
    let cases: [(&str, &str, Off); 9] = [
        ("mirror", "glass-mirror", |f| f.mirror = false),
        ("refraction", "glass-mirror", |f| f.refraction = false),
        ("soft shadows", "glass-mirror", |f| f.soft_shadows = false),
        ("shadows", "glass-mirror", |f| f.shadows = false),
        ("textures", "textured", |f| f.textures = false),
        ("indirect", "cornell", |f| f.indirect = false),
        ("ao", "ao", |f| f.ao = false),
        ("environment", "sky", |f| f.environment = false),
        ("alpha mask", "cutout", |f| f.alpha_mask = false),
    ];
    for (effect, scene, off) in cases {
        let (_, s) = find(scene);
        let on = EffectSet::of(s);
        let mut without = on;
        off(&mut without);
        assert_ne!(on, without, "{scene} does not call for {effect}");
        for (dev, a, b) in [
            ("cpu", cpu_image(s, on, 2), cpu_image(s, without, 2)),
            ("gpu", gpu_image(s, on, 2), gpu_image(s, without, 2)),
        ] {
            let changed = diffs(&a, &b).iter().filter(|&&x| x > 0.05).count();
            println!("{scene} without {effect} ({dev}): {changed} pixels change by > 0.05");
            assert!(
                changed >= 20,
                "{scene}: {effect} off changes nothing on {dev}"
            );
        }
    }
}

#[test]
fn scene_file_errors_name_file_and_line() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let check = |name: &str, text: &str, want: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let e = RenderScene::from_file(&p).unwrap_err().to_string();
        assert!(e.contains(want), "{name}: '{e}' lacks '{want}'");
        assert!(e.starts_with(&p.display().to_string()), "{e}");
    };
    let cam = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n";
    check("unknown.toml", &format!("{cam}colour = 3\n"), ":4:");
    check("unknown.toml", &format!("{cam}colour = 3\n"), "colour");
    check(
        "badvalue.toml",
        &format!("{cam}\n[render]\nspp = \"many\"\n"),
        ":6:",
    );
    check(
        "nomat.toml",
        &format!("{cam}\n[[objects]]\nshape = \"box\"\nmaterial = \"gold\"\n"),
        "no material named \"gold\"",
    );
    check(
        "badior.toml",
        &format!(
            "{cam}\n[materials.g]\ntype = \"glass\"\nior = 0.5\n\n[[objects]]\nshape = \"box\"\n"
        ),
        ":5:",
    );
    check("noobj.toml", cam, "nothing to render");
}
