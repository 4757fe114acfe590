//! CPU primary-ray throughput at 1024² on the default view of the bunny (closest hit), and
//! shadow rays (any hit), both with the default sweep BVH.

mod common;

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::camera::Camera;
use lancer::geometry::{Robustness, TriangleTest};
use lancer::trace::files::{default_light, shadow_rays};
use lancer::Query;

fn traces(c: &mut Criterion) {
    let mesh = common::bunny();
    let flat = flatten(
        LayoutKind::DfsSign,
        &build(&mesh, &BuildOptions::default()),
        &mesh,
    );
    let primary = Camera::default_view(&mesh.bounds(), 1024, 1024).primary_rays();
    let robust = Robustness::default();
    let (hits, _) = flat.trace_batch(&primary, Query::Closest, &robust);
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    let mut g = c.benchmark_group("cpu-trace/bunny-1024");
    g.sample_size(10);
    for (name, q, rays) in [
        ("primary-closest", Query::Closest, &primary),
        ("shadow-any", Query::Any, &shadow),
    ] {
        g.throughput(Throughput::Elements(rays.len() as u64));
        for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
            g.bench_function(format!("{name}/{test:?}").to_lowercase(), |b| {
                let rob = Robustness {
                    triangle_test: test,
                    ..robust
                };
                b.iter(|| flat.trace_batch(rays, q, &rob))
            });
        }
    }
    g.finish();
}

criterion_group! {
    name = benches;
    // No plots: criterion's need system fonts (absent on headless machines: it panics).
    config = Criterion::default().without_plots().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(4));
    targets = traces
}
criterion_main!(benches);
