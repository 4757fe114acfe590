//! One conformance suite over every acceleration structure in the registry
//! ([`AccelKind::ALL`]: the BVH, the kd-tree, the three grids, the BIH, the octree), each
//! built with its defaults through `accel::build`: every answer agrees with the f64 oracle
//! or is a genuine tie it names, equals the BVH's and a brute-force pass's (the tracers' own
//! f32 test and tie rule) bit for bit; rays through shared edges and vertices never leak;
//! coincident triangles keep the tie rule; invalid rays miss without work and extreme rays
//! neither hang nor panic. A structure added to the registry runs here with no new test.
//! Each structure's own options and invariants (split planes, depth caps, memory caps,
//! statistics) stay in its own file: tests/{kdtree,bih,octree,grids}.rs.

mod common;

use common::accel_check::{
    brute_force, check, check_against, same_as_bvh, smallest_index_at_nearest_t,
};
use common::hard::{coincident_stacks, edge_rays, extreme_rays, grid, invalid_rays, stack_rays};
use common::{load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::{BuildOptions, Builder};
use lancer::accel::{build, Accel, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::{Ray, Triangle, TriangleTest};
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, Truths};
use lancer::{Query, RayStats, Robustness};

/// Every structure of the registry over `mesh`, with its default options, and the BVH once
/// more with spatial splits (leaves holding parts of triangles, a triangle in several).
fn every_structure(mesh: &Mesh) -> Vec<(String, Box<dyn Accel>)> {
    let sbvh = BuildOptions {
        builder: Builder::Sbvh,
        ..BuildOptions::default()
    };
    let variants = (AccelKind::ALL.iter())
        .map(|&kind| (kind.to_string(), kind, BuildOptions::default()))
        .chain([("bvh (sbvh)".to_string(), AccelKind::ALL[0], sbvh)]);
    variants
        .map(|(name, kind, opts)| {
            let accel =
                build(kind, mesh, &opts).unwrap_or_else(|e| panic!("{name} does not build: {e}"));
            (name, accel)
        })
        .collect()
}

/// The registry holds every structure the book names, so the suite below runs them all.
#[test]
fn the_registry_holds_every_structure() {
    let names: Vec<String> = AccelKind::ALL.iter().map(|k| k.to_string()).collect();
    assert_eq!(AccelKind::ALL.len(), 7, "{names:?}");
}

#[test]
fn random_soups_against_the_oracle_the_bvh_and_brute_force() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 3000, &mesh);
        let brute = brute_force(&mesh, &rays);
        let truths = Truths::new(&mesh, &rays);
        for (kind, accel) in every_structure(&mesh) {
            let name = format!("{kind}, soup {seed}");
            let (agree, _) = check_against(&name, &truths, accel.as_ref());
            assert!(agree > 2500, "{name}: {agree} agree");
            assert_eq!(
                same_as_bvh(&name, &mesh, accel.as_ref(), &rays),
                0,
                "{name}"
            );
            let (hits, _) = accel.trace_batch(&rays, Query::Closest, &Robustness::default());
            assert!(hits == brute, "{name}: not the brute force's hits");
        }
    }
}

#[test]
fn models_primary_and_random_rays() {
    // The oracle and the brute force test every triangle per ray: fewer rays on the bunny
    // (69,451 triangles) than on the teapot; the BVH comparison takes many more.
    for (model, judged, side) in [("teapot.obj", 600, 24), ("stanford-bunny.obj", 150, 16)] {
        let Some(mesh) = load_model(model) else {
            return;
        };
        let mut rng = Rng::new(7);
        let random = random_rays(&mut rng, 3000, &mesh);
        let primary = Camera::default_view(&mesh.bounds(), 64, 64).primary_rays();
        let some: Vec<Ray> = (primary.iter().step_by(9).copied())
            .take(2 * judged)
            .collect();
        let brute = brute_force(&mesh, &some);
        let small = Camera::default_view(&mesh.bounds(), side, side).primary_rays();
        let (random_truths, small_truths) = (
            Truths::new(&mesh, &random[..judged]),
            Truths::new(&mesh, &small),
        );
        for (kind, accel) in every_structure(&mesh) {
            let accel = accel.as_ref();
            let name = format!("{kind}, {model}");
            check_against(&format!("{name} random"), &random_truths, accel);
            assert_eq!(same_as_bvh(&name, &mesh, accel, &random), 0, "{name}");
            let (agree, _) = check_against(&format!("{name} primary"), &small_truths, accel);
            assert!(agree > (side * side / 2) as usize, "{name}: {agree} agree");
            assert_eq!(same_as_bvh(&name, &mesh, accel, &primary), 0, "{name}");
            let (hits, _) = accel.trace_batch(&some, Query::Closest, &Robustness::default());
            assert!(hits == brute, "{name}: not the brute force's hits");
        }
    }
}

#[test]
fn rays_at_shared_edges_and_vertices_never_leak() {
    let (mesh, targets) = grid(24, 0.37);
    let mut rng = Rng::new(11);
    let c = mesh.bounds().center();
    let rays = edge_rays(&mut rng, c, &targets);
    let brute = brute_force(&mesh, &rays);
    let truths = Truths::new(&mesh, &rays);
    let rob = Robustness::default();
    for (kind, accel) in every_structure(&mesh) {
        for query in [Query::Closest, Query::Any] {
            let (hits, _) = accel.trace_batch(&rays, query, &rob);
            let leaks = hits.iter().filter(|h| !h.is_hit()).count();
            assert_eq!(
                leaks, 0,
                "{kind} {query:?}: rays through shared edges leaked"
            );
        }
        check_against(&format!("{kind} grid edges"), &truths, accel.as_ref());
        // Where two triangles meet at the ray, equal t goes to the smaller index even when
        // the two sit in different leaves or cells.
        let (hits, _) = accel.trace_batch(&rays, Query::Closest, &rob);
        assert!(
            hits == brute,
            "{kind}: not the brute force's hits on the grid"
        );
    }
}

#[test]
fn coincident_triangles_keep_the_tie_rule() {
    // k copies of one triangle at several depths, indices interleaved between the stacks,
    // among random triangles: the answer must be the smallest index at the nearest t.
    let mut rng = Rng::new(31);
    let mesh = coincident_stacks(&mut rng);
    let rays = stack_rays(&mut rng, 2000);
    let brute = brute_force(&mesh, &rays);
    let truths = oracle::Truths::new(&mesh, &rays);
    for (kind, accel) in every_structure(&mesh) {
        let (hits, _) = accel.trace_batch(&rays, Query::Closest, &Robustness::default());
        let exact = smallest_index_at_nearest_t(&kind.to_string(), &truths, &hits);
        assert!(exact > 1800, "{kind}: {exact} exact");
        assert!(hits == brute, "{kind}: not the brute force's hits");
    }
}

#[test]
fn invalid_rays_miss_without_work_and_extreme_rays_neither_hang_nor_panic() {
    let mut rng = Rng::new(41);
    let mesh = soup(&mut rng, 500, 0.3);
    let rob = Robustness::default();
    let invalid = invalid_rays();
    let extreme = extreme_rays(&mut rng, 3000);
    let brute = brute_force(&mesh, &extreme);
    for (kind, accel) in every_structure(&mesh) {
        for r in &invalid {
            for query in [Query::Closest, Query::Any] {
                let mut s = RayStats::default();
                let h = accel.intersect(r, query, &rob, &mut s);
                assert!(!h.is_hit(), "{kind}: {r:?} hit");
                assert_eq!(s, RayStats::default(), "{kind}: work on {r:?}");
            }
        }
        check(
            &format!("{kind} extreme rays"),
            &mesh,
            accel.as_ref(),
            &extreme,
        );
        let (hits, _) = accel.trace_batch(&extreme, Query::Closest, &rob);
        assert!(
            hits == brute,
            "{kind}: not the brute force's hits on extreme rays"
        );
        let mt = Robustness {
            triangle_test: TriangleTest::MollerTrumbore,
            ..rob
        };
        let _ = accel.trace_batch(&extreme, Query::Closest, &mt);
    }
}

#[test]
fn empty_meshes_miss_and_one_triangle_is_hit() {
    let r = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, 3.4e38);
    // No triangle, and only a degenerate one (kept out of every structure).
    for mesh in [
        Mesh::default(),
        Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X)]),
    ] {
        for (kind, accel) in every_structure(&mesh) {
            assert!(accel.bounds().is_empty(), "{kind}");
            let mut s = RayStats::default();
            let h = accel.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
            assert!(!h.is_hit(), "{kind}");
        }
    }
    let one = Mesh::from_triangles(vec![Triangle::new(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )]);
    let r = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 1.0);
    for (kind, accel) in every_structure(&one) {
        let mut s = RayStats::default();
        let h = accel.intersect(&r, Query::Closest, &Robustness::default(), &mut s);
        assert_eq!((h.prim, h.t), (0, 1.0), "{kind}");
        let h = accel.intersect(&r, Query::Any, &Robustness::default(), &mut s);
        assert_eq!(h.prim, 0, "{kind}");
    }
}
