//! For the ignored speed experiments: a side-by-side race (tests/bih.rs, tests/kdtree.rs),
//! built structures traced on the same ray sets in alternating rounds, each one's best
//! Mrays/s beside the BVH's, its work per ray and its build time; the timed default BVH;
//! a thread's own CPU time (tests/octree.rs, tests/grids.rs).

use std::time::Instant;

use lancer::accel::Accel;
use lancer::geometry::Ray;
use lancer::mesh::Mesh;
use lancer::{Query, RayStats, Robustness};

use super::accel_check::default_bvh;

/// A structure in a race: its name, the structure and its build time in seconds.
pub type Entrant = (String, Box<dyn Accel>, f64);

/// The default BVH ([`default_bvh`]) on `mesh`, timed: the first entrant, the one the
/// others' speeds are given against.
pub fn bvh_entrant(mesh: &Mesh) -> Entrant {
    let t = Instant::now();
    let bvh = default_bvh(mesh);
    ("bvh".into(), bvh, t.elapsed().as_secs_f64())
}

/// CPU time of this thread in ns (Linux: /proc/thread-self/schedstat), 0 elsewhere: what
/// other processes on a shared machine change least.
pub fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// Traces each set of `sets` (its name, its rays) closest-hit through every entrant,
/// `rounds` rounds with the entrants alternating, and prints per set and entrant the best
/// Mrays/s (and as a multiple of the first entrant's), the mean nodes and triangle tests
/// per ray and the build time as `build_time` writes it.
pub fn race(
    all: &[Entrant],
    sets: &[(&str, &[Ray])],
    rounds: usize,
    build_time: impl Fn(f64) -> String,
) {
    let rob = Robustness::default();
    for &(what, rays) in sets {
        let mut best = vec![0.0f64; all.len()];
        let mut work = vec![(0.0, 0.0); all.len()];
        for _ in 0..rounds {
            for (i, (_, a, _)) in all.iter().enumerate() {
                let t = Instant::now();
                let (_, stats) = a.trace_batch(rays, Query::Closest, &rob);
                let m = rays.len() as f64 / t.elapsed().as_secs_f64() / 1e6;
                best[i] = best[i].max(m);
                work[i] = RayStats::means(&stats);
            }
        }
        for (i, (name, _, b)) in all.iter().enumerate() {
            println!(
                "{what}, {name}: {:.2} Mrays/s ({:.2}× the BVH), {:.1} nodes, {:.2} \
                 triangle tests per ray; build {}",
                best[i],
                best[i] / best[0],
                work[i].0,
                work[i].1,
                build_time(*b)
            );
        }
    }
}
