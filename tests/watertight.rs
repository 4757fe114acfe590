//! Watertightness, the hard way: closed icospheres of 81,920 triangles (and a 12-triangle
//! cube) hit by rays aimed exactly at vertices (fans of 5 and 6) and at points of shared
//! edges, from outside and from inside, at scales 1e-4 … 1e4 and moved out to 1e5 and 1e6,
//! on the CPU and the GPU. Every ray must hit. Möller–Trumbore, the fast setting, leaks on
//! the same rays (asserted, so the test can fail).

mod common;

use common::gpu_device;
use glam::Vec3;
use lancer::accuracy::closed::{aimed_rays, cube, icosphere, leaks, placed};
use lancer::geometry::{Robustness, TriangleTest};
use lancer::mesh::Mesh;
use lancer::render::Rng;
use lancer::{Device, Query, Ray, Tracer, TracerOptions};

/// Misses among `rays` on `device` with the given triangle test.
fn misses(mesh: &Mesh, rays: &[Ray], test: TriangleTest, device: &Device) -> usize {
    let options = TracerOptions {
        robustness: Robustness {
            triangle_test: test,
            ..Robustness::default()
        },
        ..TracerOptions::default()
    };
    let mut tracer = Tracer::new(device, mesh, &options).unwrap();
    leaks(&tracer.trace(rays, Query::Closest).unwrap().hits)
}

#[test]
fn closed_meshes_leak_no_ray_at_any_scale_on_cpu_and_gpu() {
    let mut rng = Rng::new(2024, 0, 0);
    let mut mt_leaks = 0;
    let shapes = [("icosphere 81,920", icosphere(6)), ("cube", cube())];
    for (name, shape) in &shapes {
        for (scale, shift) in [
            (1.0f32, 0.0f32),
            (1e-4, 0.0),
            (1e4, 0.0),
            (100.0, 1e5),
            (1000.0, 1e6),
        ] {
            let (mesh, v) = placed(shape, scale, Vec3::splat(shift));
            let f = &shape.1;
            let n = if f.len() > 1000 { 1_000_000 } else { 100_000 };
            let rays = aimed_rays(&v, f, Vec3::splat(shift), scale, n, &mut rng);
            for device in [&Device::cpu(), gpu_device()] {
                let leaks = misses(&mesh, &rays, TriangleTest::Watertight, device);
                let mt = misses(&mesh, &rays, TriangleTest::MollerTrumbore, device);
                println!("{name} ×{scale:e} +{shift:e} on {device}: {n} rays, watertight {leaks} leaks, Möller–Trumbore {mt}");
                assert_eq!(
                    leaks, 0,
                    "{name} ×{scale:e} +{shift:e} on {device}: {leaks} rays leak"
                );
                mt_leaks += mt;
            }
        }
    }
    assert!(
        mt_leaks > 0,
        "Möller–Trumbore leaked nowhere: these rays do not test watertightness"
    );
}
