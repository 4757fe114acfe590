//! The `embree` rows of `lancer bench layouts` (the `embree` feature): Embree 3 as the
//! reference CPU tracer, on the same ray sets and the same rayon threads as the CPU twins.

use indicatif::ProgressBar;
use lancer::embree::EmbreeTracer;
use lancer::{Mesh, Query, Ray, Result};

use super::bench::median;
use super::bench_layouts::{Row, EMBREE, SINGLE_RAY};

/// Embree's scene over `mesh` (medium build quality, Embree's default), built on rayon's
/// thread count, and one row per set: `rtcIntersect1` for closest-hit sets, `rtcOccluded1`
/// for any-hit sets, one ray per call on rayon's threads, the median of `repeat` timed runs
/// after an untimed one. Returns the build time (ms), Embree's version and the rows.
pub fn embree_rows(
    mesh: &Mesh,
    sets: &[(String, Query, Vec<Ray>)],
    repeat: usize,
    bar: &ProgressBar,
) -> Result<(f64, String, Vec<Row>)> {
    bar.inc_length((sets.len() * repeat) as u64);
    bar.set_message(EMBREE);
    let embree = EmbreeTracer::new(mesh, rayon::current_num_threads())?;
    let trace = |rays: &[Ray], query: Query| match query {
        Query::Closest => drop(embree.closest(rays)),
        Query::Any => drop(embree.occluded(rays)),
    };
    let mut rows = Vec::new();
    for (name, query, rays) in sets {
        trace(rays, *query);
        let mut times = Vec::new();
        for _ in 0..repeat {
            let start = std::time::Instant::now();
            trace(rays, *query);
            times.push(start.elapsed().as_secs_f64());
            bar.inc(1);
        }
        rows.push(Row {
            layout: EMBREE,
            mode: SINGLE_RAY,
            rays: name.clone(),
            count: rays.len(),
            nodes: None,
            tris: None,
            bytes_loaded: None,
            cpu_mrays: Some(rays.len() as f64 / median(times) / 1e6),
            gpu_mrays: None,
        });
    }
    Ok((embree.build_ms(), embree.version().to_string(), rows))
}
