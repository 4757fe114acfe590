//! The CPU reference tracer against the f64 oracle: every answer agrees, or is a genuine
//! tie the oracle can name (a ray within a tiny distance of an edge, equal t).

mod common;

use common::accel_check::judge_hits;
use common::{load_model, random_rays, soup, Rng};
use lancer::accel::bvh::{BuildOptions, Builder};
use lancer::accel::{build, AccelKind};
use lancer::camera::Camera;
use lancer::geometry::Ray;
use lancer::mesh::Mesh;
use lancer::trace::oracle::{judge, Truths, Verdict};
use lancer::{LayoutKind, Query, Robustness};

/// Traces `rays` through every layout's CPU twin and every other structure, judges every
/// answer (the oracle searched once for all of them), prints the counts and fails on any
/// wrong one. Returns the counts of the BVH in its default layout.
fn check(name: &str, mesh: &Mesh, rays: &[Ray], builder: Builder) -> (usize, usize) {
    let truths = Truths::new(mesh, rays);
    let mut kinds: Vec<AccelKind> = LayoutKind::ALL.iter().map(|&l| AccelKind::Bvh(l)).collect();
    kinds.extend(
        AccelKind::ALL
            .iter()
            .filter(|k| !matches!(k, AccelKind::Bvh(_))),
    );
    let counts: Vec<(usize, usize)> = kinds
        .iter()
        .map(|&kind| check_accel(name, mesh, rays, &truths, builder, kind))
        .collect();
    counts[0]
}

fn check_accel(
    name: &str,
    mesh: &Mesh,
    rays: &[Ray],
    truths: &Truths,
    builder: Builder,
    kind: AccelKind,
) -> (usize, usize) {
    let opts = BuildOptions {
        builder,
        ..BuildOptions::default()
    };
    let accel = build(kind, mesh, &opts).unwrap();
    let (hits, _) = accel.trace_batch(rays, Query::Closest, &Robustness::default());
    let name = format!("{name} ({builder:?}, {kind})");
    judge_hits(&name, truths, Query::Closest, &hits)
}

#[test]
fn random_soups() {
    for seed in 0..4 {
        let mut rng = Rng::new(100 + seed);
        let mesh = soup(&mut rng, 2000, 0.2);
        let rays = random_rays(&mut rng, 4000, &mesh);
        for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
            let (agree, _) = check(&format!("soup {seed}"), &mesh, &rays, b);
            assert!(agree > 3000);
        }
    }
}

#[test]
fn models_random_and_primary_rays() {
    for name in ["teapot.obj", "stanford-bunny.obj"] {
        let Some(mesh) = load_model(name) else { return };
        let mut rng = Rng::new(5);
        let rays = random_rays(&mut rng, 1500, &mesh);
        check(name, &mesh, &rays, Builder::Sweep);
        let cam = Camera::default_view(&mesh.bounds(), 48, 48);
        let (agree, _) = check(name, &mesh, &cam.primary_rays(), Builder::Sweep);
        assert!(agree > 48 * 48 / 2);
    }
}

#[test]
fn rays_aimed_at_edges_and_vertices() {
    // The hardest rays: through shared vertices and edge midpoints of a real mesh.
    let Some(mesh) = load_model("teapot.obj") else {
        return;
    };
    let mut rng = Rng::new(9);
    let b = mesh.bounds();
    let r = b.extent().length();
    let rays: Vec<Ray> = (0..3000)
        .map(|i| {
            let t = &mesh.triangles[rng.u64() as usize % mesh.len()];
            let target = if i % 2 == 0 {
                t.v[i % 3]
            } else {
                0.5 * (t.v[0] + t.v[1])
            };
            let o = b.center() + rng.dir() * r;
            Ray::new(o, (target - o).normalize(), 0.0, 3.4e38)
        })
        .collect();
    let (_, ties) = check("teapot edges", &mesh, &rays, Builder::Sweep);
    println!("{ties} genuine ties among rays aimed at edges");
}

#[test]
fn the_judge_rejects_wrong_answers() {
    let mut rng = Rng::new(1);
    let mesh = soup(&mut rng, 500, 0.3);
    let rays = random_rays(&mut rng, 500, &mesh);
    let accel = build(
        AccelKind::Bvh(lancer::LayoutKind::DfsSign),
        &mesh,
        &BuildOptions::default(),
    )
    .unwrap();
    let (hits, _) = accel.trace_batch(&rays, Query::Closest, &Robustness::default());
    let (r, h) = rays
        .iter()
        .zip(&hits)
        .find(|(_, h)| h.is_hit())
        .expect("some hit");
    let as_miss = lancer::geometry::Hit::miss(r.tmax);
    assert!(matches!(judge(&mesh, r, &as_miss), Verdict::Wrong(_)));
    let far = lancer::geometry::Hit { t: h.t * 1.5, ..*h };
    assert!(matches!(judge(&mesh, r, &far), Verdict::Wrong(_)));
}

#[test]
fn judging_from_the_searched_truths_is_judging_afresh() {
    // `Truths` searches once and judges many answers; `judge_any` tests a reported hit's own
    // triangle only. Both must say what the whole search says: the same verdicts as `judge`,
    // an any-hit answer agreed with exactly when its triangle is among `all_hits`, and a miss
    // exactly when that list is empty.
    let mut rng = Rng::new(3);
    let mesh = soup(&mut rng, 400, 0.3);
    // Each ray whole, cut short before its first hit, and started past it: hits outside
    // the interval must count for nothing.
    let rays: Vec<Ray> = random_rays(&mut rng, 300, &mesh)
        .into_iter()
        .flat_map(|r| {
            let first = lancer::trace::oracle::closest(&mesh, &r).map_or(1.0, |h| h.0 as f32);
            [
                r,
                Ray::new(r.origin, r.dir, r.tmin, 0.5 * first),
                Ray::new(r.origin, r.dir, 1.01 * first, r.tmax),
            ]
        })
        .collect();
    let truths = Truths::new(&mesh, &rays);
    let (mut hits_judged, mut others_judged) = (0, 0);
    let (mut misses_wrong, mut misses_tied) = (0, 0);
    for (i, r) in rays.iter().enumerate() {
        let all = lancer::trace::oracle::all_hits(&mesh, r);
        let mut answers = vec![lancer::geometry::Hit::miss(r.tmax)];
        answers.extend(all.iter().map(|&(t, prim)| lancer::geometry::Hit {
            t: t as f32,
            prim,
            ..lancer::geometry::Hit::miss(r.tmax)
        }));
        let other = (rng.u64() % mesh.len() as u64) as u32;
        answers.push(lancer::geometry::Hit {
            t: r.tmax * 0.5,
            prim: other,
            ..lancer::geometry::Hit::miss(r.tmax)
        });
        for h in &answers {
            assert_eq!(truths.judge(i, h), judge(&mesh, r, h), "ray {i}: {h:?}");
            let any = lancer::trace::oracle::judge_any(&mesh, r, h);
            if h.is_hit() {
                let real = all.iter().any(|&(_, p)| p == h.prim);
                assert_eq!(any == Verdict::Agree, real, "ray {i}: {h:?}: {any:?}");
                match real {
                    true => hits_judged += 1,
                    false => others_judged += 1,
                }
            } else {
                // A miss is right only where nothing occludes, and a tie only where every
                // occluder is marginal (rare in a random soup).
                assert_eq!(
                    any == Verdict::Agree,
                    all.is_empty(),
                    "ray {i}: miss: {any:?}"
                );
                match any {
                    Verdict::Wrong(_) => misses_wrong += 1,
                    Verdict::Tie(_) => misses_tied += 1,
                    Verdict::Agree => {}
                }
            }
        }
        assert_eq!(truths.closest(i), lancer::trace::oracle::closest(&mesh, r));
    }
    assert!(
        hits_judged > 300 && others_judged > 300,
        "{hits_judged} {others_judged}"
    );
    assert!(
        misses_wrong > 100 && misses_tied * 20 < misses_wrong,
        "misses of occluded rays: {misses_wrong} wrong, {misses_tied} ties"
    );
}
