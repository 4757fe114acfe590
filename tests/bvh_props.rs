//! BVH invariants: every included triangle in exactly one leaf, children inside parents,
//! depth within the stack, determinism, parallel ≡ serial, and SAH quality ordering.

mod common;

use common::{load_model, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::{build, BuildOptions, Builder, BvhStats, FlatBvh, MAX_DEPTH};
use lancer::geometry::Triangle;
use lancer::scene::Mesh;
use proptest::prelude::*;

fn opts(builder: Builder) -> BuildOptions {
    BuildOptions {
        builder,
        ..BuildOptions::default()
    }
}

/// Checks every structural invariant of a flat BVH over `mesh`.
fn check_invariants(mesh: &Mesh, flat: &FlatBvh) {
    flat.validate().expect("valid BVH");
    let mut seen = vec![0u32; mesh.len()];
    let mut stack = vec![(0usize, 0usize)];
    while let Some((i, depth)) = stack.pop() {
        assert!(depth <= MAX_DEPTH);
        let n = &flat.nodes[i];
        if n.is_leaf() {
            for t in &flat.tris[n.a as usize..(n.a + n.count()) as usize] {
                seen[t.prim as usize] += 1;
                // The leaf box holds its triangles, and the stored vertices are the mesh's.
                assert!(n.bbox().contains(&t.triangle().bbox()));
                assert_eq!(t.triangle(), mesh.triangles[t.prim as usize]);
            }
        } else {
            for c in [i + 1, n.a as usize] {
                assert!(
                    n.bbox().contains(&flat.nodes[c].bbox()),
                    "child {c} outside parent {i}"
                );
                stack.push((c, depth + 1));
            }
        }
    }
    for (i, &s) in seen.iter().enumerate() {
        let included = mesh.status[i] == lancer::scene::TriStatus::Ok;
        assert_eq!(s, included as u32, "triangle {i} appears {s} times");
    }
}

fn flat(mesh: &Mesh, o: &BuildOptions) -> FlatBvh {
    FlatBvh::new(&build(mesh, o), mesh)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn invariants_hold_on_random_soups(seed in any::<u64>(), n in 1usize..600, size in 0.001f32..0.5,
                                      max_leaf in 1usize..20) {
        let mesh = soup(&mut Rng::new(seed), n, size);
        for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
            let o = BuildOptions { builder: b, max_leaf, ..BuildOptions::default() };
            let f = flat(&mesh, &o);
            check_invariants(&mesh, &f);
            // No leaf above max_leaf.
            prop_assert!(f.nodes.iter().filter(|n| n.is_leaf()).all(|n| n.count() as usize <= max_leaf));
        }
    }
}

#[test]
fn excluded_triangles_stay_out() {
    let mut rng = Rng::new(7);
    let mut mesh = soup(&mut rng, 200, 0.1);
    let mut tris = mesh.triangles.clone();
    tris[3].v[1] = Vec3::NAN;
    tris[10].v[2] = Vec3::new(f32::INFINITY, 0.0, 0.0);
    tris[20].v[2] = tris[20].v[0]; // zero area
    mesh = Mesh::from_triangles(tris);
    let f = flat(&mesh, &BuildOptions::default());
    check_invariants(&mesh, &f);
    assert_eq!(f.tris.len(), 197);
}

#[test]
fn build_is_deterministic_and_parallel_equals_serial() {
    let mesh = soup(&mut Rng::new(11), 30_000, 0.05);
    for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
        let par = build(&mesh, &opts(b));
        let again = build(&mesh, &opts(b));
        let ser = build(
            &mesh,
            &BuildOptions {
                parallel: false,
                ..opts(b)
            },
        );
        assert_eq!(par, again, "{b:?} not deterministic");
        assert_eq!(par, ser, "{b:?} parallel differs from serial");
    }
}

#[test]
fn identical_triangles_stay_within_the_stack() {
    let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let mesh = Mesh::from_triangles(vec![t; 1_000_000]);
    for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
        let f = flat(&mesh, &opts(b));
        let s = BvhStats::of(&f, &opts(b));
        assert!(s.max_depth <= MAX_DEPTH, "{b:?}: depth {}", s.max_depth);
        assert_eq!(s.triangles, 1_000_000);
        f.validate().unwrap();
    }
}

#[test]
fn depth_cap_bounds_every_leaf() {
    // The cap that protects the 64-entry stack, exercised at a depth real meshes reach:
    // an uncapped tree over this soup is deeper than 13.
    let mesh = soup(&mut Rng::new(3), 3000, 0.3);
    for b in [Builder::Sweep, Builder::Binned] {
        let free = BuildOptions {
            max_leaf: 1,
            ..opts(b)
        };
        let uncapped = BvhStats::of(&flat(&mesh, &free), &free).max_depth;
        assert!(uncapped > 13, "{b:?}: uncapped depth {uncapped}");
        let capped = BuildOptions {
            max_depth: 13,
            ..free
        };
        let f = flat(&mesh, &capped);
        check_invariants(&mesh, &f);
        let d = BvhStats::of(&f, &capped).max_depth;
        assert!(d <= 13, "{b:?}: depth {d} above the cap of 13");
    }
}

fn costs(mesh: &Mesh) -> [f64; 3] {
    [Builder::Sweep, Builder::Binned, Builder::Median]
        .map(|b| BvhStats::of(&flat(mesh, &opts(b)), &opts(b)).sah_cost)
}

#[test]
fn sweep_beats_binned_beats_median_on_random_soups() {
    for seed in 0..6 {
        let mesh = soup(&mut Rng::new(seed), 5000, 0.05 + 0.05 * seed as f32);
        let [s, b, m] = costs(&mesh);
        println!("seed {seed}: sweep {s:.3} binned {b:.3} median {m:.3}");
        assert!(
            s <= b && b <= m,
            "seed {seed}: sweep {s} binned {b} median {m}"
        );
    }
}

#[test]
fn sweep_beats_binned_beats_median_on_models() {
    for name in ["stanford-bunny.obj", "teapot.obj"] {
        let Some(mesh) = load_model(name) else { return };
        let [s, b, m] = costs(&mesh);
        println!("{name}: sweep {s:.3} binned {b:.3} median {m:.3}");
        assert!(s <= b && b <= m, "{name}: sweep {s} binned {b} median {m}");
        check_invariants(&mesh, &flat(&mesh, &BuildOptions::default()));
    }
}
