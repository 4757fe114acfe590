//! The trace kernel: a layout uploaded once, rays traced in batches (bounded by the binding
//! limit) of short dispatches (no dispatch runs for seconds).

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

use super::plumbing::{
    buffer_binding, dynamic_uniform_entry, output_buffer, storage_entry, uniform_binding, Chunks,
    Kernel, Readback, Timer,
};
use super::{bindings, shaders, BufferParts, BvhMemory, GpuBvh, GpuContext};
use crate::accel::GpuForm;
use crate::accel::TraversalMode;
use crate::accel::{Query, RayStats};
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, Robustness};

/// The prim the trace kernel reports for a ray whose traversal did not end by itself: the
/// driver cut it short (see `traversal_done` in shaders/lib/traversal.wgsl), or a subgroup
/// traversal found lanes it cannot spread its stack over. [`Tracer`](crate::Tracer) traces
/// such rays again on the CPU twin. Never a triangle index: meshes hold fewer triangles.
pub const INCOMPLETE: u32 = u32::MAX - 1;

/// Rays per dispatch: ~10–20 ms on lavapipe, far less on a real GPU.
pub(super) const CHUNK: u32 = 1 << 18;
/// Storage buffers the trace kernel binds with the BVH's arrays in one part each (nodes,
/// triangles, rays, hits, statistics).
pub(super) const TRACE_STORAGE_BUFFERS: u32 = 5;

/// Rays per batch at most (further bounded by the storage binding limit).
const MAX_BATCH: usize = 1 << 22;

/// Rays per batch: at most [`MAX_BATCH`] and what one storage binding holds (32 bytes a ray).
pub(super) fn batch_len(ctx: &GpuContext, rays: usize) -> usize {
    let limit = (ctx.limits.max_storage_buffer_binding_size).min(ctx.limits.max_buffer_size);
    // At least one ray even where a device's limits hold none (then the upload refuses it).
    rays.clamp(1, MAX_BATCH.min((limit / 32) as usize).max(1))
}

/// Which specialisation of the trace kernel to run (all from one WGSL source).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TraceKernel {
    /// Closest or any hit.
    pub query: Query,
    /// Triangle and slab tests; `checked_module: false` runs the trusted module.
    pub robustness: Robustness,
    /// Count nodes visited and triangles tested per ray.
    pub stats: bool,
    /// Invocations per workgroup.
    pub workgroup_size: u32,
    /// One ray per invocation, or the lanes of a subgroup together (see
    /// [`GpuTracer::subgroup_unavailable`]).
    pub mode: TraversalMode,
}

impl Default for TraceKernel {
    fn default() -> Self {
        TraceKernel {
            query: Query::Closest,
            robustness: Robustness::default(),
            stats: false,
            workgroup_size: 64,
            mode: TraversalMode::PerRay,
        }
    }
}

/// Times of one `trace` call.
#[derive(Clone, Copy, Debug, Default)]
pub struct Timings {
    /// Sum of the dispatches' GPU time from timestamp queries (None on the CPU or without
    /// timestamp support).
    pub gpu_ms: Option<f64>,
    /// Wall time of the whole call (GPU: upload, dispatches, readback).
    pub wall_ms: f64,
}

/// Uniform of one dispatch (WGSL `Params` in trace.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TraceParams {
    /// First ray of this dispatch.
    pub offset: u32,
    /// Rays in this dispatch.
    pub count: u32,
}

/// Hits, per-ray statistics (when counted) and GPU nanoseconds (when timed) of one batch.
type BatchResult = (Vec<Hit>, Option<Vec<RayStats>>, Option<f64>);

/// A layout on the device and the trace kernel compiled for it.
pub struct GpuTracer<'a> {
    ctx: &'a GpuContext,
    bvh: GpuBvh,
    layout: &'static str,
    layout_constants: Vec<(&'static str, f64)>,
    entries: Vec<wgpu::BindGroupLayoutEntry>,
    /// Per-ray kernel, and the subgroup kernel once asked for.
    kernels: HashMap<TraversalMode, Kernel>,
    /// The subgroup kernel's source, where both the adapter and the layout have one.
    subgroup_source: Option<String>,
    pipelines: HashMap<TraceKernel, wgpu::ComputePipeline>,
}

impl<'a> GpuTracer<'a> {
    /// Writes `bytes` over the uploaded node words from word `first` on
    /// ([`GpuBvh::write_node_words`]): the caller has checked the structure they make.
    pub fn write_node_words(&self, first: u32, bytes: &[u8]) -> Result<()> {
        self.bvh.write_node_words(self.ctx, first, bytes)
    }

    /// [`GpuTracer::write_node_words`] for the triangles' words.
    pub fn write_tri_words(&self, first: u32, bytes: &[u8]) -> Result<()> {
        self.bvh.write_tri_words(self.ctx, first, bytes)
    }

    /// Validates and uploads a layout in the given memory and compiles the kernel.
    pub fn new(ctx: &'a GpuContext, layout: &dyn GpuForm, memory: BvhMemory) -> Result<Self> {
        Self::new_with(ctx, layout, memory, None)
    }

    /// [`GpuTracer::new`] over a layout nothing changes while it is uploaded
    /// ([`GpuBvh::upload_shared`]: where the device's memory is the host's, its arrays are
    /// read in place); its words cannot be written over.
    pub fn new_shared(
        ctx: &'a GpuContext,
        layout: &Arc<dyn GpuForm>,
        memory: BvhMemory,
    ) -> Result<Self> {
        Self::new_with(ctx, layout.as_ref(), memory, Some(layout))
    }

    fn new_with(
        ctx: &'a GpuContext,
        layout: &dyn GpuForm,
        memory: BvhMemory,
        shared: Option<&Arc<dyn GpuForm>>,
    ) -> Result<Self> {
        let start = std::time::Instant::now();
        // The kernel's bindings checked before anything is uploaded.
        let parts = GpuBvh::checked_parts(ctx, layout, memory)?;
        parts.check(ctx, "trace", TRACE_STORAGE_BUFFERS, false)?;
        let bvh = match shared {
            Some(layout) => GpuBvh::upload_shared(ctx, layout, memory)?,
            None => GpuBvh::upload(ctx, layout, memory)?,
        };
        log::info!(
            "{} layout checked, packed and uploaded ({memory:?}) in {:.0} ms",
            layout.name(),
            start.elapsed().as_secs_f64() * 1e3
        );
        let mut entries = bvh.layout_entries();
        entries.extend([
            storage_entry(bindings::TRACE_RAYS, true),
            storage_entry(bindings::TRACE_HITS, false),
            storage_entry(bindings::TRACE_STATS, false),
            dynamic_uniform_entry(bindings::TRACE_PARAMS, 8),
        ]);
        // Trusted modules are safe here: GpuBvh::upload validated the layout, and every
        // ray index is guarded by params.count.
        let kernel = Kernel::new(
            ctx,
            "trace",
            "trace",
            &shaders::trace_source(layout, &parts),
            &entries,
            true,
        )?;
        let subgroup_source =
            (ctx.subgroups).and_then(|_| shaders::trace_subgroup_source(layout, &parts));
        Ok(GpuTracer {
            ctx,
            bvh,
            layout: layout.name(),
            layout_constants: layout.overrides(),
            entries,
            kernels: HashMap::from([(TraversalMode::PerRay, kernel)]),
            subgroup_source,
            pipelines: HashMap::new(),
        })
    }

    /// Why the subgroup mode cannot run here with this workgroup size (the adapter has no
    /// subgroup operations, the layout no subgroup traversal, or the workgroup is not a
    /// whole number of the adapter's largest subgroups), or None when it can.
    pub fn subgroup_unavailable(&self, workgroup_size: u32) -> Option<String> {
        // Without subgroups there is no source either; the context names the adapter first.
        let has_one = self.subgroup_source.is_some();
        (self.ctx).subgroup_unavailable(self.layout, has_one, workgroup_size)
    }

    /// The compiled kernel of a mode (compiled on first use).
    fn kernel(&mut self, mode: TraversalMode) -> Result<&Kernel> {
        if !self.kernels.contains_key(&mode) {
            let Some(source) = self.subgroup_source.as_deref() else {
                return Err(Error::Usage(format!(
                    "no {mode} trace kernel for the {} layout on {}",
                    self.layout, self.ctx.adapter.name
                )));
            };
            let kernel = Kernel::new(self.ctx, "trace", "trace", source, &self.entries, true)?;
            self.kernels.insert(mode, kernel);
        }
        self.kernels
            .get(&mode)
            .ok_or_else(|| Error::Gpu(format!("the {mode} trace kernel is missing")))
    }

    /// Where this tracer's BVH lives on the device.
    pub fn memory(&self) -> BvhMemory {
        self.bvh.memory
    }

    /// The parts its node and triangle buffers are bound in (1 each in texture memory, and
    /// for arrays that one storage binding holds).
    pub fn parts(&self) -> BufferParts {
        self.bvh.parts()
    }

    /// Whether its nodes and triangles are read where the host holds them
    /// ([`GpuTracer::new_shared`]) rather than copied.
    pub fn in_place(&self) -> [bool; 2] {
        self.bvh.in_place()
    }

    fn pipeline(&mut self, k: TraceKernel) -> Result<wgpu::ComputePipeline> {
        if let Some(p) = self.pipelines.get(&k) {
            return Ok(p.clone());
        }
        let b = |x: bool| if x { 1.0 } else { 0.0 };
        let mut constants = vec![
            ("ANY_HIT", b(k.query == Query::Any)),
            ("COUNT_STATS", b(k.stats)),
            ("WORKGROUP_SIZE", k.workgroup_size as f64),
            self.bvh.override_constant(),
        ];
        constants.extend(k.robustness.overrides());
        constants.extend(self.layout_constants.iter().copied());
        let ctx = self.ctx;
        let p = (self.kernel(k.mode)?).pipeline(ctx, &constants, !k.robustness.checked_module)?;
        self.pipelines.insert(k, p.clone());
        Ok(p)
    }

    /// Refuses a workgroup size the adapter cannot run, naming its limits.
    fn check_workgroup(&self, size: u32) -> Result<()> {
        let l = &self.ctx.limits;
        let max = l
            .max_compute_workgroup_size_x
            .min(l.max_compute_invocations_per_workgroup);
        if size == 0 || size > max {
            return Err(Error::Usage(format!(
                "workgroup size {size} is outside 1..={max}, what {} allows",
                self.ctx.adapter.name
            )));
        }
        Ok(())
    }

    /// Traces rays; returns hits, per-ray statistics when `kernel.stats`, and timings.
    /// A mode that cannot run here is refused with the reason
    /// ([`Tracer`](crate::Tracer) falls back to per-ray instead).
    pub fn trace(
        &mut self,
        rays: &[Ray],
        kernel: TraceKernel,
    ) -> Result<(Vec<Hit>, Option<Vec<RayStats>>, Timings)> {
        self.check_workgroup(kernel.workgroup_size)?;
        kernel.robustness.check_gpu()?;
        if kernel.mode == TraversalMode::Subgroup {
            if let Some(why) = self.subgroup_unavailable(kernel.workgroup_size) {
                return Err(Error::Usage(format!("no subgroup traversal: {why}")));
            }
        }
        if !self.pipelines.contains_key(&kernel) {
            // A driver may compile at the first dispatch (lavapipe does): an empty batch,
            // one workgroup with no ray, does that before the timings start.
            self.trace_batch(&[], kernel)?;
        }
        let start = Instant::now();
        let batch = batch_len(self.ctx, rays.len());
        let mut hits = Vec::with_capacity(rays.len());
        let mut stats = kernel.stats.then(|| Vec::with_capacity(rays.len()));
        let mut gpu_ns = Some(0.0f64);
        for part in rays.chunks(batch) {
            let (h, s, ns) = self.trace_batch(part, kernel)?;
            hits.extend_from_slice(&h);
            if let (Some(all), Some(s)) = (stats.as_mut(), s) {
                all.extend_from_slice(&s);
            }
            gpu_ns = gpu_ns.zip(ns).map(|(a, b)| a + b);
        }
        let timings = Timings {
            gpu_ms: gpu_ns.map(|ns| ns * 1e-6),
            wall_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        Ok((hits, stats, timings))
    }

    fn trace_batch(&mut self, rays: &[Ray], kernel: TraceKernel) -> Result<BatchResult> {
        let ctx = self.ctx;
        // Compiles the mode's kernel on first use.
        let pipeline = self.pipeline(kernel)?;
        let chunks = Chunks::new(ctx, rays.len() as u32, CHUNK, 8);
        let params = chunks.uniforms(|offset, count| TraceParams { offset, count });
        // Upload straight from the caller's slice; an empty batch binds one zero ray.
        let zero = [0u8; 32];
        let ray_bytes: &[u8] = if rays.is_empty() {
            &zero
        } else {
            bytemuck::cast_slice(rays)
        };
        let ray_buf = ctx.buffer_with("rays", ray_bytes, wgpu::BufferUsages::STORAGE);
        let param_buf = ctx.buffer_with("params", &params, wgpu::BufferUsages::UNIFORM);
        let hit_size = rays.len() as u64 * 16;
        let stat_size = if kernel.stats {
            rays.len() as u64 * 8
        } else {
            0
        };
        let hit_buf = output_buffer(ctx, "hits", hit_size);
        let stat_buf = output_buffer(ctx, "stats", stat_size);
        let mut entries = self.bvh.bind_entries();
        entries.extend([
            buffer_binding(bindings::TRACE_RAYS, &ray_buf),
            buffer_binding(bindings::TRACE_HITS, &hit_buf),
            buffer_binding(bindings::TRACE_STATS, &stat_buf),
            uniform_binding(bindings::TRACE_PARAMS, &param_buf, 8),
        ]);
        let bind = (self.kernels.get(&kernel.mode))
            .ok_or_else(|| Error::Gpu(format!("the {} trace kernel is missing", kernel.mode)))?
            .bind(ctx, &entries)?;
        let timer = Timer::new(ctx, chunks.count());
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        chunks.record(
            &mut enc,
            &pipeline,
            &bind,
            kernel.workgroup_size,
            timer.as_ref(),
        );
        if let Some(t) = &timer {
            t.resolve(&mut enc);
        }
        let mut from = vec![(&hit_buf, hit_size), (&stat_buf, stat_size)];
        if let Some(t) = &timer {
            from.push((t.buffer(), t.buffer().size()));
        }
        let readback = Readback::record(ctx, &mut enc, &from);
        ctx.queue.submit([enc.finish()]);
        let parts = readback.read(ctx)?;
        let hits: Vec<Hit> = bytemuck::pod_collect_to_vec(&parts[0]);
        let stats = kernel
            .stats
            .then(|| bytemuck::pod_collect_to_vec(&parts[1]));
        let ns = timer.map(|_| Timer::nanoseconds(ctx, &parts[2]));
        Ok((hits, stats, ns))
    }
}
