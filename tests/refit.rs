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
