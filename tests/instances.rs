//! Two-level acceleration on the CPU (`accel::instances`): an instanced scene traces as its
//! flattened copy does — bit for bit where the maps are exact (identity), judged by the f64
//! oracle on the world-space triangles where they round (rotations, scales, mirrors) — with
//! every structure of the registry and every BVH layout as the bottom level, the tie rule
//! kept across instances, and bad instances refused; the top level's WGSL on the GPU equals
//! its CPU twin bit for bit with every layout.

mod common;

use std::sync::Arc;

use common::accel_check::{brute_force, check};
use common::gpu_device;
use common::gpu_twin::{bits, cpu_device, same_on_gpu};
use common::{random_rays, soup, Rng};
use glam::{Mat4, Quat, Vec3};
use lancer::accel::bvh::BuildOptions;
use lancer::accel::instances::{Affine, GpuTwoLevel, Instance, InstanceSet, TwoLevel};
use lancer::accel::{build, Accel, AccelKind, GpuForm};
use lancer::geometry::{Hit, Triangle};
use lancer::mesh::Mesh;
use lancer::render::RenderOptions;
use lancer::trace::oracle::{judge, Verdict};
use lancer::{LayoutKind, Query, RayStats, Robustness, Tracer, TracerOptions};

/// The sky of the instanced field's render.
const SKY: Vec3 = Vec3::new(0.35, 0.45, 0.6);

/// Every bottom level: each structure of the registry, and the BVH in every layout.
fn every_bottom() -> Vec<AccelKind> {
    let layouts = LayoutKind::ALL.iter().map(|&l| AccelKind::Bvh(l));
    AccelKind::ALL[1..].iter().copied().chain(layouts).collect()
}

fn placed(mesh: u32, to_world: Affine) -> Instance {
    Instance { mesh, to_world }
}

fn two_level(kind: AccelKind, set: &InstanceSet) -> TwoLevel {
    TwoLevel::build(kind, set, &BuildOptions::default())
        .unwrap_or_else(|e| panic!("{kind:?} does not build: {e}"))
}

/// Three soups, placed five times at the identity: instances 0 and 2 (and 1 and 4) are the
/// same triangles, so every hit on them is an exact tie across instances that the smaller
/// index wins, as in the flattened scene.
#[test]
fn at_the_identity_every_bottom_level_traces_the_flattened_scene_bit_for_bit() {
    let mut rng = Rng::new(3700);
    let meshes: Vec<Arc<Mesh>> = (0..3).map(|_| Arc::new(soup(&mut rng, 400, 0.3))).collect();
    let instances = [0, 1, 0, 2, 1]
        .map(|m| placed(m, Affine::IDENTITY))
        .to_vec();
    let set = InstanceSet::new(meshes, instances).unwrap();
    let flat = set.flatten().expect("the set flattens");
    assert_eq!(flat.len(), 2000);
    let rays = random_rays(&mut rng, 2000, &flat);
    let expected = brute_force(&flat, &rays);
    let ties = expected.iter().filter(|h| h.is_hit()).count();
    for kind in every_bottom() {
        let name = format!("{kind:?}");
        let two = two_level(kind, &set);
        let (hits, _) = two.trace_batch(&rays, Query::Closest, &Robustness::default());
        for (i, (got, want)) in hits.iter().zip(&expected).enumerate() {
            assert_eq!(got, want, "{name}: ray {i} {:?}", rays[i]);
        }
        // Duplicates are exact ties: the hit is always on instance 0, 1 or 3.
        let firsts = set.first_prims();
        for h in hits.iter().filter(|h| h.is_hit()) {
            assert!(
                h.prim < firsts[2] || (firsts[3]..firsts[4]).contains(&h.prim),
                "{h:?}"
            );
        }
        check(&name, &flat, &two, &rays);
    }
    assert!(ties > 500, "only {ties} rays hit");
}

/// Rotated, scaled, mirrored and moved copies of a soup: every answer agrees with the
/// oracle on the flattened (world-space) triangles, closest and any hit, and the closest hit
/// is the flattened BVH's triangle on almost every ray (they differ only where rounding the
/// map moves a ray across an edge or between near-equal hits).
#[test]
fn moved_instances_agree_with_the_oracle_and_their_flattened_copy() {
    let mut rng = Rng::new(3701);
    let meshes = vec![
        Arc::new(soup(&mut rng, 600, 0.2)),
        Arc::new(soup(&mut rng, 300, 0.4)),
    ];
    let maps = [
        Mat4::from_scale_rotation_translation(
            Vec3::splat(0.5),
            Quat::from_rotation_y(0.8),
            Vec3::new(0.3, 0.1, -0.2),
        ),
        Mat4::from_scale_rotation_translation(
            Vec3::new(-1.0, 1.0, 1.0),
            Quat::from_rotation_x(-0.4),
            Vec3::new(-0.6, 0.0, 0.5),
        ),
        Mat4::from_translation(Vec3::new(0.7, -0.3, 0.9)),
        Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.7, 1.3),
            Quat::from_rotation_z(2.1) * Quat::from_rotation_x(0.3),
            Vec3::new(-1.1, 1.2, 0.0),
        ),
    ];
    let instances = maps
        .iter()
        .enumerate()
        .map(|(i, m)| placed(i as u32 % 2, Affine::from_mat4(m)))
        .collect();
    let set = InstanceSet::new(meshes, instances).unwrap();
    let flat = set.flatten().expect("the set flattens");
    let rays = random_rays(&mut rng, 3000, &flat);
    let rob = Robustness::default();
    let bvh = build(AccelKind::ALL[0], &flat, &BuildOptions::default()).unwrap();
    let (reference, _) = bvh.trace_batch(&rays, Query::Closest, &rob);
    let hit = reference.iter().filter(|h| h.is_hit()).count();
    assert!(hit > 1000, "only {hit} rays hit");
    for kind in [
        AccelKind::Bvh(LayoutKind::DfsSign),
        AccelKind::Bvh(LayoutKind::Cwbvh),
        AccelKind::KdTree,
    ] {
        let name = format!("{kind:?}, moved");
        let two = two_level(kind, &set);
        check(&name, &flat, &two, &rays);
        let (hits, _) = two.trace_batch(&rays, Query::Closest, &rob);
        let differ = (hits.iter().zip(&reference))
            .filter(|(a, b)| a.prim != b.prim)
            .count();
        println!(
            "{name}: {differ} of {} rays hit another triangle",
            rays.len()
        );
        assert!(differ * 200 <= rays.len(), "{name}: {differ} differ");
        for ((r, a), b) in rays.iter().zip(&hits).zip(&reference) {
            if a.prim == b.prim && a.is_hit() {
                let rel = (a.t - b.t).abs() / b.t.abs().max(1e-6);
                assert!(rel < 1e-4, "{name}: {r:?}: t {} against {}", a.t, b.t);
            }
        }
    }
}

/// A mirrored copy of a single triangle is hit with the same barycentrics as its flattened
/// copy (corners are not reordered by a mirroring map), and hits are numbered by instance.
#[test]
fn hits_are_numbered_by_instance_with_the_same_barycentrics() {
    let tri = Triangle::new(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    );
    let mesh = Arc::new(Mesh::from_triangles(vec![tri, tri]));
    let mirror = Affine::from_mat4(&Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
    let far = Affine::translation(Vec3::new(0.0, 0.0, 4.0));
    let set = InstanceSet::new(
        vec![mesh],
        vec![
            placed(0, far),
            placed(0, mirror),
            placed(0, Affine::IDENTITY),
        ],
    )
    .unwrap();
    assert_eq!(set.first_prims(), [0, 2, 4]);
    let ray = lancer::geometry::Ray::new(Vec3::new(0.3, -0.2, -5.0), Vec3::Z, 0.0, f32::INFINITY);
    let flat = set.flatten().expect("the set flattens");
    let two = two_level(AccelKind::Bvh(LayoutKind::DfsSign), &set);
    let mut stats = RayStats::default();
    let got = two.intersect(&ray, Query::Closest, &Robustness::default(), &mut stats);
    let want = brute_force(&flat, &[ray])[0];
    assert_eq!(got, want);
    // The mirror and the identity instance are coincident at z = 0: the mirror (2) wins.
    assert_eq!(got.prim, 2);
    assert_eq!(got.t, 5.0);
    assert!(stats.nodes >= 3 && stats.tris >= 2, "{stats:?}");
    let any = two.intersect(&ray, Query::Any, &Robustness::default(), &mut stats);
    assert!(any.is_hit() && judge(&flat, &ray, &got) == Verdict::Agree);
}

/// A mesh with no usable triangle takes numbers but no place in the top level; one instance
/// is one leaf; bad instances are refused with what is wrong.
#[test]
fn empty_meshes_keep_their_numbers_and_bad_instances_are_refused() {
    let mut rng = Rng::new(3702);
    let flat_only = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X)]);
    let meshes = vec![Arc::new(flat_only), Arc::new(soup(&mut rng, 100, 0.3))];
    let instances = vec![
        placed(1, Affine::IDENTITY),
        placed(0, Affine::IDENTITY),
        placed(1, Affine::translation(Vec3::splat(3.0))),
    ];
    let set = InstanceSet::new(meshes.clone(), instances).unwrap();
    assert_eq!(set.first_prims(), [0, 100, 101]);
    let two = two_level(AccelKind::Bvh(LayoutKind::Bvh8), &set);
    assert_eq!((two.placed_instances(), two.top_nodes()), (2, 3));
    let flat = set.flatten().expect("the set flattens");
    let rays = random_rays(&mut rng, 500, &flat);
    check("instances after an empty mesh", &flat, &two, &rays);
    let (hits, _) = two.trace_batch(&rays, Query::Closest, &Robustness::default());
    assert!(hits.iter().any(|h| h.prim > 100) && hits.iter().any(|h| h.prim < 100));

    let refused = |instances: Vec<Instance>| {
        InstanceSet::new(meshes.clone(), instances)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    assert!(refused(vec![placed(2, Affine::IDENTITY)]).contains("places mesh 2 of 2"));
    let singular = Affine::from_mat4(&Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)));
    assert!(refused(vec![placed(0, singular)]).contains("not finite and invertible"));
    let mut nan = Affine::IDENTITY;
    nan.rows[2][3] = f32::NAN;
    assert!(refused(vec![placed(1, Affine::IDENTITY), placed(1, nan)]).contains("instance 1"));
    // A scene with nothing to hit misses everything.
    let empty = InstanceSet::new(meshes, vec![placed(0, Affine::IDENTITY)]).unwrap();
    let two = two_level(AccelKind::Bvh(LayoutKind::DfsSign), &empty);
    let (hits, _) = two.trace_batch(&rays, Query::Closest, &Robustness::default());
    assert!(hits.iter().all(|h| *h == Hit::miss(h.t) && !h.is_hit()));
}

/// The top level's WGSL against its CPU twin, bit for bit (hits and work counted, both BVH
/// memories, closest and any hit), with every layout as the bottom level: moved, rotated,
/// scaled and mirrored instances of three meshes, and duplicates at the identity (exact ties
/// across instances). Mesh 0, one triangle, has the shallowest tree: the kernel's stack must
/// hold the walk of the deepest bottom level, not of the first.
#[test]
fn gpu_two_level_equals_its_cpu_twin_with_every_layout() {
    let mut rng = Rng::new(3703);
    let one = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let meshes = vec![
        Arc::new(Mesh::from_triangles(vec![one])),
        Arc::new(soup(&mut rng, 300, 0.25)),
        Arc::new(soup(&mut rng, 200, 0.4)),
    ];
    let maps = [
        Affine::IDENTITY,
        Affine::from_mat4(&Mat4::from_scale_rotation_translation(
            Vec3::new(-0.7, 0.7, 0.7),
            Quat::from_rotation_y(0.8),
            Vec3::new(0.4, 0.1, -0.3),
        )),
        Affine::IDENTITY,
        Affine::from_mat4(&Mat4::from_scale_rotation_translation(
            Vec3::new(1.5, 0.6, 1.1),
            Quat::from_rotation_z(2.1) * Quat::from_rotation_x(0.3),
            Vec3::new(-0.9, 0.8, 0.2),
        )),
    ];
    let instances = [(0, 3), (1, 0), (2, 1), (1, 2), (2, 3), (2, 0)]
        .map(|(m, a)| placed(m, maps[a]))
        .to_vec();
    let set = InstanceSet::new(meshes, instances).unwrap();
    let flat = set.flatten().expect("the set flattens");
    let rays = random_rays(&mut rng, 1500, &flat);
    for &layout in LayoutKind::ALL {
        let two = GpuTwoLevel::build(layout, &set, &BuildOptions::default()).unwrap();
        let tree: Arc<dyn GpuForm> = Arc::new(two);
        let [closest, _] = same_on_gpu(
            &format!("two-level {layout}"),
            &tree,
            &rays,
            Robustness::default(),
        );
        let hits = closest.iter().filter(|h| h.is_hit()).count();
        assert!(hits > 500, "{layout}: only {hits} hits");
        for (r, h) in rays.iter().zip(&closest) {
            let v = judge(&flat, r, h);
            assert!(
                !matches!(v, Verdict::Wrong(_)),
                "{layout}: {r:?}: {h:?}: {v:?}"
            );
        }
    }
}

/// The two-level twin's batches over cwbvh bottom levels walk two rays at a time
/// (`interleaved.rs`); over other layouts, one at a time. Either way every hit is the one
/// walked alone (`intersect`) gives, bit for bit: closest and any hit, under each triangle
/// test, over several batch chunks, with rotated, mirrored and coincident instances (exact
/// ties across instances), rays parallel to an axis and invalid rays among them.
#[test]
fn two_level_batches_answer_as_rays_walked_alone() {
    let mut rng = Rng::new(3710);
    let one = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let meshes = vec![
        Arc::new(soup(&mut rng, 300, 0.25)),
        Arc::new(Mesh::from_triangles(vec![one])),
        Arc::new(soup(&mut rng, 500, 0.3)),
    ];
    let turned = Affine::from_mat4(&Mat4::from_scale_rotation_translation(
        Vec3::new(-0.8, 1.2, 0.9),
        Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.2),
        Vec3::new(0.3, -0.2, 0.5),
    ));
    let instances = [
        (0, Affine::IDENTITY),
        (2, turned),
        (0, Affine::IDENTITY),
        (1, turned),
        (2, Affine::IDENTITY),
    ]
    .map(|(m, a)| placed(m, a))
    .to_vec();
    let set = InstanceSet::new(meshes, instances).unwrap();
    let flat = set.flatten().expect("the set flattens");
    let mut rays = random_rays(&mut rng, 3000, &flat);
    for (i, r) in rays.iter_mut().enumerate().step_by(37) {
        r.dir[i % 3] = 0.0;
    }
    rays[5].dir = Vec3::NAN;
    rays[1500].tmin = rays[1500].tmax + 1.0;
    let cwbvh = AccelKind::Bvh(LayoutKind::Cwbvh);
    assert!(build(cwbvh, &flat, &BuildOptions::default())
        .unwrap()
        .as_cwbvh()
        .is_some());
    let settings = [
        Robustness::default(),
        Robustness {
            triangle_test: lancer::geometry::TriangleTest::MollerTrumbore,
            ..Robustness::default()
        },
        Robustness {
            precision: lancer::geometry::Precision::F64,
            ..Robustness::default()
        },
    ];
    for kind in [cwbvh, AccelKind::Bvh(LayoutKind::DfsSign)] {
        let two = two_level(kind, &set);
        for rob in &settings {
            for query in [Query::Closest, Query::Any] {
                let batch = two.trace_hits(&rays, query, rob);
                let mut hits = 0;
                for (i, (r, got)) in rays.iter().zip(&batch).enumerate() {
                    let alone = two.intersect(r, query, rob, &mut RayStats::default());
                    assert_eq!(bits(got), bits(&alone), "{kind:?} {query:?} ray {i}: {r:?}");
                    hits += alone.is_hit() as usize;
                }
                assert!(hits > 1000, "{kind:?} {query:?}: only {hits} hits");
            }
        }
    }
}

/// The library's way in: a `Tracer` over instances, on the CPU and the GPU, answers as the
/// flattened scene's tracer does at the identity (bit for bit), in the default layouts.
#[test]
fn tracers_over_instances_answer_as_over_the_flattened_scene() {
    let mut rng = Rng::new(3704);
    let meshes = vec![Arc::new(soup(&mut rng, 500, 0.3))];
    let instances = [0, 0, 0].map(|m| placed(m, Affine::IDENTITY)).to_vec();
    let set = InstanceSet::new(meshes, instances).unwrap();
    let flat = set.flatten().expect("the set flattens");
    let rays = random_rays(&mut rng, 1000, &flat);
    let want = brute_force(&flat, &rays);
    let options = TracerOptions {
        stats: true,
        ..TracerOptions::default()
    };
    for device in [cpu_device(), gpu_device()] {
        let mut two = Tracer::with_instances(device, &set, &options).unwrap();
        let mut one = Tracer::new(device, &flat, &options).unwrap();
        let got = two.trace(&rays, Query::Closest).unwrap();
        let flat_hits = one.trace(&rays, Query::Closest).unwrap().hits;
        assert_eq!(got.cpu_retraced, 0);
        for (i, ((a, b), w)) in got.hits.iter().zip(&flat_hits).zip(&want).enumerate() {
            assert!(
                bits(a) == bits(w) && bits(b) == bits(w),
                "ray {i}: {a:?} {b:?} {w:?}"
            );
        }
        // Every hit is on the first copy: the tie rule across instances.
        assert!(got.hits.iter().all(|h| !h.is_hit() || h.prim < 500));
        let two_stats = got.stats.unwrap();
        assert!(two_stats.iter().any(|s| s.nodes > 3));
        // TracerOptions::flatten: the set traced as its flattened mesh, work counters too.
        let flatten = TracerOptions {
            flatten: true,
            ..options
        };
        let mut flattened = Tracer::with_instances(device, &set, &flatten).unwrap();
        let got = flattened.trace(&rays, Query::Closest).unwrap();
        let one_stats = one.trace(&rays, Query::Closest).unwrap().stats.unwrap();
        assert!(got
            .hits
            .iter()
            .zip(&flat_hits)
            .all(|(a, b)| bits(a) == bits(b)));
        assert_eq!(got.stats.unwrap(), one_stats);
        assert_ne!(
            two_stats, one_stats,
            "two levels count their top level's work"
        );
    }
}

/// A wavy field of 100,352 triangles placed 1,000 times, turned and moved: 10⁸ instanced
/// triangles.
fn hundred_million() -> (Arc<Mesh>, InstanceSet) {
    let n = 224u32;
    let positions: Vec<[f32; 3]> = (0..=n)
        .flat_map(|j| {
            (0..=n).map(move |i| {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                [x, 0.05 * (12.0 * x).sin() * (9.0 * y).cos(), y]
            })
        })
        .collect();
    let quads = (0..n).flat_map(|j| (0..n).map(move |i| j * (n + 1) + i));
    let indices: Vec<[u32; 3]> = quads
        .flat_map(|a| [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]])
        .collect();
    let field = Arc::new(Mesh::from_indexed(&positions, &indices).unwrap());
    assert_eq!(field.len(), 100_352);
    let instances: Vec<Instance> = (0..1000)
        .map(|k| {
            let m = Mat4::from_rotation_translation(
                Quat::from_rotation_y(0.7 * k as f32),
                Vec3::new((k % 32) as f32, 0.0, (k / 32) as f32),
            );
            placed(0, Affine::from_mat4(&m))
        })
        .collect();
    let set = InstanceSet::new(vec![field.clone()], instances).unwrap();
    assert_eq!(set.triangle_count(), 100_352_000);
    (field, set)
}

/// The view over [`hundred_million`]'s field.
const FIELD_EYE: Vec3 = Vec3::new(16.0, 24.0, -4.0);

/// 10⁸ instanced triangles ([`hundred_million`]) built and traced on the CPU and the GPU
/// (never flattened: that would take ~4 GB). The GPU equals the CPU twin bit for bit; every
/// hit lies on its instance's triangle in f64.
#[test]
fn a_hundred_million_instanced_triangles_trace_on_both_devices() {
    let (field, set) = hundred_million();
    let camera = lancer::camera::Camera {
        eye: FIELD_EYE,
        look_at: Vec3::new(16.0, 0.0, 15.0),
        up: Vec3::Y,
        vfov_deg: 50.0,
        width: 64,
        height: 48,
    };
    let rays = camera.primary_rays();
    let mut answers = Vec::new();
    for device in [cpu_device(), gpu_device()] {
        let mut tracer = Tracer::with_instances(device, &set, &TracerOptions::default()).unwrap();
        let result = tracer.trace(&rays, Query::Closest).unwrap();
        assert_eq!(result.cpu_retraced, 0);
        answers.push(result.hits);
    }
    let (cpu, gpu) = (&answers[0], &answers[1]);
    assert!(
        cpu.iter().zip(gpu).all(|(a, b)| bits(a) == bits(b)),
        "GPU ≠ CPU"
    );
    let hits: Vec<_> = rays.iter().zip(cpu).filter(|(_, h)| h.is_hit()).collect();
    assert!(
        hits.len() * 3 > rays.len(),
        "only {} of {} rays hit",
        hits.len(),
        rays.len()
    );
    let copies: std::collections::HashSet<u32> =
        hits.iter().map(|(_, h)| h.prim / 100_352).collect();
    assert!(copies.len() > 100, "hits on {} copies only", copies.len());
    // A hit within the map's rounding of an edge may miss its triangle in f64 (the ray
    // moved into object space is a few ulps off): such hits lie on an edge (barycentric
    // below 1e-3; the field's triangles are 1/224 wide); the rest hit in f64 at their t.
    let mut on_edges = 0;
    for (r, h) in &hits {
        let (k, local) = ((h.prim / 100_352) as usize, (h.prim % 100_352) as usize);
        let map = set.instances[k].to_world;
        let v = field.triangles[local]
            .v
            .map(|p| map.point_f64(p.as_dvec3()));
        let o = r.origin.as_dvec3();
        match lancer::geometry::intersect_f64(&v, o, r.dir.as_dvec3()) {
            Some((t, _, _)) => {
                assert!(
                    (t - h.t as f64).abs() <= 1e-4 * t,
                    "{r:?}: t {} against {t}",
                    h.t
                )
            }
            None => {
                on_edges += 1;
                let edge = h.u.min(h.v).min(1.0 - h.u - h.v);
                assert!(edge < 1e-3, "{r:?} misses its hit {h:?} in f64");
            }
        }
    }
    println!("{} hits, {on_edges} within rounding of an edge", hits.len());
    assert!(on_edges * 50 < hits.len());
}

/// A scene file's `copies` and `grid` (scenes/copies.toml: 64 spheres on a grid, three
/// boxes, a floor) keep each object once, placed by instances numbered as the flattened
/// scene: traced in two levels, rays hit what they hit in the flattened scene (where
/// another triangle, the f64 oracle judges both right), and the render equals the
/// flattened scene's render within the tolerance of a GPU against its CPU reference.
#[test]
fn scene_copies_trace_and_render_in_two_levels_as_the_flattened_scene() {
    let path = std::path::Path::new("scenes/copies.toml");
    let mut scene = lancer::RenderScene::from_file(path).unwrap();
    scene.camera.width = 96;
    scene.camera.height = 72;
    let set = scene
        .placements
        .as_ref()
        .expect("copies make placements")
        .set()
        .clone();
    assert_eq!((set.meshes.len(), set.instances.len()), (3, 1 + 64 + 3));
    let unique: usize = set.meshes.iter().map(|m| m.len()).sum();
    assert_eq!(scene.mesh.len(), unique, "each object once");
    let flat = scene.clone().flattened().unwrap();
    assert_eq!(flat.mesh.len() as u64, set.triangle_count());
    assert!(flat.placements.is_none());
    assert_eq!(flat.emitters, scene.emitters);
    let rays = scene.camera.primary_rays();
    let options = TracerOptions::default();
    let mut two = Tracer::with_instances(cpu_device(), &set, &options).unwrap();
    let mut one = Tracer::new(cpu_device(), &flat.mesh, &options).unwrap();
    let a = two.trace(&rays, Query::Closest).unwrap().hits;
    let b = one.trace(&rays, Query::Closest).unwrap().hits;
    let mut differ = 0;
    for ((r, x), y) in rays.iter().zip(&a).zip(&b) {
        if x.prim != y.prim {
            differ += 1;
            for h in [x, y] {
                let v = judge(&flat.mesh, r, h);
                assert!(!matches!(v, Verdict::Wrong(_)), "{r:?}: {h:?}: {v:?}");
            }
        }
    }
    println!(
        "{differ} of {} rays hit another triangle, each judged right",
        rays.len()
    );
    assert!(differ * 100 < rays.len());
    // Renders: two levels on the CPU and the GPU, and the flattened scene on the CPU.
    let opts = RenderOptions {
        spp: Some(2),
        ..RenderOptions::default()
    };
    let image = |s: &lancer::RenderScene, d: &lancer::Device| {
        lancer::render::render(s, d, &opts).unwrap().image.pixels
    };
    let placed = image(&scene, cpu_device());
    for (what, other) in [
        ("the flattened scene", image(&flat, cpu_device())),
        ("the GPU", image(&scene, gpu_device())),
    ] {
        let d: Vec<f32> = (placed.iter().zip(&other))
            .map(|(x, y)| (*x - *y).abs().max_element())
            .collect();
        let over = d.iter().filter(|&&x| x > 2.0 / 255.0).count();
        let mean = d.iter().sum::<f32>() / d.len() as f32;
        println!(
            "two levels against {what}: {over} of {} pixels over 2/255, mean {mean:e}",
            d.len()
        );
        assert!(over * 50 <= d.len() && mean <= 0.004, "{what}");
    }
    let lum: Vec<f32> = placed.iter().map(|c| c.x + c.y + c.z).collect();
    let spread = lum.iter().cloned().fold(0.0, f32::max) - lum.iter().cloned().fold(9.0, f32::min);
    assert!(spread > 0.1, "a flat image");
}

/// 10⁸ instanced triangles ([`hundred_million`]) render at a small size on the CPU and the
/// GPU, through two levels (the flattened scene would not fit CI's memory): the images
/// agree within the renderer's GPU tolerance, and show the field.
#[test]
fn a_hundred_million_instanced_triangles_render_on_both_devices() {
    let (field, set) = hundred_million();
    let n = field.len();
    let mut scene = lancer::RenderScene {
        camera: lancer::camera::Camera {
            eye: FIELD_EYE,
            look_at: Vec3::new(16.0, 0.0, 15.0),
            up: Vec3::Y,
            vfov_deg: 50.0,
            width: 48,
            height: 32,
        },
        settings: lancer::render::Settings {
            integrator: lancer::render::Integrator::Path,
            max_bounces: 1,
            spp: 1,
            seed: 3,
            ao_distance: 1.0,
        },
        mesh: (*field).clone(),
        uvs: vec![[glam::Vec2::ZERO; 3]; n],
        normals: Vec::new(),
        tangents: Vec::new(),
        material_of: vec![0; n],
        materials: vec![lancer::render::Material::diffuse(Vec3::splat(0.7))],
        textures: Vec::new(),
        lights: vec![lancer::render::Light::Directional {
            direction: Vec3::new(-0.4, -1.0, -0.5).normalize(),
            irradiance: Vec3::splat(2.5),
        }],
        environment: Some(lancer::render::Environment::uniform(SKY)),
        emitters: Vec::new(),
        emitter_cdf: Vec::new(),
        placements: None,
    };
    scene.placements = Some(lancer::render::Placements::new(set, vec![0]));
    assert_eq!(scene.triangle_count(), 100_352_000);
    let opts = RenderOptions::default();
    let cpu = lancer::render::render(&scene, cpu_device(), &opts)
        .unwrap()
        .image
        .pixels;
    let gpu = lancer::render::render(&scene, gpu_device(), &opts)
        .unwrap()
        .image
        .pixels;
    let d: Vec<f32> = (cpu.iter().zip(&gpu))
        .map(|(x, y)| (*x - *y).abs().max_element())
        .collect();
    let over = d.iter().filter(|&&x| x > 2.0 / 255.0).count();
    println!("GPU against CPU: {over} of {} pixels over 2/255", d.len());
    assert!(over * 50 <= d.len());
    let background = cpu
        .iter()
        .filter(|c| (**c - SKY).abs().max_element() < 1e-6)
        .count();
    println!("{background} of {} pixels see the sky", cpu.len());
    assert!(
        background * 3 < cpu.len() * 2,
        "the field covers under a third of the image"
    );
}

/// Secondary rays leaving placed triangles never re-hit them with the renderer's error
/// bound, which counts the placements' rounding ([`Placements::error`]): here a box whose
/// object space lies far from its origin, placed back near the world's origin, so that the
/// world vertices are small but carry the rounding of large ones. Without the placements'
/// term (the interpolation's bound alone) rays do re-hit: the test can fail.
#[test]
fn secondary_rays_leaving_placed_triangles_never_re_hit_them() {
    use lancer::render::{offset_origin, point_error, Placements};
    let mut rng = Rng::new(41);
    let far = Vec3::new(3.0e4, -2.0e4, 1.0e4);
    let mut mesh = soup(&mut rng, 300, 1.0);
    for t in &mut mesh.triangles {
        t.v = t.v.map(|p| p + far);
    }
    let mesh = Arc::new(mesh);
    let instances: Vec<Instance> = (0..12)
        .map(|k| {
            let m = Mat4::from_scale_rotation_translation(
                Vec3::splat([0.5f32, 1.0, 3.0][k % 3]),
                Quat::from_rotation_y(0.9 * k as f32) * Quat::from_rotation_x(0.4 * k as f32),
                Vec3::new(k as f32 * 0.3, 0.0, 0.0),
            ) * Mat4::from_translation(-far);
            placed(0, Affine::from_mat4(&m))
        })
        .collect();
    let set = InstanceSet::new(vec![mesh.clone()], instances).unwrap();
    let pl = Placements::new(set.clone(), vec![0]);
    let (mut full, mut bare, mut own) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..4000 {
        let prim = rng.u32() % set.triangle_count() as u32;
        let t = pl.triangle(prim, &mesh);
        let (mut u, mut v) = (rng.f32(), rng.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let w = 1.0 - u - v;
        let p = t.v[0] * w + t.v[1] * u + t.v[2] * v;
        let err = point_error(&t.v, w, u, v);
        let ng = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize();
        for side in [ng, -ng] {
            let mut d = rng.dir();
            if d.dot(side) < 0.0 {
                d = -d;
            }
            let ray =
                |e: Vec3| lancer::geometry::Ray::new(offset_origin(p, e, side), d, 0.0, 3.4e38);
            full.push(ray(err + pl.error(&t, p)));
            bare.push(ray(err));
            own.push(prim);
        }
    }
    let self_hits = |device: &lancer::Device, rays: &[lancer::geometry::Ray]| {
        let mut tracer = Tracer::with_instances(device, &set, &TracerOptions::default()).unwrap();
        let hits = tracer.trace(rays, Query::Closest).unwrap().hits;
        hits.iter().zip(&own).filter(|(h, o)| h.prim == **o).count()
    };
    let without = self_hits(cpu_device(), &bare);
    println!(
        "interpolation bound alone: {without} of {} rays re-hit",
        bare.len()
    );
    assert!(
        without > 0,
        "no self-hit without the placements' term: the test cannot fail"
    );
    for device in [cpu_device(), gpu_device()] {
        let with = self_hits(device, &full);
        println!(
            "{device}: with the placements' term: {with} of {} rays re-hit",
            full.len()
        );
        assert_eq!(with, 0, "{device}");
    }
}

/// `copies` and `grid` are checked as the rest of a scene is: one line naming the problem.
#[test]
fn bad_copies_are_refused_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |object: &str| {
        let path = dir.path().join("s.toml");
        let text = format!(
            "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
             [[objects]]\nshape = \"box\"\n{object}\n"
        );
        std::fs::write(&path, text).unwrap();
        let a = lancer::render::load_instances(&path)
            .err()
            .map(|e| e.to_string());
        let b = lancer::RenderScene::from_file(&path)
            .err()
            .map(|e| e.to_string());
        assert_eq!(a, b, "the assembled scene and its instances refuse alike");
        a.unwrap_or_default()
    };
    let both = "grid = { count = [2, 1, 1], step = [1.0, 0.0, 0.0] }\n[[objects.copies]]\n";
    assert!(refused(both).contains("s.toml:5: use one of 'copies' and 'grid'"));
    let empty = "grid = { count = [2, 0, 1], step = [1.0, 0.0, 0.0] }";
    assert!(refused(empty).contains("makes 0 copies"));
    // Counts whose product wraps around 2⁶⁴ to 4: refused by the true product.
    let wraps = "grid = { count = [2, 2147549185, 4294836226], step = [0.0, 0.0, 0.0] }";
    assert!(refused(wraps).contains("makes 18446744073709551620 copies"));
    let flat = "[[objects.copies]]\nscale = [1.0, 0.0, 1.0]";
    assert!(refused(flat).contains("'scale' must be finite and non-zero"));
    let unknown = "[[objects.copies]]\nmove = [1.0, 0.0, 1.0]";
    assert!(refused(unknown).contains("unknown field"));
    let runaway = "spin = [0.0, inf, 0.0]";
    assert!(refused(runaway).contains("s.toml:5: 'move' and 'spin' must be finite numbers"));
}

/// `Tracer::set_transforms` moves the instances of a tracer: only the top level is built
/// again and written over the uploaded arrays (in both memories; 1,000 instances make a
/// top level of ~8,000 words, more than a texture row), and the tracer then answers as one
/// built over the moved instances, bit for bit with the same work. Bad maps are refused and
/// leave the tracer as it was.
#[test]
fn moving_instances_traces_as_a_tracer_built_over_them() {
    let mut rng = Rng::new(77);
    let meshes = vec![
        Arc::new(soup(&mut rng, 40, 0.2)),
        Arc::new(soup(&mut rng, 25, 0.3)),
    ];
    let maps = |turn: f32| -> Vec<Affine> {
        (0..1000)
            .map(|k| {
                let m = Mat4::from_scale_rotation_translation(
                    Vec3::splat(0.5 + (k % 3) as f32 * 0.25),
                    Quat::from_rotation_y(turn * k as f32),
                    Vec3::new(
                        (k % 40) as f32,
                        (k / 40) as f32 * 0.1 + turn,
                        (k / 40) as f32,
                    ),
                );
                Affine::from_mat4(&m)
            })
            .collect()
    };
    let set_of = |maps: &[Affine]| {
        let instances = (maps.iter().enumerate())
            .map(|(k, &m)| placed((k % 2) as u32, m))
            .collect();
        InstanceSet::new(meshes.clone(), instances).unwrap()
    };
    let (first, second) = (maps(0.3), maps(1.1));
    let moved_set = set_of(&second);
    let rays = random_rays(&mut rng, 3000, &moved_set.flatten().unwrap());
    for device in [cpu_device(), gpu_device()] {
        for memory in [
            lancer::gpu::BvhMemory::Buffers,
            lancer::gpu::BvhMemory::Textures,
        ] {
            let options = TracerOptions {
                stats: true,
                memory,
                ..TracerOptions::default()
            };
            let mut tracer = Tracer::with_instances(device, &set_of(&first), &options).unwrap();
            let before = tracer.trace(&rays, Query::Closest).unwrap().hits;
            // Refused: too few maps, a singular map. The tracer is unchanged.
            assert!(tracer.set_transforms(&second[1..]).is_err());
            let mut singular = second.clone();
            singular[5] = Affine {
                rows: [[0.0; 4]; 3],
            };
            assert!(tracer.set_transforms(&singular).is_err());
            let again = tracer.trace(&rays, Query::Closest).unwrap().hits;
            assert!(before.iter().zip(&again).all(|(a, b)| bits(a) == bits(b)));
            tracer.set_transforms(&second).unwrap();
            let mut fresh = Tracer::with_instances(device, &moved_set, &options).unwrap();
            for query in [Query::Closest, Query::Any] {
                let got = tracer.trace(&rays, query).unwrap();
                let want = fresh.trace(&rays, query).unwrap();
                assert!(
                    got.hits
                        .iter()
                        .zip(&want.hits)
                        .all(|(a, b)| bits(a) == bits(b)),
                    "{device} {memory:?} {query:?}"
                );
                assert_eq!(got.stats, want.stats, "{device} {memory:?} {query:?}");
            }
            let hits = tracer.trace(&rays, Query::Closest).unwrap().hits;
            let moved = hits
                .iter()
                .zip(&before)
                .filter(|(a, b)| a.prim != b.prim)
                .count();
            assert!(moved * 2 > rays.len(), "only {moved} rays see the move");
        }
    }
    // A tracer not over instances has nothing to move.
    let mut one = Tracer::new(
        cpu_device(),
        &moved_set.flatten().unwrap(),
        &TracerOptions::default(),
    )
    .unwrap();
    assert!(one.set_transforms(&second).is_err());
}

/// Objects that move (`move`, `spin` in a scene file) render frame by frame: frame f of a
/// renderer handed the two levels of frame 0 (only the top level built again) is the image
/// of the scene moved to frame f and rendered from scratch, bit for bit, on the CPU and the
/// GPU; frame 0 is the scene as placed; and the frames differ (things move).
#[test]
fn moving_objects_render_each_frame_as_a_render_from_scratch() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string("scenes/copies.toml").unwrap();
    let moving = src.replacen(
        "grid = { count = [8, 1, 8], step = [1.0, 0.0, 1.0] }",
        "grid = { count = [8, 1, 8], step = [1.0, 0.0, 1.0] }\nmove = [0.05, 0.02, 0.0]\nspin = [0.0, 0.0, 25.0]",
        1,
    );
    assert_ne!(moving, src);
    let path = dir.path().join("moving.toml");
    std::fs::write(&path, moving).unwrap();
    let mut scene = lancer::RenderScene::from_file(&path).unwrap();
    scene.camera.width = 40;
    scene.camera.height = 30;
    assert!(scene.moves());
    let still = lancer::RenderScene::from_file(std::path::Path::new("scenes/copies.toml")).unwrap();
    assert!(!still.moves());
    let maps = |s: &lancer::RenderScene| {
        let set = s.placements.as_ref().unwrap().set();
        set.instances.iter().map(|i| i.to_world).collect::<Vec<_>>()
    };
    assert_eq!(maps(&scene.at_frame(0).unwrap()), maps(&scene));
    let opts = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    for device in [cpu_device(), gpu_device()] {
        let first = lancer::render::Renderer::new(&scene, device, &opts).unwrap();
        let two = first.two_level().expect("two levels");
        // One renderer moved from frame to frame (only the top level's words, the
        // placements and the emitters written over what was uploaded).
        let mut mover = lancer::render::Renderer::new(&scene, device, &opts).unwrap();
        mover.render(&opts).unwrap();
        let mut images = Vec::new();
        for frame in [2u32, 5] {
            let moved = scene.at_frame(frame).unwrap();
            let reuse = RenderOptions {
                two_level: Some(two.clone()),
                ..opts.clone()
            };
            let mut next = lancer::render::Renderer::new(&moved, device, &reuse).unwrap();
            let got = next.render(&reuse).unwrap().image.pixels;
            let fresh = lancer::render::render(&moved, device, &opts)
                .unwrap()
                .image
                .pixels;
            let differ = got.iter().zip(&fresh).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{device} frame {frame}");
            assert!(mover.can_move_to(&moved));
            mover.move_to(moved, &opts).unwrap();
            let kept = mover.render(&opts).unwrap().image.pixels;
            let differ = kept.iter().zip(&fresh).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{device} frame {frame}, the renderer moved");
            images.push(got);
        }
        // Another scene's placements are refused, the renderer kept.
        assert!(!mover.can_move_to(&still));
        // The fixed offset (a share of the scene's diagonal, which moves) moves too.
        let fixed = RenderOptions {
            robustness: lancer::Robustness {
                ray_offset: lancer::geometry::RayOffset::Fixed,
                ..Default::default()
            },
            ..opts.clone()
        };
        let mut mover = lancer::render::Renderer::new(&scene, device, &fixed).unwrap();
        let moved = scene.at_frame(40).unwrap();
        let fresh = lancer::render::render(&moved, device, &fixed).unwrap();
        assert_ne!(moved.fixed_offset(), scene.fixed_offset());
        mover.move_to(moved, &fixed).unwrap();
        let kept = mover.render(&fixed).unwrap().image.pixels;
        assert!(
            kept == fresh.image.pixels,
            "{device}: fixed offset, the renderer moved"
        );
        let moved = images[0]
            .iter()
            .zip(&images[1])
            .filter(|(a, b)| a != b)
            .count();
        assert!(
            moved * 20 > images[0].len(),
            "{device}: only {moved} pixels change"
        );
    }
}

/// `Tracer::refit_mesh` deforms one mesh of a tracer over instances: its BVH is refit and
/// flattened again, and on a GPU only that mesh's words and the top level's are written
/// over the uploaded arrays (both memories). The tracer then answers as one built over the
/// deformed mesh, bit for bit (closest and any hit). Refused without the trees, for another
/// triangle count, and for a mesh out of range.
#[test]
fn refitting_a_mesh_traces_as_a_tracer_built_over_it() {
    let mut rng = Rng::new(5150);
    let a = soup(&mut rng, 300, 0.2);
    let b = soup(&mut rng, 120, 0.3);
    let mut deformed = a.clone();
    for t in &mut deformed.triangles {
        t.v =
            t.v.map(|p| p + Vec3::new(0.3 * (3.0 * p.y).sin(), 0.1 * p.x, 0.0));
    }
    let maps: Vec<Affine> = (0..60)
        .map(|k| {
            let m = Mat4::from_rotation_translation(
                Quat::from_rotation_y(0.4 * k as f32),
                Vec3::new((k % 8) as f32 * 2.5, 0.0, (k / 8) as f32 * 2.5),
            );
            Affine::from_mat4(&m)
        })
        .collect();
    let set_of = |first: Mesh| {
        let instances = (maps.iter().enumerate())
            .map(|(k, &m)| placed((k % 3 == 0) as u32, m))
            .collect();
        InstanceSet::new(vec![Arc::new(first), Arc::new(b.clone())], instances).unwrap()
    };
    let moved_set = set_of(deformed.clone());
    let rays = random_rays(&mut rng, 3000, &moved_set.flatten().unwrap());
    for device in [cpu_device(), gpu_device()] {
        for memory in [
            lancer::gpu::BvhMemory::Buffers,
            lancer::gpu::BvhMemory::Textures,
        ] {
            let options = TracerOptions {
                memory,
                refit: true,
                ..TracerOptions::default()
            };
            let mut tracer = Tracer::with_instances(device, &set_of(a.clone()), &options).unwrap();
            let before = tracer.trace(&rays, Query::Closest).unwrap().hits;
            assert!(tracer.refit_mesh(2, &deformed).is_err());
            assert!(tracer.refit_mesh(0, &b).is_err());
            tracer.refit_mesh(0, &deformed).unwrap();
            let mut fresh = Tracer::with_instances(device, &moved_set, &options).unwrap();
            for query in [Query::Closest, Query::Any] {
                let got = tracer.trace(&rays, query).unwrap().hits;
                let want = fresh.trace(&rays, query).unwrap().hits;
                let differ = (got.iter().zip(&want))
                    .filter(|(x, y)| match query {
                        Query::Closest => bits(x) != bits(y),
                        Query::Any => x.is_hit() != y.is_hit(),
                    })
                    .count();
                assert_eq!(differ, 0, "{device} {memory:?} {query:?}");
            }
            let after = tracer.trace(&rays, Query::Closest).unwrap().hits;
            let changed = after
                .iter()
                .zip(&before)
                .filter(|(x, y)| bits(x) != bits(y))
                .count();
            assert!(
                changed * 10 > rays.len(),
                "only {changed} rays see the deformation"
            );
        }
    }
    // Without the trees, nothing to refit.
    let mut plain =
        Tracer::with_instances(cpu_device(), &set_of(a.clone()), &TracerOptions::default())
            .unwrap();
    assert!(plain.refit_mesh(0, &deformed).is_err());
}

/// A glTF file's first animation moves its meshes frame by frame (frame f at f ÷ fps
/// seconds): a parent's `LINEAR` translation and a child's `STEP` rotation compose as the
/// node tree does, keys hold before the first and after the last, the frame rate can be
/// set; a map that scales to 0 is refused at the frame it happens, naming it. A frame
/// rendered with the two levels of frame 0 handed over equals one rendered from scratch.
#[test]
fn gltf_animations_move_their_meshes_frame_by_frame() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, vanish: bool| {
        let path = dir.path().join(name);
        let doc = common::writers::animated_cube([2.0, 0.0, 0.0], vanish, false);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        path
    };
    let mut scene = lancer::RenderScene::from_mesh(&write("slide.gltf", false), 40, 30).unwrap();
    assert!(scene.moves());
    assert_eq!(scene.animation_frames(), Some(24));
    let corner = Vec3::splat(0.5);
    let placed = |s: &lancer::RenderScene| {
        // The cube, then the ground `render MESH` adds.
        let set = s.placements.as_ref().unwrap().set();
        assert_eq!(set.instances.len(), 2);
        set.instances[0].to_world.point(corner)
    };
    assert_eq!(placed(&scene), corner, "at rest");
    // A quarter turn about +Y takes (x, y, z) to (z, y, −x).
    let turned = Vec3::new(2.5, 0.5, -0.5);
    for (frame, want) in [
        (0, corner),
        (12, corner + Vec3::X),
        (23, corner + Vec3::X * (2.0 * 23.0 / 24.0)),
        (24, turned),
        (100, turned),
    ] {
        let got = placed(&scene.at_frame(frame).unwrap());
        assert!(
            (got - want).abs().max_element() < 1e-5,
            "frame {frame}: {got} against {want}"
        );
    }
    scene.set_frame_rate(12.0).unwrap();
    assert_eq!(scene.animation_frames(), Some(12));
    assert!((placed(&scene.at_frame(12).unwrap()) - turned).length() < 1e-5);
    assert!(scene.set_frame_rate(0.0).is_err() && scene.set_frame_rate(f32::NAN).is_err());

    let opts = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    let moved = scene.at_frame(6).unwrap();
    for device in [cpu_device(), gpu_device()] {
        let first = lancer::render::Renderer::new(&scene, device, &opts).unwrap();
        let reuse = RenderOptions {
            two_level: Some(first.two_level().expect("two levels")),
            ..opts.clone()
        };
        let mut next = lancer::render::Renderer::new(&moved, device, &reuse).unwrap();
        let got = next.render(&reuse).unwrap().image.pixels;
        let fresh = lancer::render::render(&moved, device, &opts).unwrap();
        assert!(
            got == fresh.image.pixels,
            "{device}: frame 6 reused ≠ fresh"
        );
        let rest = lancer::render::render(&scene, device, &opts).unwrap();
        assert!(got != rest.image.pixels, "{device}: the cube moved");
    }

    let vanishing = lancer::RenderScene::from_mesh(&write("vanish.gltf", true), 40, 30).unwrap();
    assert!(vanishing.at_frame(12).is_ok(), "half size");
    let err = vanishing.at_frame(24).unwrap_err().to_string();
    assert!(
        err.contains("frame 24") && err.contains("singular"),
        "{err}"
    );

    // Still uses (trace, rays) take a file that is placed only for its animation flattened.
    let slide = dir.path().join("slide.gltf");
    assert!(lancer::render::load_instances(&slide).unwrap().is_none());
    // An animation that cannot be played (its key times read from a VEC3 accessor) leaves
    // the file drawn still.
    let mut doc = common::writers::animated_cube([2.0, 0.0, 0.0], false, false);
    let first_output = doc["animations"][0]["samplers"][0]["output"].clone();
    doc["animations"][0]["samplers"][0]["input"] = first_output;
    let broken = dir.path().join("broken.gltf");
    std::fs::write(&broken, serde_json::to_vec(&doc).unwrap()).unwrap();
    let still = lancer::RenderScene::from_mesh(&broken, 40, 30).unwrap();
    assert!(!still.moves());
}

/// A glTF camera its file's animation moves is the view of each frame (frame f at f ÷ fps
/// seconds); a view given on the command line (`--look-from`, …) holds in every frame; a
/// still camera stays still.
#[test]
fn gltf_animations_move_the_files_camera() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, dolly: bool| {
        let path = dir.path().join(name);
        let doc = common::writers::animated_cube([0.0; 3], false, dolly);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        path
    };
    let dolly = write("dolly.gltf", true);
    let size = lancer::render::ImageSize {
        width: Some(40),
        height: Some(30),
        scale: None,
    };
    let scene = lancer::RenderScene::open(&dolly, &size, &Default::default()).unwrap();
    let eye = |s: &lancer::RenderScene, f: u32| s.at_frame(f).unwrap().camera.eye;
    assert_eq!(scene.camera.eye, Vec3::new(0.0, 0.0, 5.0), "at rest");
    assert_eq!(eye(&scene, 0), Vec3::new(0.0, 0.0, 5.0));
    assert!((eye(&scene, 12) - Vec3::new(0.0, 0.0, 4.0)).length() < 1e-5);
    assert!((eye(&scene, 30) - Vec3::new(0.0, 0.0, 3.0)).length() < 1e-5);
    assert_eq!(scene.at_frame(30).unwrap().camera.width, 40);
    let view = lancer::camera::ViewChange {
        look_from: Some(Vec3::new(1.0, 2.0, 6.0)),
        ..Default::default()
    };
    let held = lancer::RenderScene::open(&dolly, &size, &view).unwrap();
    assert_eq!(
        eye(&held, 30),
        Vec3::new(1.0, 2.0, 6.0),
        "the command line's view holds"
    );
    let still =
        lancer::RenderScene::open(&write("still.gltf", false), &size, &Default::default()).unwrap();
    assert_eq!(eye(&still, 30), Vec3::new(0.0, 0.0, 5.0));
    // A renderer moved to a frame takes that frame's view: as a renderer made for it.
    let opts = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    for device in [cpu_device(), gpu_device()] {
        let mut mover = lancer::render::Renderer::new(&scene, device, &opts).unwrap();
        let rest = mover.render(&opts).unwrap().image.pixels;
        let frame = scene.at_frame(12).unwrap();
        let fresh = lancer::render::render(&frame, device, &opts)
            .unwrap()
            .image
            .pixels;
        mover.move_to(frame, &opts).unwrap();
        let got = mover.render(&opts).unwrap().image.pixels;
        assert!(got == fresh && got != rest, "{device}");
    }
}
