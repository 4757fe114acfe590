//! A trace's summary and statistics: `lancer trace --json` ([`TraceReport`]) and `--stats`
//! ([`TraceStats`], whose [`text`](TraceStats::text) gives the lines the CLI prints), built
//! from a [`TraceResult`] and what the caller asked for.

use serde::Serialize;

use crate::accel::{AccelKind, RayStats};
use crate::device::Device;
use crate::gpu::BvhMemory;
use crate::{LayoutKind, TraversalMode};

use super::{TraceResult, TracerOptions};

/// `trace --json`: one object a run.
#[derive(Clone, Debug, Serialize)]
pub struct TraceReport {
    /// Rays traced.
    pub rays: usize,
    /// Rays that hit something.
    pub hits: usize,
    /// The hit file written (`-`: stdout).
    pub out: String,
    /// The rest, with --stats only (else absent).
    #[serde(flatten)]
    pub stats: Option<TraceStats>,
}

impl TraceReport {
    /// The summary of `result`, written to `out`, with `stats` or without.
    pub fn new(result: &TraceResult, out: &str, stats: Option<TraceStats>) -> TraceReport {
        TraceReport {
            rays: result.hits.len(),
            hits: result.hits.iter().filter(|h| h.is_hit()).count(),
            out: out.to_string(),
            stats,
        }
    }

    /// The lines after the hits are written: rays and hits, and the work per ray when the
    /// trace kept statistics.
    pub fn text(&self, result: &TraceResult) -> Vec<String> {
        let mut lines = vec![format!(
            "{} rays, {} hits, written to {}",
            self.rays, self.hits, self.out
        )];
        if let Some((nodes, tris)) = means(result) {
            lines.push(format!("nodes/ray {nodes:.2}  triangles/ray {tris:.2}"));
        }
        lines
    }
}

/// `trace --stats --json`.
#[derive(Clone, Debug, Serialize)]
pub struct TraceStats {
    /// "cpu" or "gpu".
    pub device: &'static str,
    /// The GPU adapter (null on the CPU).
    pub adapter: Option<String>,
    /// CPU threads (rayon's pool; --threads).
    pub cpu_threads: usize,
    /// `--accel` structure, e.g. "bvh (dfs-sign)".
    pub structure: String,
    /// `--layout`.
    pub layout: String,
    /// Traversal mode that ran (per-ray where subgroup could not).
    pub mode: String,
    /// Where the GPU read the BVH (null on the CPU).
    pub bvh_memory: Option<String>,
    /// GPU time of the dispatches in ms (null on the CPU or without timestamp queries).
    pub gpu_ms: Option<f64>,
    /// Wall time of the trace in ms (GPU: upload, dispatch and read-back).
    pub wall_ms: f64,
    /// Mean nodes (or cells) visited per ray.
    pub nodes_per_ray: Option<f64>,
    /// Mean triangles tested per ray.
    pub triangles_per_ray: Option<f64>,
    /// The device in words (the text's; not serialised).
    #[serde(skip)]
    pub device_text: String,
    /// The traversal mode asked for (the text's; not serialised).
    #[serde(skip)]
    pub asked: TraversalMode,
}

impl TraceStats {
    /// The statistics of `result`, traced on `device` through `kind` (`layout`) with
    /// `options`.
    pub fn new(
        result: &TraceResult,
        device: &Device,
        kind: AccelKind,
        layout: LayoutKind,
        options: &TracerOptions,
    ) -> TraceStats {
        let gpu = device.gpu_context();
        let means = means(result);
        TraceStats {
            device: if gpu.is_some() { "gpu" } else { "cpu" },
            adapter: gpu.map(|c| c.adapter.to_string()),
            cpu_threads: rayon::current_num_threads(),
            structure: kind.to_string(),
            layout: layout.name().to_string(),
            mode: result.mode.name().to_string(),
            bvh_memory: gpu.map(|_| memory_name(options.memory).to_string()),
            gpu_ms: result.timings.gpu_ms,
            wall_ms: result.timings.wall_ms,
            nodes_per_ray: means.map(|m| m.0),
            triangles_per_ray: means.map(|m| m.1),
            device_text: device.to_string(),
            asked: options.mode,
        }
    }

    /// The lines `lancer trace --stats` prints before writing the hits.
    pub fn text(&self) -> Vec<String> {
        let mut lines = vec![
            format!("device    {}", self.device_text),
            format!("structure {}", self.structure),
            format!("layout    {}", self.layout),
        ];
        if self.mode == self.asked.name() {
            lines.push(format!("mode      {}", self.mode));
        } else {
            lines.push(format!(
                "mode      {} ({} asked for, see the warning)",
                self.mode, self.asked
            ));
        }
        if let Some(memory) = &self.bvh_memory {
            lines.push(format!("bvh       in {memory}"));
            let gpu = (self.gpu_ms)
                .map(|ms| format!("{ms:.2} ms"))
                .unwrap_or("n/a".into());
            lines.push(format!(
                "gpu time  {gpu} (dispatches)  wall {:.2} ms (upload+dispatch+readback)",
                self.wall_ms
            ));
        }
        lines
    }
}

/// Mean nodes and triangles per ray, where the trace kept statistics.
fn means(result: &TraceResult) -> Option<(f64, f64)> {
    (result.stats.as_ref())
        .filter(|s| !s.is_empty())
        .map(|s| RayStats::means(s))
}

/// Where the BVH lives, as the command line spells it.
fn memory_name(memory: BvhMemory) -> &'static str {
    match memory {
        BvhMemory::Buffers => "buffers",
        BvhMemory::Textures => "textures",
    }
}
