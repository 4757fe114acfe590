//! A structure's GPU kernel against its CPU twin, bit for bit (hits and statistics, both BVH
//! memories, closest and any hit), and the GPU's answers judged by the f64 oracle: shared by
//! tests/gpu_forms.rs (the kd-tree and the BIH) and tests/layout_cwbvh.rs.

use std::sync::{Arc, OnceLock};

use lancer::accel::GpuForm;
use lancer::accel::{build_gpu, AccelKind};
use lancer::geometry::{Hit, Ray};
use lancer::gpu::BvhMemory;
use lancer::mesh::Mesh;
use lancer::trace::oracle::{judge, judge_any, Verdict};
use lancer::{Device, Query, Robustness, Tracer, TracerOptions};

use crate::common::gpu_device;

pub fn cpu_device() -> &'static Device {
    static DEVICE: OnceLock<Device> = OnceLock::new();
    DEVICE.get_or_init(Device::cpu)
}

pub fn bits(h: &Hit) -> [u32; 4] {
    [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()]
}

/// Structure `kind`'s GPU form, as `Tracer::with_structure` builds it.
pub fn gpu_form(kind: AccelKind, mesh: &Mesh) -> Arc<dyn GpuForm> {
    build_gpu(kind, mesh, &Default::default())
        .unwrap()
        .unwrap_or_else(|| panic!("{kind} has no GPU form"))
}

/// Traces `rays` through `tree` on the CPU twin and on the GPU in both memories, closest and
/// any hit; asserts that hits and statistics agree bit for bit, and that no ray was cut
/// short by the driver (it would be traced again on the CPU, and agree trivially). Returns
/// the GPU's closest and any hits.
pub fn same_on_gpu(
    name: &str,
    tree: &Arc<dyn GpuForm>,
    rays: &[Ray],
    rob: Robustness,
) -> [Vec<Hit>; 2] {
    let options = |memory| TracerOptions {
        memory,
        robustness: rob,
        stats: true,
        ..TracerOptions::default()
    };
    let mut cpu =
        Tracer::with_layout(cpu_device(), tree.clone(), &options(Default::default())).unwrap();
    let queries = [Query::Closest, Query::Any];
    let want = queries.map(|q| cpu.trace(rays, q).unwrap());
    let mut got = [Vec::new(), Vec::new()];
    for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
        let mut gpu = Tracer::with_layout(gpu_device(), tree.clone(), &options(memory)).unwrap();
        for (q, c) in queries.iter().zip(&want) {
            let g = gpu.trace(rays, *q).unwrap();
            let what = format!("{name} {memory:?} {q:?}");
            assert_eq!(g.cpu_retraced, 0, "{what}: rays cut short by the driver");
            let (cs, gs) = (c.stats.as_ref().unwrap(), g.stats.as_ref().unwrap());
            let mut differ = 0;
            for (i, r) in rays.iter().enumerate() {
                let same = bits(&c.hits[i]) == bits(&g.hits[i]) && cs[i] == gs[i];
                if !same {
                    differ += 1;
                    if differ <= 3 {
                        println!(
                            "{what}: ray {i} {r:?}: CPU {:?} {:?}, GPU {:?} {:?}",
                            c.hits[i], cs[i], g.hits[i], gs[i]
                        );
                    }
                }
            }
            let hits = g.hits.iter().filter(|h| h.is_hit()).count();
            println!("{what}: {} rays, {hits} hits, {differ} differ", rays.len());
            assert_eq!(differ, 0, "{what}: GPU ≠ CPU twin");
            got[(*q == Query::Any) as usize] = g.hits;
        }
    }
    got
}

/// Judges every `every`-th ray's GPU answers, closest and any hit, by the f64 oracle;
/// fails on a wrong one. Returns how many closest hits the oracle agrees with exactly.
pub fn judged(name: &str, mesh: &Mesh, rays: &[Ray], hits: &[Vec<Hit>; 2], every: usize) -> usize {
    let mut agree = 0;
    for (i, r) in rays.iter().enumerate().step_by(every) {
        for (q, v) in [
            (Query::Closest, judge(mesh, r, &hits[0][i])),
            (Query::Any, judge_any(mesh, r, &hits[1][i])),
        ] {
            match v {
                Verdict::Wrong(w) => panic!("{name} {q:?}: ray {i} {r:?}: {w}"),
                Verdict::Agree if q == Query::Closest => agree += 1,
                _ => {}
            }
        }
    }
    println!(
        "{name}: {agree} of {} judged agree",
        rays.len().div_ceil(every)
    );
    agree
}
