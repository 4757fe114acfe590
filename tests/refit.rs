//! A refit BVH (`Bvh::refit`: bounds recomputed for moved triangles, its shape kept) traces
//! the same hits as a BVH built from scratch over the moved triangles, bit for bit, with
//! every builder's tree in every layout, on the CPU twin and the GPU; its SAH cost is no
//! better than the rebuild's.

mod common;

use std::sync::Arc;

use common::gpu_twin::{bits, same_on_gpu};
use common::{random_rays, Rng};
use glam::Vec3;
use lancer::accel::bvh::{build, layouts, BuildOptions, Builder, BvhStats};
use lancer::accel::GpuForm;
use lancer::geometry::Triangle;
use lancer::mesh::Mesh;
use lancer::{LayoutKind, Query, Robustness};

/// A wavy sheet of 2·n² triangles twisted about the vertical axis by `twist` radians per
/// unit of height, and bent by `bend`.
fn sheet(n: usize, twist: f32, bend: f32) -> Mesh {
    let p = |i: usize, j: usize| {
        let (x, z) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
        let y = 0.08 * (11.0 * x).sin() * (7.0 * z).cos() + bend * x * x;
        let a = twist * (z + 0.5);
        Vec3::new(x * a.cos() - y * a.sin(), x * a.sin() + y * a.cos(), z)
    };
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    Mesh::from_triangles(tris)
}

#[test]
fn a_refit_traces_the_same_hits_as_a_rebuild_over_the_same_triangles() {
    let base = sheet(48, 0.0, 0.0);
    let moved = sheet(48, 2.5, 0.6);
    let mut rng = Rng::new(9);
    let rays = random_rays(&mut rng, 3000, &moved);
    let rob = Robustness::default();
    for builder in [
        Builder::Sweep,
        Builder::Binned,
        Builder::Sbvh,
        Builder::Ploc,
    ] {
        let opts = BuildOptions {
            builder,
            ..BuildOptions::default()
        };
        let mut refit = build(&base, &opts);
        refit.refit(&moved).unwrap();
        let rebuilt = build(&moved, &opts);
        let (refit_sah, rebuilt_sah) = (
            BvhStats::of(&refit, &opts).sah_cost,
            BvhStats::of(&rebuilt, &opts).sah_cost,
        );
        println!("{builder:?}: SAH refit {refit_sah:.2}, rebuilt {rebuilt_sah:.2}");
        assert!(refit_sah >= rebuilt_sah * 0.99, "{builder:?}");
        for &layout in LayoutKind::ALL {
            let a = layouts::try_flatten(layout, &refit, &moved).unwrap();
            let b = layouts::try_flatten(layout, &rebuilt, &moved).unwrap();
            for query in [Query::Closest, Query::Any] {
                let (x, y) = (
                    a.trace_hits(&rays, query, &rob),
                    b.trace_hits(&rays, query, &rob),
                );
                let differ = (x.iter().zip(&y))
                    .filter(|(p, q)| match query {
                        Query::Closest => bits(p) != bits(q),
                        Query::Any => p.is_hit() != q.is_hit(),
                    })
                    .count();
                assert_eq!(differ, 0, "{builder:?} {layout} {query:?}");
            }
        }
    }
    // The GPU traces the refit layout as its twin does.
    let mut refit = build(&base, &BuildOptions::default());
    refit.refit(&moved).unwrap();
    let form: Arc<dyn GpuForm> = layouts::try_flatten(LayoutKind::Cwbvh, &refit, &moved)
        .unwrap()
        .into();
    same_on_gpu("refit cwbvh", &form, &rays, rob);
}

/// A refit cannot leave a triangle out as a load does: one moved beyond the supported range
/// (±1e11, infinities included) is refused by name, the tree unchanged; a NaN corner only
/// makes its triangle never hit.
#[test]
fn a_refit_refuses_triangles_moved_beyond_the_supported_range() {
    let base = sheet(8, 0.0, 0.0);
    let opts = BuildOptions::default();
    for far in [1e12, 1e20, f32::INFINITY, -f32::INFINITY] {
        let mut tree = build(&base, &opts);
        let before = tree.clone();
        let mut moved = base.clone();
        moved.triangles[5].v[1].y = far;
        let err = tree
            .refit(&moved)
            .expect_err("refit beyond the range")
            .to_string();
        assert!(
            err.contains("triangle 5") && err.contains("supported range"),
            "{err}"
        );
        assert_eq!(tree, before, "a refused refit changes nothing");
    }
    // A triangle the load left out (beyond the range) is not the tree's: it may stay there.
    let mut far = base.clone();
    far.triangles[3].v[0].x = 1e20;
    far.status[3] = lancer::mesh::TriStatus::TooFar;
    let mut tree = build(&far, &opts);
    assert!(!tree.order().contains(&3));
    tree.refit(&far)
        .expect("a triangle left out does not count");
    let mut tree = build(&base, &opts);
    let mut moved = base.clone();
    moved.triangles[5].v[1].y = f32::NAN;
    tree.refit(&moved).expect("a NaN corner refits");
    for kind in LayoutKind::ALL {
        layouts::try_flatten(*kind, &tree, &moved).expect("flattens");
    }
}

/// Triangles marked usable by hand though they lie far beyond the supported range (their
/// boxes' areas overflow f32) still flatten into every layout: the wide layouts' SAH
/// programme picks a valid split where every cost is infinite, and nothing panics.
#[test]
fn infinite_sah_costs_still_make_valid_wide_trees() {
    let mut far = sheet(8, 0.0, 0.0);
    for t in &mut far.triangles {
        for v in &mut t.v {
            *v *= 1e20;
        }
    }
    far.status.fill(lancer::mesh::TriStatus::Ok);
    let tree = build(&far, &BuildOptions::default());
    assert_eq!(tree.order().len(), far.len(), "every triangle in the tree");
    for kind in LayoutKind::ALL {
        let layout = layouts::try_flatten(*kind, &tree, &far).expect("flattens");
        layout.validate().expect("a valid layout");
    }
}
