//! Rendering through every acceleration structure: the same hits (ties to the smaller
//! triangle index) make the same image, so every structure's CPU render equals the BVH's bit
//! for bit, and the kd-tree's and the BIH's GPU renders equal the BVH's GPU render bit for
//! bit (and their CPU renders within the GPU's shading tolerance).

mod common;

use std::path::PathBuf;

use common::gpu_device;
use glam::Vec3;
use lancer::render::{render, RenderOptions, RenderScene, Rendered};
use lancer::{AccelKind, Device, Error};

/// Scenes that exercise the integrator's paths (area light and bounces; mirror, glass,
/// point and sun lights; alpha masks, tested inside each traversal), small.
fn scenes() -> Vec<(&'static str, RenderScene)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    ["cornell", "glass-mirror", "cutout"]
        .into_iter()
        .map(|name| {
            let mut s = RenderScene::from_file(&dir.join(format!("{name}.toml"))).unwrap();
            (s.camera.width, s.camera.height) = (48, 36);
            (name, s)
        })
        .collect()
}

fn render_with(scene: &RenderScene, device: &Device, accel: AccelKind) -> Rendered {
    let options = RenderOptions {
        spp: Some(2),
        accel: Some(accel),
        ..RenderOptions::default()
    };
    render(scene, device, &options).unwrap_or_else(|e| panic!("{accel}: {e}"))
}

fn bits(px: &[Vec3]) -> Vec<[u32; 3]> {
    px.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
}

/// Pixels whose bits differ, with the first few printed.
fn differing(what: &str, got: &[Vec3], want: &[Vec3], width: u32) -> usize {
    let (g, w) = (bits(got), bits(want));
    let bad: Vec<usize> = (0..g.len()).filter(|&i| g[i] != w[i]).collect();
    for &i in bad.iter().take(3) {
        let (x, y) = (i as u32 % width, i as u32 / width);
        println!("{what}: pixel ({x}, {y}): {:?} vs {:?}", got[i], want[i]);
    }
    bad.len()
}

#[test]
fn every_structure_renders_the_bvh_image_on_the_cpu() {
    for (name, s) in scenes() {
        let bvh = render_with(
            &s,
            &Device::cpu(),
            AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        );
        // Not a flat image: equality means something.
        let lum: Vec<f32> = bvh.image.pixels.iter().map(|c| c.x + c.y + c.z).collect();
        let spread =
            lum.iter().cloned().fold(0.0, f32::max) - lum.iter().cloned().fold(f32::MAX, f32::min);
        assert!(spread > 0.1, "{name}: the BVH image is flat");
        for &kind in &AccelKind::ALL[1..] {
            let got = render_with(&s, &Device::cpu(), kind);
            let what = format!("{name} {kind} (cpu)");
            let n = differing(&what, &got.image.pixels, &bvh.image.pixels, s.camera.width);
            println!("{what}: {n} pixels differ from the BVH's");
            assert_eq!(n, 0, "{what}: image differs from the BVH's");
        }
    }
}

/// On the GPU the kd-tree and the BIH render the BVH's image bit for bit (the same hits
/// shaded by the same kernel). The GPU's shading arithmetic is not the CPU's to the bit (a
/// driver may fuse a multiply-add or round a division differently: tests/render.rs bounds
/// that for the BVH); against the CPU render (every structure's, by the test above) they
/// are held to the same tolerance.
#[test]
fn kdtree_and_bih_render_the_bvh_image_on_the_gpu() {
    // Two scenes (each structure's kernel compiles for long on lavapipe): the kd-tree's
    // leaf step is its own, alpha test included.
    for (name, s) in scenes().into_iter().filter(|(n, _)| *n != "glass-mirror") {
        let gpu_bvh = render_with(
            &s,
            gpu_device(),
            AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        );
        let cpu = render_with(
            &s,
            &Device::cpu(),
            AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        );
        for kind in [AccelKind::KdTree, AccelKind::Bih] {
            let gpu = render_with(&s, gpu_device(), kind);
            let what = format!("{name} {kind} (gpu)");
            // Pixels the driver cut short are redone on the CPU and would agree trivially.
            assert_eq!(
                gpu.cpu_pixels, 0,
                "{what}: pixels rendered again on the CPU"
            );
            let n = differing(
                &what,
                &gpu.image.pixels,
                &gpu_bvh.image.pixels,
                s.camera.width,
            );
            let far = (gpu.image.pixels.iter().zip(&cpu.image.pixels))
                .filter(|(a, b)| (**a - **b).abs().max_element() > 2.0 / 255.0)
                .count();
            println!(
                "{what}: {n} pixels differ from the BVH's GPU render, {far} from the CPU \
                 render by > 2/255"
            );
            assert_eq!(n, 0, "{what}: GPU image differs from the BVH's");
            assert!(
                far as f64 <= 0.02 * cpu.image.pixels.len() as f64,
                "{what}: GPU vs CPU beyond tests/render.rs's tolerance"
            );
        }
    }
}

#[test]
fn a_structure_without_a_gpu_kernel_is_refused_on_a_gpu() {
    let (_, s) = scenes().swap_remove(0);
    for kind in [
        AccelKind::UniformGrid,
        AccelKind::TwoLevelGrid,
        AccelKind::HashedGrid,
        AccelKind::Octree,
    ] {
        let options = RenderOptions {
            accel: Some(kind),
            ..RenderOptions::default()
        };
        match render(&s, gpu_device(), &options) {
            Err(Error::Usage(m)) => assert!(m.contains(kind.name()) && m.contains("--device cpu")),
            Err(e) => panic!("{kind}: wrong error {e}"),
            Ok(_) => panic!("{kind}: rendered on a GPU without a kernel"),
        }
    }
}
