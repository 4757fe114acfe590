//! Watertightness, the hard way: closed icospheres of 81,920 triangles, a 12-triangle cube
//! and the Stanford bunny with its holes closed (69,451 triangles and the fans) hit by rays
//! aimed exactly at vertices (fans of 5 and 6) and at points of shared edges, from outside
//! and from inside, at scales 1e-4 … 1e4 and moved out to 1e5 and 1e6, on the CPU and the
//! GPU. No ray may leak, grazing ones included: a hit whose t error bound reaches back past
//! the origin is not dropped as a possible self-hit when it is proven in front of it
//! (`geometry::grazing_in_front`; such hits are counted, judged by the f64 oracle, and
//! under pbrt-v4's rule alone would leak). Möller–Trumbore, the fast setting, leaks on the
//! same rays (asserted, so the test can fail).

mod common;

use common::{gpu_device, load_model};
use glam::Vec3;
use lancer::accuracy::close_holes::{close_holes, open_edges};
use lancer::accuracy::closed::{aimed_rays, cube, icosphere, leaks, placed, Indexed};
use lancer::geometry::{intersect_watertight_bounded, Robustness, TriangleTest, WatertightRay};
use lancer::mesh::Mesh;
use lancer::render::Rng;
use lancer::trace::oracle::{self, Verdict};
use lancer::{Device, Hit, Query, Ray, Tracer, TracerOptions};

/// Misses among `rays` traced on `device` with the given triangle test (the first few
/// described for the test log), and the hits whose t error bound reaches back past the
/// origin: grazing hits that pbrt-v4's near-hit rule (t > δt) alone would drop as a possible
/// self-hit, kept because they are proven in front of it.
fn misses(mesh: &Mesh, rays: &[Ray], test: TriangleTest, device: &Device) -> (usize, usize) {
    let options = TracerOptions {
        robustness: Robustness {
            triangle_test: test,
            ..Robustness::default()
        },
        ..TracerOptions::default()
    };
    let mut tracer = Tracer::new(device, mesh, &options).unwrap();
    let hits = tracer.trace(rays, Query::Closest).unwrap().hits;
    if test == TriangleTest::Watertight {
        for (r, _) in (rays.iter().zip(&hits))
            .filter(|(_, h)| !h.is_hit())
            .take(3)
        {
            println!("  leak: {r:?}, oracle {:?}", oracle::closest(mesh, r));
        }
    }
    let grazing: Vec<(&Ray, &Hit)> = (rays.iter().zip(&hits))
        .filter(|(r, h)| {
            h.is_hit() && {
                let tri = &mesh.triangles[h.prim as usize];
                let wr = WatertightRay::new(r.dir);
                intersect_watertight_bounded(tri, r.origin, &wr, r.tmin, r.tmax)
                    .is_some_and(|t| t.in_front)
            }
        })
        .collect();
    for (r, h) in &grazing {
        let verdict = oracle::judge(mesh, r, h);
        assert!(
            !matches!(verdict, Verdict::Wrong(_)),
            "a grazing hit kept past its error bound is wrong: {r:?} {h:?}: {verdict:?}"
        );
    }
    (leaks(&hits), grazing.len())
}

/// The bunny with its holes closed, moved so that its box centre (inside it) is the origin
/// and scaled to a radius of 1, like the other shapes. None without ../shared.
fn closed_bunny() -> Option<Indexed> {
    let mesh = load_model("stanford-bunny.obj")?;
    let ((v, f), holes) = close_holes(&mesh);
    let open = open_edges(&(v.clone(), f.clone()));
    println!(
        "bunny: {holes} holes closed, {} triangles, {open} open edges",
        f.len()
    );
    assert!(holes > 0, "the bunny has holes in its base");
    assert_eq!(open, 0, "the bunny is not closed");
    let b = mesh.bounds();
    let (c, r) = (b.center(), 0.5 * b.extent().length());
    let v: Vec<Vec3> = v.iter().map(|p| (*p - c) / r).collect();
    // The aimed rays' inside origins lie near the centre: it must be inside (odd crossings).
    let closed = placed(&(v.clone(), f.clone()), 1.0, Vec3::ZERO).0;
    for d in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
        let crossings = oracle::all_hits(&closed, &Ray::new(Vec3::ZERO, d, 0.0, f32::MAX));
        assert!(
            crossings.len() % 2 == 1,
            "the bunny's centre is not inside it"
        );
    }
    Some((v, f))
}

#[test]
fn closed_meshes_leak_no_ray_at_any_scale_on_cpu_and_gpu() {
    let mut rng = Rng::new(2024, 0, 0);
    let mut mt_leaks = 0;
    let mut grazing_kept = 0;
    let mut shapes = vec![("icosphere 81,920", icosphere(6)), ("cube", cube())];
    shapes.extend(closed_bunny().map(|b| ("bunny (closed)", b)));
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
                let (leaks, grazing) = misses(&mesh, &rays, TriangleTest::Watertight, device);
                let (mt, _) = misses(&mesh, &rays, TriangleTest::MollerTrumbore, device);
                println!("{name} ×{scale:e} +{shift:e} on {device}: {n} rays, watertight {leaks} leaks ({grazing} grazing hits past their error bound kept), Möller–Trumbore {mt}");
                assert_eq!(
                    leaks, 0,
                    "{name} ×{scale:e} +{shift:e} on {device}: {leaks} rays leak"
                );
                grazing_kept += grazing;
                mt_leaks += mt;
            }
        }
    }
    println!("grazing hits kept past their error bound, in all: {grazing_kept}");
    // These rays reach the case: under pbrt-v4's rule alone each of these would be a leak.
    assert!(
        grazing_kept > 0,
        "no grazing hit past its error bound: the rays do not test the near-hit rule"
    );
    assert!(
        mt_leaks > 0,
        "Möller–Trumbore leaked nowhere: these rays do not test watertightness"
    );
}
