//! Embree 3 (`lancer::embree`, the `embree` feature) against lancer's CPU twin, judged by the
//! f64 oracle: Embree's closest hits name the twin's triangle at a t the oracle accepts, or a
//! genuine tie; where Embree's occlusion answer differs from the twin's, the oracle finds
//! only marginal occluders (edge or interval-end hits either answer may take). Embree's own
//! instances against lancer's two levels: the same triangles, numbered alike, for nearly
//! every ray (each moves rays into object space with its own rounding); and `bench
//! instances` gains Embree's rows.

#![cfg(feature = "embree")]

mod common;

use std::sync::Arc;

use common::{load_model, random_rays, soup, Rng};
use glam::{Mat4, Quat, Vec3};
use lancer::accel::bvh::BuildOptions;
use lancer::accel::instances::{Affine, Instance, InstanceSet, TwoLevel};
use lancer::accel::{Accel, AccelKind};
use lancer::bench::{self, BenchReport};
use lancer::camera::Camera;
use lancer::embree::{EmbreeInstances, EmbreeTracer};
use lancer::geometry::{Hit, Ray, Triangle, MISS};
use lancer::mesh::Mesh;
use lancer::trace::compare::compare_hits_independent;
use lancer::trace::files::{bounce_rays, default_light, shadow_rays};
use lancer::trace::oracle::{judge_any, Verdict};
use lancer::{Device, DeviceChoice, LayoutKind, Query, Robustness, Tracer, TracerOptions};

fn twin_hits(mesh: &Mesh, rays: &[Ray], query: Query) -> Vec<Hit> {
    let cpu = Device::cpu();
    let mut t = Tracer::new(&cpu, mesh, &TracerOptions::default()).unwrap();
    t.trace(rays, query).unwrap().hits
}

/// Embree's closest hits agree with the twin's or are genuine ties the oracle names.
fn check_closest(name: &str, mesh: &Mesh, embree: &EmbreeTracer, rays: &[Ray]) {
    let got = embree.closest(rays);
    assert_eq!(got.len(), rays.len());
    let reference = twin_hits(mesh, rays, Query::Closest);
    let cmp = compare_hits_independent(mesh, rays, Query::Closest, &reference, &got);
    let hits = got.iter().filter(|h| h.is_hit()).count();
    println!(
        "{name} closest: {} rays, {hits} hits; {} agree ({} identical), {} ties, {} disagree",
        rays.len(),
        cmp.agree,
        cmp.identical,
        cmp.ties,
        cmp.disagree.len()
    );
    assert!(
        cmp.disagree.is_empty(),
        "{name}: {} disagree; first: {:?}",
        cmp.disagree.len(),
        cmp.disagree[0]
    );
    // Not vacuous: rays hit, and nearly all name the twin's triangle.
    assert!(hits > 0, "{name}: no hits");
    assert!(cmp.agree * 100 >= rays.len() * 99, "{name}: too few agree");
}

/// Embree's occlusion answers agree with the twin's any-hit answers; where they differ, both
/// are right only if every occluder the oracle finds is marginal.
fn check_occluded(name: &str, mesh: &Mesh, embree: &EmbreeTracer, rays: &[Ray]) {
    let got = embree.occluded(rays);
    assert_eq!(got.len(), rays.len());
    let reference = twin_hits(mesh, rays, Query::Any);
    let mut differ = 0;
    for (i, ((r, &blocked), h)) in rays.iter().zip(&got).zip(&reference).enumerate() {
        if blocked == h.is_hit() {
            continue;
        }
        differ += 1;
        let verdict = judge_any(mesh, r, &Hit::miss(r.tmax));
        assert!(
            matches!(verdict, Verdict::Tie(_)),
            "{name} ray {i}: Embree says blocked={blocked}, the twin {h:?}; oracle: {verdict:?}"
        );
    }
    let blocked = got.iter().filter(|&&b| b).count();
    println!(
        "{name} occluded: {} rays, {blocked} blocked; {differ} differ from the twin (ties)",
        rays.len()
    );
    assert!(blocked > 0, "{name}: nothing blocked");
    assert!(
        blocked < rays.len(),
        "{name}: everything blocked, a test that cannot tell"
    );
}

#[test]
fn embree_agrees_with_the_cpu_twin_on_the_bunny() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let embree = EmbreeTracer::new(&mesh, 2).unwrap();
    assert!(embree.version().starts_with("3."), "{}", embree.version());
    let primary = Camera::default_view(&mesh.bounds(), 96, 96).primary_rays();
    let hits = twin_hits(&mesh, &primary, Query::Closest);
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    let bounce = bounce_rays(&mesh, &primary, &hits, 1);
    let random = random_rays(&mut Rng::new(13), 8000, &mesh);
    check_closest("bunny primary", &mesh, &embree, &primary);
    check_occluded("bunny shadow", &mesh, &embree, &shadow);
    check_closest("bunny bounce", &mesh, &embree, &bounce);
    check_closest("bunny random", &mesh, &embree, &random);
    check_occluded("bunny random", &mesh, &embree, &random);
}

#[test]
fn excluded_triangles_keep_the_original_indices() {
    // Triangles the BVH leaves out (NaN, zero area) come first, so Embree's primitive IDs
    // are shifted from lancer's indices and only the map gives the right ones.
    let mut rng = Rng::new(21);
    let soup = soup(&mut rng, 2000, 0.2);
    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    let mut tris = vec![
        Triangle::new(nan, Vec3::ZERO, Vec3::X),
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0),
    ];
    tris.extend(soup.triangles.iter().copied());
    let mesh = Mesh::from_triangles(tris);
    assert_eq!(mesh.included().len(), mesh.len() - 2);
    let embree = EmbreeTracer::new(&mesh, 2).unwrap();
    let rays = random_rays(&mut rng, 20_000, &mesh);
    check_closest("soup", &mesh, &embree, &rays);
    check_occluded("soup", &mesh, &embree, &rays);
}

#[test]
fn invalid_rays_and_an_empty_mesh_are_misses() {
    let mesh = soup(&mut Rng::new(9), 100, 0.3);
    let embree = EmbreeTracer::new(&mesh, 2).unwrap();
    let c = mesh.bounds().center();
    let o = c - Vec3::Z * 10.0;
    let bad = [
        Ray::new(o, Vec3::new(f32::NAN, 0.0, 1.0), 0.0, 1e30),
        Ray::new(o, Vec3::ZERO, 0.0, 1e30),
        Ray::new(Vec3::splat(f32::INFINITY), Vec3::Z, 0.0, 1e30),
        Ray::new(o, Vec3::Z, 5.0, 1.0),
    ];
    let got = embree.closest(&bad);
    assert!(got.iter().all(|h| h.prim == MISS), "{got:?}");
    assert!(embree.occluded(&bad).iter().all(|&b| !b));
    let empty = EmbreeTracer::new(&Mesh::from_triangles(Vec::new()), 2).unwrap();
    let ray = [Ray::new(o, Vec3::Z, 0.0, 1e30)];
    assert_eq!(empty.closest(&ray)[0].prim, MISS);
    assert!(!empty.occluded(&ray)[0]);
}

/// A map scaling by `scale`, turning by `angle` about `axis`, then moving by `at`.
fn placed(mesh: u32, axis: Vec3, angle: f32, scale: f32, at: Vec3) -> Instance {
    let m = Mat4::from_scale_rotation_translation(
        Vec3::splat(scale),
        Quat::from_axis_angle(axis.normalize(), angle),
        at,
    );
    Instance {
        mesh,
        to_world: Affine::from_mat4(&m),
    }
}

/// Two soups (the first led by two triangles the BVH leaves out, so Embree's primitive IDs
/// are shifted from lancer's indices), placed four times, turned, scaled and moved so that
/// the copies overlap: closest hits cross instances.
fn four_copies(rng: &mut Rng) -> InstanceSet {
    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    let mut tris = vec![
        Triangle::new(nan, Vec3::ZERO, Vec3::X),
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0),
    ];
    tris.extend(soup(rng, 1500, 0.25).triangles);
    let meshes = vec![
        Arc::new(Mesh::from_triangles(tris)),
        Arc::new(soup(rng, 600, 0.3)),
    ];
    let instances = vec![
        placed(0, Vec3::Y, 0.7, 1.0, Vec3::ZERO),
        placed(
            1,
            Vec3::new(1.0, 1.0, 0.0),
            1.9,
            0.8,
            Vec3::new(1.5, 0.0, 0.5),
        ),
        placed(0, Vec3::X, -0.4, 1.3, Vec3::new(0.0, 1.5, 1.0)),
        placed(
            1,
            Vec3::new(0.2, -1.0, 0.5),
            2.8,
            1.0,
            Vec3::new(1.0, 1.0, -1.0),
        ),
    ];
    InstanceSet::new(meshes, instances).unwrap()
}

/// Embree's instanced closest hits name lancer's two-level triangle for ≥ 99 % of `rays`
/// (at nearly the same t), and its occlusion answers equal the two levels' any-hit answers
/// for ≥ 99 %.
fn check_instances(name: &str, two: &TwoLevel, embree: &EmbreeInstances, rays: &[Ray]) {
    let rob = Robustness::default();
    let expected = two.trace_hits(rays, Query::Closest, &rob);
    let got = embree.closest(rays);
    assert_eq!(got.len(), rays.len());
    let same = (expected.iter().zip(&got))
        .filter(|(e, g)| e.prim == g.prim)
        .count();
    for (i, (e, g)) in expected.iter().zip(&got).enumerate() {
        if e.is_hit() && e.prim == g.prim {
            let tol = 1e-4 * e.t.abs().max(1.0);
            assert!((e.t - g.t).abs() <= tol, "{name} ray {i}: {e:?} vs {g:?}");
        }
    }
    let hits = got.iter().filter(|h| h.is_hit()).count();
    println!(
        "{name} closest: {} rays, {hits} hits; {same} name the two levels' triangle",
        rays.len()
    );
    assert!(hits > 0, "{name}: no hits");
    assert!(same * 100 >= rays.len() * 99, "{name}: only {same} agree");

    let expected = two.trace_hits(rays, Query::Any, &rob);
    let got = embree.occluded(rays);
    assert_eq!(got.len(), rays.len());
    let equal = (expected.iter().zip(&got))
        .filter(|(e, &g)| e.is_hit() == g)
        .count();
    let blocked = got.iter().filter(|&&b| b).count();
    println!(
        "{name} occluded: {} rays, {blocked} blocked; {equal} equal the two levels' answer",
        rays.len()
    );
    assert!(
        blocked > 0 && blocked < rays.len(),
        "{name}: {blocked} blocked"
    );
    assert!(equal * 100 >= rays.len() * 99, "{name}: only {equal} equal");
}

#[test]
fn embree_instances_agree_with_the_two_levels() {
    let mut rng = Rng::new(37);
    let set = four_copies(&mut rng);
    let flat = set.flatten().expect("the set flattens");
    let kind = AccelKind::Bvh(LayoutKind::DfsSign);
    let two = TwoLevel::build(kind, &set, &BuildOptions::default()).unwrap();
    let embree = EmbreeInstances::new(&set, 2).unwrap();
    assert!(embree.version().starts_with("3."), "{}", embree.version());
    assert!(embree.build_ms() >= 0.0);
    let primary = Camera::default_view(&flat.bounds(), 96, 96).primary_rays();
    let hits = two.trace_hits(&primary, Query::Closest, &Robustness::default());
    let shadow = shadow_rays(&primary, &hits, default_light(&flat.bounds()));
    let random = random_rays(&mut rng, 20_000, &flat);
    check_instances("instances primary", &two, &embree, &primary);
    check_instances("instances shadow", &two, &embree, &shadow);
    check_instances("instances random", &two, &embree, &random);
    // Every instance is hit, each numbered in its own range.
    let got = embree.closest(&random);
    let firsts = set.first_prims();
    for (i, &first) in firsts.iter().enumerate() {
        let end = firsts.get(i + 1).copied().unwrap_or(flat.len() as u32);
        assert!(
            got.iter().any(|h| (first..end).contains(&h.prim)),
            "instance {i} never hit"
        );
    }
}

#[test]
fn embree_instances_refuse_bad_sets_and_miss_without_instances() {
    let mesh = Arc::new(soup(&mut Rng::new(5), 50, 0.3));
    let bad = InstanceSet {
        meshes: vec![mesh.clone()],
        instances: vec![placed(1, Vec3::Y, 0.0, 1.0, Vec3::ZERO)],
    };
    assert!(EmbreeInstances::new(&bad, 2).is_err());
    let singular = InstanceSet {
        meshes: vec![mesh.clone()],
        instances: vec![placed(0, Vec3::Y, 0.0, 0.0, Vec3::ZERO)],
    };
    assert!(EmbreeInstances::new(&singular, 2).is_err());
    let ray = [Ray::new(Vec3::new(0.0, 0.0, -10.0), Vec3::Z, 0.0, 1e30)];
    let none = EmbreeInstances::new(&InstanceSet::new(vec![mesh], Vec::new()).unwrap(), 2).unwrap();
    assert_eq!(none.closest(&ray)[0].prim, MISS);
    assert!(!none.occluded(&ray)[0]);
    // A mesh with no usable triangle is placed by no instance, and the numbering goes on.
    let empty = Arc::new(Mesh::from_triangles(vec![Triangle::new(
        Vec3::ZERO,
        Vec3::X,
        Vec3::X * 2.0,
    )]));
    let one = Arc::new(Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    )]));
    let set = InstanceSet::new(
        vec![empty, one],
        vec![
            placed(0, Vec3::Y, 0.0, 1.0, Vec3::ZERO),
            placed(1, Vec3::Y, 0.0, 1.0, Vec3::ZERO),
        ],
    )
    .unwrap();
    let embree = EmbreeInstances::new(&set, 2).unwrap();
    let h = embree.closest(&ray)[0];
    assert_eq!(h.prim, 1, "{h:?}");
    assert!((h.t - 10.0).abs() < 1e-5, "{h:?}");
    assert!(embree.occluded(&ray)[0]);
}

#[test]
fn bench_instances_gains_the_embree_rows() {
    let config = bench::instances::Config {
        mesh: soup(&mut Rng::new(11), 300, 0.3),
        name: "soup".into(),
        copies: 4,
        width: 16,
        height: 12,
        device: DeviceChoice::Cpu,
        bvh_memory: Default::default(),
        layout: Some(LayoutKind::DfsSign),
        repeat: 1,
        build: Default::default(),
    };
    let report = bench::instances::run(&config, &|_| {}).unwrap();
    let e = report.embree.as_ref().expect("Embree's rows");
    assert!(e.version.starts_with("3."), "{}", e.version);
    let builds: Vec<&str> = e.builds.iter().map(|b| b.variant).collect();
    assert_eq!(builds, ["instanced", "flattened"]);
    assert!(e.builds.iter().all(|b| b.build_ms >= 0.0));
    assert_eq!(e.runs.len(), 4);
    for (r, lancer) in e.runs.iter().zip(&report.runs) {
        assert_eq!(
            (r.variant, r.rays, r.count),
            (lancer.variant, lancer.rays, lancer.count)
        );
        assert!(r.cpu_mrays_per_s > 0.0, "{r:?}");
    }
    for rays in ["primary", "shadow"] {
        assert!(report.embree_cost_ratio(rays).is_some_and(|r| r > 0.0));
    }
    let j = serde_json::to_value(&report).unwrap();
    assert_eq!(j["embree"]["runs"][0]["variant"], "instanced");
    assert_eq!(report.runs.len(), 4, "lancer's rows unchanged");
    let text = report.text();
    assert!(
        text.contains("embree instanced")
            && text.contains("embree flattened")
            && text.contains("Embree instanced ÷ flattened")
            && text.contains("embree rows: Embree 3."),
        "{text}"
    );
}
