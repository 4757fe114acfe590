//! BVH invariants: every included triangle in exactly one leaf, children inside parents,
//! depth within the stack, determinism, parallel ≡ serial, and SAH quality ordering.

mod common;

use common::{load_model, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions, Builder, Bvh, BvhStats, Node, MAX_DEPTH};
use lancer::geometry::Triangle;
use lancer::mesh::{Mesh, TriStatus};
use proptest::prelude::*;

fn opts(builder: Builder) -> BuildOptions {
    BuildOptions {
        builder,
        ..BuildOptions::default()
    }
}

/// Checks every structural invariant of a BVH over `mesh`, and that every layout
/// flattens it into arrays its own validation accepts.
fn check_invariants(mesh: &Mesh, bvh: &Bvh) {
    let mut seen = vec![0u32; mesh.len()];
    let mut stack = vec![(&bvh.root, 0usize)];
    while let Some((n, depth)) = stack.pop() {
        assert!(depth <= MAX_DEPTH);
        match n {
            Node::Leaf { bbox, start, count } => {
                for &prim in &bvh.order[*start as usize..(start + count) as usize] {
                    seen[prim as usize] += 1;
                    // The leaf box holds its triangles.
                    assert!(bbox.contains(&mesh.triangles[prim as usize].bbox()));
                }
            }
            Node::Inner { bbox, children, .. } => {
                for c in children.iter() {
                    assert!(bbox.contains(c.bbox()), "child outside its parent");
                    stack.push((c, depth + 1));
                }
            }
        }
    }
    for (i, &s) in seen.iter().enumerate() {
        let included = mesh.status[i] == TriStatus::Ok;
        assert_eq!(s, included as u32, "triangle {i} appears {s} times");
    }
    for &kind in LayoutKind::ALL {
        let layout = flatten(kind, bvh, mesh);
        layout.validate().unwrap_or_else(|e| panic!("{kind}: {e}"));
        assert_eq!(layout.triangles(), bvh.order.len(), "{kind}");
    }
}

/// Largest leaf of a tree.
fn largest_leaf(n: &Node) -> usize {
    match n {
        Node::Leaf { count, .. } => *count as usize,
        Node::Inner { children, .. } => largest_leaf(&children[0]).max(largest_leaf(&children[1])),
    }
}

proptest! {
    #![proptest_config(common::proptest_config("bvh_props", 48))]
    #[test]
    fn invariants_hold_on_random_soups(seed in any::<u64>(), n in 1usize..600, size in 0.001f32..0.5,
                                      max_leaf in 1usize..20) {
        let mesh = soup(&mut Rng::new(seed), n, size);
        for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
            let o = BuildOptions { builder: b, max_leaf, ..BuildOptions::default() };
            let f = build(&mesh, &o);
            check_invariants(&mesh, &f);
            // No leaf above max_leaf.
            prop_assert!(largest_leaf(&f.root) <= max_leaf);
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
    let f = build(&mesh, &BuildOptions::default());
    check_invariants(&mesh, &f);
    assert_eq!(f.order.len(), 197);
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
        let f = build(&mesh, &opts(b));
        let s = BvhStats::of(&f, &opts(b));
        assert!(s.max_depth <= MAX_DEPTH, "{b:?}: depth {}", s.max_depth);
        assert_eq!(s.triangles, 1_000_000);
        check_invariants(&mesh, &f);
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
        let uncapped = BvhStats::of(&build(&mesh, &free), &free).max_depth;
        assert!(uncapped > 13, "{b:?}: uncapped depth {uncapped}");
        let capped = BuildOptions {
            max_depth: 13,
            ..free
        };
        let f = build(&mesh, &capped);
        check_invariants(&mesh, &f);
        let d = BvhStats::of(&f, &capped).max_depth;
        assert!(d <= 13, "{b:?}: depth {d} above the cap of 13");
    }
}

fn costs(mesh: &Mesh) -> [f64; 3] {
    [Builder::Sweep, Builder::Binned, Builder::Median]
        .map(|b| BvhStats::of(&build(mesh, &opts(b)), &opts(b)).sah_cost)
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
        check_invariants(&mesh, &build(&mesh, &BuildOptions::default()));
    }
}
