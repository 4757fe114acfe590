//! The hard cases of `lancer::accuracy::cases` — axis-parallel and ±0 directions, origins on
//! slab planes, flat boxes, grazing rays, rays through a box corner, boxes behind the origin,
//! rays in a triangle's plane — and degenerate input (one triangle, 10⁵ triangles with one
//! centroid, zero-area, collinear and needle triangles), on the CPU and the GPU: with the
//! robust defaults no hit is lost (0 false misses against the f64 oracle), no answer is
//! wrong, and CPU ≡ GPU bit for bit. The plain slab test, the fast setting, loses hits on a
//! constructed case (asserted, so the test can fail). The f64 precision knob traces the
//! oracle's own answers on the CPU and is refused on the GPU.

mod common;

use common::{gpu_device, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::LayoutKind;
use lancer::accel::{self, AccelKind};
use lancer::accuracy::cases::{self, HardCase};
use lancer::accuracy::{false_misses, secondary, wrong_answers};
use lancer::geometry::{Hit, Precision, Ray, RayOffset, Robustness, SlabTest, Triangle};
use lancer::mesh::{load_obj, Mesh};
use lancer::trace::oracle;
use lancer::{Device, Query, Tracer, TracerOptions};

fn trace(device: &Device, mesh: &Mesh, rays: &[Ray], robustness: Robustness) -> Vec<Hit> {
    let options = TracerOptions {
        robustness,
        ..TracerOptions::default()
    };
    let mut tracer = Tracer::new(device, mesh, &options).unwrap();
    tracer.trace(rays, Query::Closest).unwrap().hits
}

/// Rays whose hits differ between two devices (prim, or t's bits).
fn differing(a: &[Hit], b: &[Hit]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.prim != y.prim || x.t.to_bits() != y.t.to_bits())
        .count()
}

/// With the robust defaults, on CPU and GPU: no false miss, no wrong answer, a hit exactly
/// where the oracle hits when the case is exact in f32, and CPU ≡ GPU.
fn check_robust(case: &HardCase) {
    let rob = Robustness::default();
    let truths = oracle::Truths::new(&case.mesh, &case.rays);
    let oracle_hits: Vec<bool> = (0..case.rays.len())
        .map(|i| truths.closest(i).is_some())
        .collect();
    let cpu = trace(&Device::cpu(), &case.mesh, &case.rays, rob);
    let gpu = trace(gpu_device(), &case.mesh, &case.rays, rob);
    for (device, hits) in [("cpu", &cpu), ("gpu", &gpu)] {
        let lost = false_misses(&case.mesh, &case.rays, hits, &rob);
        let wrong = wrong_answers(&case.mesh, &case.rays, hits);
        let hit_count = hits.iter().filter(|h| h.is_hit()).count();
        let unlike_oracle = (hits.iter().zip(&oracle_hits))
            .filter(|(h, o)| h.is_hit() != **o)
            .count();
        println!(
            "{} on {device}: {} rays, {hit_count} hits, {lost} false misses, {wrong} wrong, \
             {unlike_oracle} hit/miss unlike the oracle{}",
            case.name,
            case.rays.len(),
            if case.exact { "" } else { " (ties allowed)" }
        );
        assert_eq!(lost, 0, "{} on {device}: {lost} false misses", case.name);
        assert_eq!(wrong, 0, "{} on {device}: {wrong} wrong answers", case.name);
        if case.exact {
            assert_eq!(unlike_oracle, 0, "{} on {device}", case.name);
        }
    }
    let diff = differing(&cpu, &gpu);
    assert_eq!(
        diff, 0,
        "{}: {diff} rays differ between CPU and GPU",
        case.name
    );
}

#[test]
fn robust_defaults_lose_no_hit_on_any_hard_case_on_cpu_and_gpu() {
    for case in cases::all(3000, 12) {
        check_robust(&case);
    }
}

#[test]
fn the_plain_slab_test_loses_hits_through_box_corners_on_cpu_and_gpu() {
    let case = cases::box_corners(4000, 5);
    let plain = Robustness {
        slab_test: SlabTest::Plain,
        ..Robustness::default()
    };
    for device in [&Device::cpu(), gpu_device()] {
        let hits = trace(device, &case.mesh, &case.rays, plain);
        let lost = false_misses(&case.mesh, &case.rays, &hits, &plain);
        println!(
            "plain slab test on {device}: {lost} of {} rays lost",
            case.rays.len()
        );
        assert!(
            lost > 0,
            "{device}: the plain slab test lost no hit: the case does not test the box test"
        );
    }
}

/// Rays at a mesh's triangles (aimed at random points of them, vertices and edges
/// included) and at random points around it.
fn rays_at(mesh: &Mesh, n: usize, rng: &mut Rng) -> Vec<Ray> {
    let usable = mesh.included();
    let mut rays = random_rays(rng, n / 2, mesh);
    let r = mesh.bounds().extent().length().max(1e-3);
    for i in 0..n - n / 2 {
        let t = &mesh.triangles[usable[i % usable.len()] as usize];
        let (u, v) = match i % 4 {
            0 => (0.0, 0.0),
            1 => (0.5, 0.0),
            _ => {
                let (u, v) = (rng.f32(), rng.f32());
                if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                }
            }
        };
        let target = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * v;
        let o = target + rng.dir() * 2.0 * r;
        rays.push(Ray::new(o, target - o, 0.0, 3.4e38));
    }
    rays
}

/// `n` triangles whose boxes all have their centre exactly at the origin (v₁ = −v₀, and
/// |v₂| ≤ |v₀| on every axis): no centroid split separates them.
fn one_centroid(n: usize, rng: &mut Rng) -> Mesh {
    let tris = (0..n)
        .map(|_| {
            let a = rng.vec3(-1.0, 1.0);
            Triangle::new(a, -a, a * rng.vec3(-1.0, 1.0))
        })
        .collect();
    Mesh::from_triangles(tris)
}

/// A soup with zero-area (a repeated vertex), collinear and needle (1e-6 wide) triangles.
fn slivers(rng: &mut Rng) -> Mesh {
    let mut tris = soup(rng, 200, 0.3).triangles;
    for _ in 0..100 {
        let (a, b) = (rng.vec3(-1.0, 1.0), rng.vec3(-1.0, 1.0));
        tris.push(Triangle::new(a, a, b));
        tris.push(Triangle::new(a, b, a + (b - a) * 0.25));
        let side = (b - a).cross(Vec3::Z).normalize_or(Vec3::X) * 1e-6;
        tris.push(Triangle::new(a, b, (a + b) * 0.5 + side));
    }
    Mesh::from_triangles(tris)
}

#[test]
fn degenerate_input_gives_the_same_answers_on_cpu_gpu_and_the_oracle() {
    let mut rng = Rng::new(31);
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(-1.0, -0.5, 0.2),
        Vec3::new(1.0, -0.25, 0.0),
        Vec3::new(0.1, 0.9, -0.3),
    )]);
    let meshes = [
        ("one triangle", one, 2000),
        (
            "10^6 triangles, one centroid",
            one_centroid(1_000_000, &mut rng),
            100,
        ),
        (
            "zero-area, collinear and needle triangles",
            slivers(&mut rng),
            3000,
        ),
    ];
    for (name, mesh, n) in meshes {
        let rays = rays_at(&mesh, n, &mut rng);
        check_robust(&HardCase {
            name,
            mesh,
            rays,
            exact: false,
        });
    }
}

#[test]
fn f64_precision_traces_the_oracles_answers_on_the_cpu_and_the_gpu_refuses_it() {
    let mut rng = Rng::new(77);
    let mesh = soup(&mut rng, 2000, 0.2);
    let rays = random_rays(&mut rng, 4000, &mesh);
    let f64 = Robustness {
        precision: Precision::F64,
        ..Robustness::default()
    };
    let hits = trace(&Device::cpu(), &mesh, &rays, f64);
    let unlike = (rays.iter().zip(&hits))
        .filter(|(r, h)| match oracle::closest(&mesh, r) {
            None => h.is_hit(),
            Some((t, p)) => h.prim != p || h.t != t as f32,
        })
        .count();
    let n_hits = hits.iter().filter(|h| h.is_hit()).count();
    println!(
        "f64 tracer: {n_hits} hits of {} rays, {unlike} unlike the oracle",
        rays.len()
    );
    assert!(n_hits > rays.len() / 4, "too few hits to compare");
    assert_eq!(unlike, 0, "the f64 tracer is not the oracle's arithmetic");
    for case in cases::all(1000, 3) {
        let hits = trace(&Device::cpu(), &case.mesh, &case.rays, f64);
        assert_eq!(
            false_misses(&case.mesh, &case.rays, &hits, &f64),
            0,
            "{}",
            case.name
        );
    }
    // Secondary rays from exactly computed hit points (on the Cornell box's walls at 0,
    // where the error bound and so the offset are 0) start on their own surface: there the
    // f64 test computes t = ±1e-17, which its own error bound must reject.
    let cornell = load_obj(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.obj"),
    )
    .unwrap();
    let (rays2, own) = secondary::secondary_rays(&cornell, 2000, RayOffset::ErrorBound, 3);
    let hits2 = trace(&Device::cpu(), &cornell, &rays2, f64);
    let selfs = secondary::self_hits(&hits2, &own);
    println!(
        "f64 tracer: {selfs} of {} secondary rays re-hit their triangle",
        rays2.len()
    );
    assert_eq!(selfs, 0);
    // No f64 on the GPU, and no f64 in the structures other than the BVH: refused by name.
    let options = TracerOptions {
        robustness: f64,
        ..TracerOptions::default()
    };
    let e = Tracer::new(gpu_device(), &mesh, &options)
        .unwrap()
        .trace(&rays, Query::Closest)
        .unwrap_err();
    assert!(
        e.to_string().contains("f64 precision runs on the CPU only"),
        "{e}"
    );
    let cpu = Device::cpu();
    let e = Tracer::with_structure(&cpu, &mesh, AccelKind::KdTree, &options)
        .unwrap()
        .trace(&rays, Query::Closest)
        .unwrap_err();
    assert!(e.to_string().contains("f64 precision is the BVH's"), "{e}");
}

/// Every structure (each BVH layout included) on the CPU, and every GPU form on the GPU.
fn every_tracer(mesh: &Mesh) -> Vec<(String, Tracer<'static>)> {
    let options = TracerOptions::default();
    let kinds = (LayoutKind::ALL.iter().map(|&l| AccelKind::Bvh(l))).chain(
        AccelKind::ALL
            .iter()
            .copied()
            .filter(|k| !matches!(k, AccelKind::Bvh(_))),
    );
    let mut tracers = Vec::new();
    for kind in kinds {
        let name = match kind {
            AccelKind::Bvh(layout) => format!("bvh {}", layout.name()),
            other => other.to_string(),
        };
        let cpu = Tracer::with_structure(cpu_device(), mesh, kind, &options).unwrap();
        tracers.push((format!("{name} on the cpu"), cpu));
        if accel::build_gpu(kind, mesh, &options.build)
            .unwrap()
            .is_some()
        {
            let gpu = Tracer::with_structure(gpu_device(), mesh, kind, &options).unwrap();
            tracers.push((format!("{name} on the gpu"), gpu));
        }
    }
    tracers
}

fn cpu_device() -> &'static Device {
    static CPU: std::sync::OnceLock<Device> = std::sync::OnceLock::new();
    CPU.get_or_init(Device::cpu)
}

/// A ray's tmax of +∞ (a valid interval: "no end") finds what tmax = f32::MAX finds, in every
/// structure on both devices; the box cut must not become ∞ − ∞ = NaN.
#[test]
fn an_infinite_tmax_hits_like_the_largest_finite_one_everywhere() {
    let mut rng = Rng::new(2024);
    let mesh = soup(&mut rng, 800, 0.3);
    let finite: Vec<Ray> = (random_rays(&mut rng, 600, &mesh).into_iter())
        .map(|r| Ray::new(r.origin, r.dir, r.tmin, f32::MAX))
        .collect();
    let infinite: Vec<Ray> = (finite.iter())
        .map(|r| Ray::new(r.origin, r.dir, r.tmin, f32::INFINITY))
        .collect();
    for (name, mut tracer) in every_tracer(&mesh) {
        let a = tracer.trace(&finite, Query::Closest).unwrap().hits;
        let b = tracer.trace(&infinite, Query::Closest).unwrap().hits;
        let hits = a.iter().filter(|h| h.is_hit()).count();
        let unlike = (a.iter().zip(&b)).filter(|(x, y)| x.prim != y.prim).count();
        let lost = false_misses(&mesh, &infinite, &b, &Robustness::default());
        println!("{name}: {hits} hits with tmax = MAX, {unlike} differ with tmax = ∞, {lost} lost");
        assert!(hits > 100, "{name}: the rays should hit the soup");
        assert_eq!(unlike, 0, "{name}: tmax = ∞ changes {unlike} hits");
        assert_eq!(lost, 0, "{name}: tmax = ∞ loses {lost} hits");
    }
}

/// Short directions: scaled down to just above `limits::MIN_DIR` a ray hits the same triangle
/// as the unit ray, at t scaled up exactly by the inverse power of two; below it the ray is
/// invalid (a miss, not an answer computed with every axis taken as parallel).
#[test]
fn directions_down_to_min_dir_hit_like_unit_ones_and_shorter_ones_are_refused() {
    let mut rng = Rng::new(77);
    let mesh = soup(&mut rng, 800, 0.3);
    let unit = random_rays(&mut rng, 600, &mesh);
    let scale = |s: f32| -> Vec<Ray> {
        (unit.iter())
            .map(|r| Ray::new(r.origin, r.dir * s, r.tmin, r.tmax))
            .collect()
    };
    // 2⁻⁶⁴ ≈ 5.4e-20 keeps every unit component's scaled copy exact and above MIN_DIR
    // for the largest; 2⁻⁷⁰ ≈ 8.5e-22 puts every component below it.
    let (short, too_short) = (scale(2f32.powi(-64)), scale(2f32.powi(-70)));
    assert!(too_short.iter().all(|r| !r.is_valid()) && short.iter().all(|r| r.is_valid()));
    for (name, mut tracer) in every_tracer(&mesh) {
        let a = tracer.trace(&unit, Query::Closest).unwrap().hits;
        let b = tracer.trace(&short, Query::Closest).unwrap().hits;
        let c = tracer.trace(&too_short, Query::Closest).unwrap().hits;
        let hits = a.iter().filter(|h| h.is_hit()).count();
        let unlike = (a.iter().zip(&b)).filter(|(x, y)| x.prim != y.prim).count();
        let lost = false_misses(&mesh, &short, &b, &Robustness::default());
        let wrong = wrong_answers(&mesh, &short, &b);
        println!("{name}: {hits} unit hits; 2^-64 directions: {unlike} differ, {lost} lost, {wrong} wrong");
        assert!(hits > 100, "{name}: the rays should hit the soup");
        assert_eq!((unlike, lost, wrong), (0, 0, 0), "{name}");
        assert!(
            c.iter().all(|h| !h.is_hit()),
            "{name}: invalid rays must miss"
        );
    }
}

/// Two parallel 2 × 2 walls `gap` apart (z = 0 and z = gap), scaled and moved; the first two
/// triangles are the lower wall.
fn two_walls(gap: f32, scale: f32, shift: f32) -> Mesh {
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * scale + Vec3::splat(shift);
    let quad = |z: f32| {
        let [a, b, c, d] = [p(-1., -1., z), p(1., -1., z), p(1., 1., z), p(-1., 1., z)];
        [Triangle::new(a, b, c), Triangle::new(a, c, d)]
    };
    Mesh::from_triangles([quad(0.0), quad(gap)].concat())
}

/// Secondary rays leaving one of two walls 1e-4 of the scene's width apart, toward the
/// other: with the error-bound offset every one hits the other wall (no tunnelling) and none
/// its own triangle, at scales 1e-3 … 1e4 and 1e5 away from the origin, on CPU and GPU. The
/// scene-relative fixed epsilon (1e-4 of the diagonal) starts beyond the other wall and
/// tunnels (asserted, so the test can fail); no offset re-hits its own wall.
#[test]
fn secondary_rays_between_close_walls_neither_tunnel_nor_re_hit() {
    let mut fixed_tunnels = 0;
    // Moved away, the walls stay resolvable while their gap exceeds the hit points' error
    // bound, about 4e-7 of their distance from the origin (the gap here is 2e-4 × scale).
    for (scale, shift) in [(1e-3f32, 0.0f32), (1.0, 0.0), (1e4, 0.0), (1e3, 1e5)] {
        let mesh = two_walls(2e-4, scale, shift);
        for offset in [RayOffset::ErrorBound, RayOffset::Fixed, RayOffset::None] {
            let (rays, own) = secondary::secondary_rays(&mesh, 2000, offset, 9);
            // Rays leaving toward the other wall, clearly (not along the walls), that cross
            // its plane well inside it (not past its edge).
            let toward: Vec<(Ray, u32)> = (rays.iter().zip(&own))
                .filter(|(r, &o)| {
                    let (up, other_z) = if o < 2 { (1.0, 2e-4) } else { (-1.0, 0.0) };
                    let z = other_z * scale + shift;
                    let land = r.origin + r.dir * ((z - r.origin.z) / r.dir.z);
                    r.dir.z * up > 0.05 * r.dir.length()
                        && ((land.x - shift) / scale).abs() < 0.99
                        && ((land.y - shift) / scale).abs() < 0.99
                })
                .map(|(r, &o)| (*r, o))
                .collect();
            let only: Vec<Ray> = toward.iter().map(|(r, _)| *r).collect();
            let rob = Robustness {
                ray_offset: offset,
                ..Robustness::default()
            };
            for device in [&Device::cpu(), gpu_device()] {
                let hits = trace(device, &mesh, &only, rob);
                let other = |o: u32, p: u32| (o < 2) != (p < 2) && p != lancer::geometry::MISS;
                let tunnelled = (hits.iter().zip(&toward))
                    .filter(|(h, (_, o))| !other(*o, h.prim) && h.prim != *o)
                    .count();
                let selfs = (hits.iter().zip(&toward))
                    .filter(|(h, (_, o))| h.prim == *o)
                    .count();
                println!(
                    "walls ×{scale:e} +{shift:e}, {offset:?} on {device}: {} rays toward the \
                     other wall, {tunnelled} tunnel through it, {selfs} re-hit their own",
                    toward.len()
                );
                assert!(toward.len() > 1000);
                if offset == RayOffset::ErrorBound {
                    assert_eq!(
                        (tunnelled, selfs),
                        (0, 0),
                        "×{scale:e} +{shift:e} on {device}"
                    );
                }
                if offset == RayOffset::Fixed {
                    fixed_tunnels += tunnelled;
                }
            }
        }
    }
    assert!(
        fixed_tunnels > 0,
        "the fixed epsilon never tunnelled: the walls are too far apart"
    );
}

/// Primary hits' t against the f64 oracle's: a relative error of at most 1e-5, measured
/// against max(t, scene size × 1e-3) (a tiny t near the origin is f32 cancellation, not the
/// test's error), for the bunny at scales 1e-4 … 1e4 and moved to 1e5, on CPU and GPU.
#[test]
fn primary_hits_t_equals_the_oracles_within_1e_5() {
    let Some(bunny) = common::load_model("stanford-bunny.obj") else {
        return;
    };
    for (scale, shift) in [(1.0f32, 0.0f32), (1e-4, 0.0), (1e4, 0.0), (1e3, 1e5)] {
        let tris: Vec<Triangle> = (bunny.triangles.iter())
            .map(|t| Triangle {
                v: t.v.map(|p| p * scale + Vec3::splat(shift)),
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let size = mesh.bounds().extent().length() as f64;
        let rays = lancer::camera::Camera::default_view(&mesh.bounds(), 48, 48).primary_rays();
        let truths = oracle::Truths::new(&mesh, &rays);
        for device in [&Device::cpu(), gpu_device()] {
            let hits = trace(device, &mesh, &rays, Robustness::default());
            let (mut worst, mut compared) = (0.0f64, 0);
            for (i, (r, h)) in rays.iter().zip(&hits).enumerate() {
                let Some((t, p)) = truths.closest(i) else {
                    continue;
                };
                if p != h.prim {
                    continue; // a tie or an edge: judged by the other tests
                }
                let err = (h.t as f64 - t).abs() * r.dir.length() as f64
                    / (t * r.dir.length() as f64).max(size * 1e-3);
                worst = worst.max(err);
                compared += 1;
            }
            println!("bunny ×{scale:e} +{shift:e} on {device}: {compared} hits, largest relative t error {worst:.2e}");
            assert!(compared > 500, "too few hits compared");
            assert!(
                worst <= 1e-5,
                "×{scale:e} +{shift:e} on {device}: t error {worst:e}"
            );
        }
    }
}
