//! BVH traversal on the GPU: the flat BVH uploaded once, rays traced in batches (bounded by
//! the binding limit) of short dispatches (no dispatch runs for seconds).

use std::collections::HashMap;
use std::time::Instant;

use super::{shaders, BvhMemory, GpuBvh, GpuContext};
use crate::accel::bvh::FlatBvh;
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, TriangleTest};
use crate::trace::{Query, RayStats};

/// Rays per dispatch: ~10–20 ms on lavapipe, far less on a real GPU.
const CHUNK: usize = 1 << 18;
/// Rays per batch at most (further bounded by the storage binding limit).
const MAX_BATCH: usize = 1 << 22;

/// Which specialisation of the traversal kernel to run (all from one WGSL source).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TraceKernel {
    pub query: Query,
    pub test: TriangleTest,
    /// Count nodes visited and triangles tested per ray.
    pub stats: bool,
    pub workgroup_size: u32,
    /// Shader module created without bounds checks and loop bounding. Only offered for a
    /// BVH that [`FlatBvh::validate`] accepted (GpuTracer::new checks it).
    pub trusted: bool,
}

impl Default for TraceKernel {
    fn default() -> Self {
        TraceKernel {
            query: Query::Closest,
            test: TriangleTest::Watertight,
            stats: false,
            workgroup_size: 64,
            trusted: false,
        }
    }
}

/// Times of one `trace` call.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuTimings {
    /// Sum of the dispatches' GPU time from timestamp queries (None without support).
    pub gpu_ms: Option<f64>,
    /// Wall time of the whole call: upload, dispatches, readback.
    pub wall_ms: f64,
}

/// Uniform of one dispatch (WGSL `Params`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Params {
    pub offset: u32,
    pub count: u32,
}

/// Hits, per-ray statistics (when counted) and GPU nanoseconds (when timed) of one batch.
type BatchResult = (Vec<Hit>, Option<Vec<RayStats>>, Option<f64>);

pub struct GpuTracer<'a> {
    ctx: &'a GpuContext,
    bvh: GpuBvh,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    checked: wgpu::ShaderModule,
    trusted: wgpu::ShaderModule,
    pipelines: HashMap<TraceKernel, wgpu::ComputePipeline>,
}

pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl<'a> GpuTracer<'a> {
    /// Validates and uploads a flat BVH in the default memory.
    pub fn new(ctx: &'a GpuContext, flat: &FlatBvh) -> Result<GpuTracer<'a>> {
        Self::with_memory(ctx, flat, BvhMemory::default())
    }

    /// Validates and uploads a flat BVH in the given memory.
    pub fn with_memory(
        ctx: &'a GpuContext,
        flat: &FlatBvh,
        memory: BvhMemory,
    ) -> Result<GpuTracer<'a>> {
        let bvh = GpuBvh::upload(ctx, flat, memory)?;
        let dev = &ctx.device;
        let [nodes, tris, node_texels, tri_texels] = GpuBvh::layout_entries();
        let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("traverse"),
            entries: &[
                nodes,
                tris,
                node_texels,
                tri_texels,
                storage_entry(2, true),
                storage_entry(3, false),
                storage_entry(4, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 5,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(8),
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("traverse"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let src = shaders::traverse_source();
        let desc = || wgpu::ShaderModuleDescriptor {
            label: Some("traverse.wgsl"),
            source: wgpu::ShaderSource::Wgsl(src.as_str().into()),
        };
        let checked = dev.create_shader_module(desc());
        // SAFETY: GpuBvh::upload above validated the BVH (indices in range, depth within
        // the stack), and every ray index is guarded by params.count.
        let trusted = unsafe {
            dev.create_shader_module_trusted(desc(), wgpu::ShaderRuntimeChecks::unchecked())
        };
        Ok(GpuTracer {
            ctx,
            bvh,
            layout,
            pipeline_layout,
            checked,
            trusted,
            pipelines: HashMap::new(),
        })
    }

    /// Where this tracer's BVH lives on the device.
    pub fn memory(&self) -> BvhMemory {
        self.bvh.memory
    }

    fn pipeline(&mut self, k: TraceKernel) -> &wgpu::ComputePipeline {
        let (dev, pl) = (&self.ctx.device, &self.pipeline_layout);
        let memory = self.bvh.override_constant();
        let module = if k.trusted {
            &self.trusted
        } else {
            &self.checked
        };
        self.pipelines.entry(k).or_insert_with(|| {
            let b = |x: bool| if x { 1.0 } else { 0.0 };
            let constants = [
                ("ANY_HIT", b(k.query == Query::Any)),
                ("COUNT_STATS", b(k.stats)),
                ("MOLLER_TRUMBORE", b(k.test == TriangleTest::MollerTrumbore)),
                ("WORKGROUP_SIZE", k.workgroup_size as f64),
                memory,
            ];
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("traverse"),
                layout: Some(pl),
                module,
                entry_point: Some("trace"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        })
    }

    /// Traces rays; returns hits, per-ray statistics when `kernel.stats`, and timings.
    pub fn trace(
        &mut self,
        rays: &[Ray],
        kernel: TraceKernel,
    ) -> Result<(Vec<Hit>, Option<Vec<RayStats>>, GpuTimings)> {
        let start = Instant::now();
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        let batch = rays.len().clamp(1, MAX_BATCH.min((limit / 32) as usize));
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
        let timings = GpuTimings {
            gpu_ms: gpu_ns.map(|ns| ns * 1e-6),
            wall_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        Ok((hits, stats, timings))
    }

    fn trace_batch(&mut self, rays: &[Ray], kernel: TraceKernel) -> Result<BatchResult> {
        let n = rays.len().max(1);
        let chunks = n.div_ceil(CHUNK);
        let align = self.ctx.limits.min_uniform_buffer_offset_alignment.max(8) as usize;
        let mut params = vec![0u8; chunks * align];
        for c in 0..chunks {
            let p = Params {
                offset: (c * CHUNK) as u32,
                count: (rays.len() - (c * CHUNK).min(rays.len())).min(CHUNK) as u32,
            };
            params[c * align..c * align + 8].copy_from_slice(bytemuck::bytes_of(&p));
        }
        let dev = &self.ctx.device;
        // Upload straight from the caller's slice; an empty batch binds one zero ray.
        let zero = [0u8; 32];
        let ray_bytes: &[u8] = if rays.is_empty() {
            &zero
        } else {
            bytemuck::cast_slice(rays)
        };
        let ray_buf = self
            .ctx
            .buffer_with("rays", ray_bytes, wgpu::BufferUsages::STORAGE);
        let param_buf = self
            .ctx
            .buffer_with("params", &params, wgpu::BufferUsages::UNIFORM);
        let hit_size = (n * 16) as u64;
        let stat_size = if kernel.stats { (n * 8) as u64 } else { 8 };
        let storage = |label, size| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let hit_buf = storage("hits", hit_size);
        let stat_buf = storage("stats", stat_size);
        let readback = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: hit_size + stat_size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let [nodes, tris, node_texels, tri_texels] = self.bvh.bind_entries();
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("traverse"),
            layout: &self.layout,
            entries: &[
                nodes,
                tris,
                node_texels,
                tri_texels,
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ray_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: hit_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: stat_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &param_buf,
                        offset: 0,
                        size: wgpu::BufferSize::new(8),
                    }),
                },
            ],
        });
        let timed = self.ctx.timestamps && chunks * 2 <= wgpu::QUERY_SET_MAX_QUERIES as usize;
        let queries = timed.then(|| {
            let set = dev.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("dispatch times"),
                ty: wgpu::QueryType::Timestamp,
                count: (chunks * 2) as u32,
            });
            let size = (chunks * 2 * 8) as u64;
            let resolve = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        let wg = kernel.workgroup_size.max(1);
        let pipeline = self.pipeline(kernel).clone();
        let mut enc = dev.create_command_encoder(&Default::default());
        for c in 0..chunks {
            let count = (n - c * CHUNK).min(CHUNK) as u32;
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace"),
                timestamp_writes: queries.as_ref().map(|(set, _, _)| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some((2 * c) as u32),
                        end_of_pass_write_index: Some((2 * c + 1) as u32),
                    }
                }),
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[(c * align) as u32]);
            pass.dispatch_workgroups(count.div_ceil(wg), 1, 1);
        }
        enc.copy_buffer_to_buffer(&hit_buf, 0, &readback, 0, hit_size);
        enc.copy_buffer_to_buffer(&stat_buf, 0, &readback, hit_size, stat_size);
        if let Some((set, resolve, read)) = &queries {
            enc.resolve_query_set(set, 0..(chunks * 2) as u32, resolve, 0);
            enc.copy_buffer_to_buffer(resolve, 0, read, 0, resolve.size());
        }
        self.ctx.queue.submit([enc.finish()]);

        let mut buffers = vec![&readback];
        if let Some((_, _, read)) = &queries {
            buffers.push(read);
        }
        for b in &buffers {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                if let Err(e) = r {
                    eprintln!("error: GPU readback failed: {e}");
                }
            });
        }
        dev.poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("GPU did not finish: {e}")))?;
        let map_err = |e| Error::Gpu(format!("GPU readback failed: {e}"));
        let (hits, stats) = {
            let view = readback.get_mapped_range(..).map_err(map_err)?;
            let hits: Vec<Hit> = bytemuck::cast_slice(&view[..rays.len() * 16]).to_vec();
            let stats = kernel.stats.then(|| {
                bytemuck::cast_slice(&view[hit_size as usize..hit_size as usize + rays.len() * 8])
                    .to_vec()
            });
            (hits, stats)
        };
        readback.unmap();
        let ns = match &queries {
            Some((_, _, read)) => {
                let view = read.get_mapped_range(..).map_err(map_err)?;
                let ts: &[u64] = bytemuck::cast_slice(&view);
                let period = self.ctx.queue.get_timestamp_period() as f64;
                Some(
                    ts.chunks(2)
                        .map(|p| p[1].saturating_sub(p[0]) as f64 * period)
                        .sum(),
                )
            }
            None => None,
        };
        Ok((hits, stats, ns))
    }
}
