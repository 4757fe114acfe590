//! Embree 3 (`lancer::embree`, the `embree` feature) against lancer's CPU twin, judged by the
//! f64 oracle: Embree's closest hits name the twin's triangle at a t the oracle accepts, or a
//! genuine tie; where Embree's occlusion answer differs from the twin's, the oracle finds
//! only marginal occluders (edge or interval-end hits either answer may take).

#![cfg(feature = "embree")]

mod common;

use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::camera::Camera;
use lancer::embree::EmbreeTracer;
use lancer::geometry::{Hit, Ray, Triangle, MISS};
use lancer::mesh::Mesh;
use lancer::trace::compare::compare_hits_independent;
use lancer::trace::files::{bounce_rays, default_light, shadow_rays};
use lancer::trace::oracle::{judge_any, Verdict};
use lancer::{Device, Query, Tracer, TracerOptions};

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
