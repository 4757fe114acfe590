//! A render's statistics: `lancer render --stats` (the lines of [`RenderStats::text`]) and
//! `--stats --json` (the [`RenderStats`] object, serde), built from the [`Renderer`], what
//! it [`Rendered`] and what the caller asked for.

use std::path::Path;

use serde::Serialize;

use crate::accel::bvh::BvhStats;
use crate::device::Device;
use crate::gpu::BvhMemory;
use crate::{LayoutKind, TraversalMode};

use super::{RenderOptions, Rendered, Renderer, Stop};

/// `render --stats --json`: one object. Times in milliseconds unless named seconds; null
/// where a key does not apply.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// The image written.
    pub output: String,
    /// Its width in pixels (the tile's with a crop).
    pub width: u32,
    /// Its height in pixels.
    pub height: u32,
    /// The full image's width.
    pub full_width: u32,
    /// The full image's height.
    pub full_height: u32,
    /// [x0, y0, x1, y1] with a crop.
    pub crop: Option<[u32; 4]>,
    /// Samples per pixel taken.
    pub samples: u32,
    /// Samples per pixel asked for.
    pub requested: u32,
    /// "complete", "time-limit" or "cancelled".
    pub stop: &'static str,
    /// The device, in words.
    pub device: String,
    /// bvh, kdtree, octree, bih, grid, grid2 or hashgrid.
    pub structure: &'static str,
    /// The BVH's flattened layout (a BVH only).
    pub layout: Option<&'static str>,
    /// triangles, nodes, leaves, max_depth, sah_cost (a BVH over one mesh only).
    pub bvh: Option<BvhStats>,
    /// A scene with copies, rendered in two levels: its instances.
    pub instances: Option<usize>,
    /// A scene with copies, rendered in two levels: the triangles its instances place.
    pub instanced_triangles: Option<u64>,
    /// The effects simulated, space-separated.
    pub effects: String,
    /// GPU: textures or buffers.
    pub bvh_memory: Option<String>,
    /// GPU: the traversal mode that ran, per-ray or subgroup.
    pub mode: Option<&'static str>,
    /// Building (and flattening) the structure.
    pub build_ms: f64,
    /// GPU: uploading the structure and scene, creating the shader module (0 on the CPU).
    pub upload_ms: f64,
    /// GPU: the driver compiling the pipeline before the first sample (0 on the CPU).
    pub compile_ms: f64,
    /// The first sample, compilation excluded.
    pub first_sample_ms: f64,
    /// Mean per sample per pixel.
    pub ms_per_spp: f64,
    /// All samples.
    pub seconds: f64,
    /// Camera rays (one per pixel per sample) per second.
    pub camera_rays_per_s: f64,
    /// GPU: pixels whose samples the driver cut short, rendered again on the CPU.
    pub cpu_pixels: usize,
    /// The structure in words, e.g. "bvh (dfs-sign)" (the text's; not serialised).
    #[serde(skip)]
    pub structure_text: String,
    /// The traversal mode asked for (the text's; not serialised).
    #[serde(skip)]
    pub asked: TraversalMode,
    /// The BVH layout asked for (the text's; not serialised).
    #[serde(skip)]
    pub layout_asked: &'static str,
}

impl RenderStats {
    /// The statistics of `done`, rendered by `renderer` on `device` with `options` into
    /// `output`; `full` is the full image's size, `layout` the BVH layout asked for.
    pub fn new(
        renderer: &Renderer,
        done: &Rendered,
        device: &Device,
        options: &RenderOptions,
        full: (u32, u32),
        layout: LayoutKind,
        output: &Path,
    ) -> RenderStats {
        let (w, h) = (done.image.width, done.image.height);
        let gpu = !device.is_cpu();
        RenderStats {
            output: output.display().to_string(),
            width: w,
            height: h,
            full_width: full.0,
            full_height: full.1,
            crop: options.crop.map(|c| [c.x0, c.y0, c.x1, c.y1]),
            samples: done.samples,
            requested: done.requested,
            stop: match done.stop {
                Stop::Complete => "complete",
                Stop::TimeLimit => "time-limit",
                Stop::Cancelled => "cancelled",
            },
            device: device.to_string(),
            structure: renderer.structure().name(),
            layout: renderer.bvh_stats().map(|_| layout.name()),
            bvh: renderer.bvh_stats().copied(),
            instances: renderer.placements().map(|p| p.set().instances.len()),
            instanced_triangles: renderer.placements().map(|p| p.set().triangle_count()),
            effects: done.effects.to_string(),
            bvh_memory: gpu.then(|| memory_name(options.memory).to_string()),
            mode: gpu.then(|| done.mode.name()),
            build_ms: renderer.build_ms(),
            upload_ms: renderer.upload_ms(),
            compile_ms: done.compile_ms,
            first_sample_ms: done.first_sample_ms,
            ms_per_spp: done.seconds * 1e3 / done.samples as f64,
            seconds: done.seconds,
            camera_rays_per_s: done.samples as f64 * (w as f64 * h as f64) / done.seconds,
            cpu_pixels: done.cpu_pixels,
            structure_text: renderer.structure().to_string(),
            asked: options.mode,
            layout_asked: layout.name(),
        }
    }

    /// The lines `lancer render --stats` prints.
    pub fn text(&self) -> Vec<String> {
        let mut lines = vec![format!(
            "structure: {}  build {:.1} ms",
            self.structure_text, self.build_ms
        )];
        if let (Some(s), Some(layout)) = (&self.bvh, self.layout) {
            lines.push(format!(
                "triangles {}  nodes {}  leaves {}  max depth {}  SAH {:.2}",
                s.triangles, s.nodes, s.leaves, s.max_depth, s.sah_cost,
            ));
            lines.push(format!("layout: {layout}"));
        }
        if let (Some(n), Some(tris)) = (self.instances, self.instanced_triangles) {
            lines.push(format!(
                "two levels: {n} instances placing {tris} triangles, layout {}",
                self.layout_asked
            ));
        }
        lines.push(format!("effects: {}", self.effects));
        if let (Some(memory), Some(mode)) = (&self.bvh_memory, self.mode) {
            lines.push(format!("BVH memory: {memory}"));
            if mode == self.asked.name() {
                lines.push(format!("mode: {mode}"));
            } else {
                lines.push(format!(
                    "mode: {mode} ({} asked for, see the warning)",
                    self.asked
                ));
            }
            lines.push(format!(
                "upload + shader module {:.1} ms, pipeline compile {:.1} ms",
                self.upload_ms, self.compile_ms
            ));
        }
        lines.push(format!(
            "first sample {:.1} ms; {:.2} M camera rays/s, {:.1} ms per spp",
            self.first_sample_ms,
            self.camera_rays_per_s * 1e-6,
            self.ms_per_spp
        ));
        lines
    }
}

/// Where the BVH lives, as the command line spells it.
fn memory_name(memory: BvhMemory) -> &'static str {
    match memory {
        BvhMemory::Buffers => "buffers",
        BvhMemory::Textures => "textures",
    }
}
