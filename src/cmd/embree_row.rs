//! Embree 3 in `lancer bench layouts` (the `embree` feature): the reference CPU tracer, run
//! on the same ray sets and the same rayon threads as the CPU twins, once beside every timed
//! run of a layout so that each layout's speed is also a ratio to Embree's paired run.

use std::time::Instant;

use lancer::embree::EmbreeTracer;
use lancer::{Mesh, Query, Ray, Result};

use super::bench_layouts::Reference;

/// Embree's scene over `mesh` (medium build quality, Embree's default), built on rayon's
/// thread count, as the bench's reference: `rtcIntersect1` for closest-hit sets,
/// `rtcOccluded1` for any-hit sets, one ray per call on rayon's threads, each call timed
/// on the wall clock.
pub fn reference(mesh: &Mesh) -> Result<Reference> {
    let embree = EmbreeTracer::new(mesh, rayon::current_num_threads())?;
    let (build_ms, version) = (embree.build_ms(), embree.version().to_string());
    let time = move |rays: &[Ray], query: Query| {
        let start = Instant::now();
        match query {
            Query::Closest => drop(embree.closest(rays)),
            Query::Any => drop(embree.occluded(rays)),
        }
        start.elapsed().as_secs_f64()
    };
    Ok(Reference {
        time: Box::new(time),
        build_ms,
        version,
    })
}
