//! BVH build time of sweep / binned / median against the `bvh` and `obvhs` crates, on the
//! bunny and a generated 1M-triangle mesh; SAH costs (same formula for all) printed first.

mod common;

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions, Builder, BvhStats};
use lancer::geometry::Aabb;
use lancer::mesh::Mesh;

fn opts(builder: Builder) -> BuildOptions {
    BuildOptions {
        builder,
        ..BuildOptions::default()
    }
}

// --- the `bvh` crate (nalgebra types) ---
struct Shape {
    lo: [f32; 3],
    hi: [f32; 3],
    node: usize,
}
impl bvh::aabb::Bounded<f32, 3> for Shape {
    fn aabb(&self) -> bvh::aabb::Aabb<f32, 3> {
        bvh::aabb::Aabb::with_bounds(self.lo.into(), self.hi.into())
    }
}
impl bvh::bounding_hierarchy::BHShape<f32, 3> for Shape {
    fn set_bh_node_index(&mut self, i: usize) {
        self.node = i;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}
fn bvh_shapes(mesh: &Mesh) -> Vec<Shape> {
    mesh.included()
        .iter()
        .map(|&i| {
            let b = mesh.triangles[i as usize].bbox();
            Shape {
                lo: b.lo.into(),
                hi: b.hi.into(),
                node: 0,
            }
        })
        .collect()
}
fn bvh_crate_cost(b: &bvh::bvh::Bvh<f32, 3>) -> f64 {
    use bvh::bvh::BvhNode;
    let area = |a: &bvh::aabb::Aabb<f32, 3>| {
        Aabb {
            lo: glam::Vec3::from_slice(a.min.coords.as_slice()),
            hi: glam::Vec3::from_slice(a.max.coords.as_slice()),
        }
        .area() as f64
    };
    let mut root = 0.0;
    let mut cost = 0.0;
    for (i, n) in b.nodes.iter().enumerate() {
        if let BvhNode::Node {
            child_l_aabb,
            child_r_aabb,
            child_l_index,
            child_r_index,
            ..
        } = n
        {
            let a = area(&child_l_aabb.join(child_r_aabb));
            if i == 0 {
                root = a;
            }
            cost += 2.0 * a;
            for (ci, cb) in [(child_l_index, child_l_aabb), (child_r_index, child_r_aabb)] {
                if matches!(b.nodes[*ci], BvhNode::Leaf { .. }) {
                    cost += area(cb);
                }
            }
        }
    }
    cost / root
}

// --- obvhs ---
fn obvhs_tris(mesh: &Mesh) -> Vec<obvhs::triangle::Triangle> {
    mesh.included()
        .iter()
        .map(|&i| {
            let v = mesh.triangles[i as usize]
                .v
                .map(|p| glam::Vec3A::new(p.x, p.y, p.z));
            obvhs::triangle::Triangle {
                v0: v[0],
                v1: v[1],
                v2: v[2],
            }
        })
        .collect()
}
fn obvhs_build(tris: &[obvhs::triangle::Triangle]) -> obvhs::bvh2::Bvh2 {
    let mut t = Duration::ZERO;
    obvhs::bvh2::builder::build_bvh2_from_tris(tris, obvhs::BvhBuildParams::medium_build(), &mut t)
}
fn obvhs_cost(b: &obvhs::bvh2::Bvh2) -> f64 {
    let area = |n: &obvhs::bvh2::node::Bvh2Node| {
        let d = n.aabb.diagonal();
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x) as f64
    };
    let root = area(&b.nodes[0]);
    b.nodes
        .iter()
        .map(|n| {
            area(n)
                * if n.prim_count == 0 {
                    2.0
                } else {
                    n.prim_count as f64
                }
        })
        .sum::<f64>()
        / root
}

fn bench_mesh(c: &mut Criterion, name: &str, mesh: &Mesh, samples: usize) {
    let ours = [Builder::Sweep, Builder::Binned, Builder::Median]
        .map(|b| (b, BvhStats::of(&build(mesh, &opts(b)), &opts(b)).sah_cost));
    let obv = obvhs_tris(mesh);
    let mut shapes = bvh_shapes(mesh);
    let bvh_cost = bvh_crate_cost(&bvh::bvh::Bvh::build_with_executor(
        &mut shapes,
        bvh::bvh::rayon_executor,
    ));
    println!("SAH cost on {name} (T_cube = T_obj = 1, normalised by root area):");
    for (b, cst) in ours {
        println!("  lancer {b:?}: {cst:.2}");
    }
    println!(
        "  obvhs medium_build: {:.2}",
        obvhs_cost(&obvhs_build(&obv))
    );
    println!("  bvh crate (build_par): {bvh_cost:.2}");

    let mut g = c.benchmark_group(format!("build/{name}"));
    g.sample_size(samples);
    for b in [Builder::Sweep, Builder::Binned, Builder::Median] {
        g.bench_function(format!("lancer-{b:?}").to_lowercase(), |x| {
            x.iter(|| flatten(LayoutKind::DfsSign, &build(mesh, &opts(b)), mesh))
        });
    }
    g.bench_function("obvhs-medium", |x| x.iter(|| obvhs_build(&obv)));
    g.bench_function("bvh-crate-par", |x| {
        x.iter(|| {
            let mut s = bvh_shapes(mesh);
            bvh::bvh::Bvh::build_with_executor(&mut s, bvh::bvh::rayon_executor)
        })
    });
    g.finish();
}

fn builds(c: &mut Criterion) {
    bench_mesh(c, "bunny", &common::bunny(), 20);
    bench_mesh(c, "terrain-1M", &common::terrain(1_000_000), 10);
}

criterion_group! {
    name = benches;
    // No plots: criterion's need system fonts (absent on headless machines: it panics).
    config = Criterion::default().without_plots().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(5));
    targets = builds
}
criterion_main!(benches);
