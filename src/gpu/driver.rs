//! The driver's own traversal: Vulkan ray queries (wgpu's experimental ray-query feature) on
//! an acceleration structure the driver builds from a layout's leaf triangles. It shows how
//! far a compute layout is from the vendor's traversal (the `driver` row of `bench layouts`)
//! and is an independent oracle for `lancer check`. Its t comes from the driver's own
//! arithmetic: it agrees with lancer within the f64 oracle's tolerance, not bit for bit.
//!
//! The triangles go in in the layout's leaf order (the BVH's spatial order): a driver that
//! builds its tree by index order (lavapipe does) traces a file-order mesh far slower.

use std::time::Instant;

use super::plumbing::{
    buffer_binding, dynamic_uniform_entry, output_buffer, storage_entry, uniform_binding, wait,
    Chunks, Kernel, Readback, Timer,
};
use super::trace::{batch_len, CHUNK};
use super::{bindings, shaders, GpuContext, Timings, TraceParams};
use crate::accel::Query;
use crate::accel::{GpuForm, LeafTri};
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray};

/// Bytes between vertices in a [`LeafTri`]: each vertex is a 16-byte word (xyz, then a spare
/// slot), so the leaf triangle array is the driver's vertex buffer as it is.
const VERTEX_STRIDE: u64 = 16;

/// A layout's triangles in the driver's acceleration structure, and the kernel that traces
/// rays through it with ray queries.
pub struct DriverTracer<'a> {
    ctx: &'a GpuContext,
    tris: wgpu::Buffer,
    triangles: u32,
    /// The top-level structure the kernel binds (it keeps its one instance's bottom level
    /// alive).
    tlas: Option<wgpu::Tlas>,
    kernel: Kernel,
    /// Pipelines for closest and any hit.
    pipelines: [Option<wgpu::ComputePipeline>; 2],
    /// Wall time of the driver's build, ms.
    build_ms: f64,
}

impl<'a> DriverTracer<'a> {
    /// Has the driver build its acceleration structure over the layout's leaf triangles and
    /// compiles the kernel. Refused where the device has no ray queries
    /// ([`GpuContext::ray_query`]).
    pub fn new(ctx: &'a GpuContext, layout: &dyn GpuForm) -> Result<Self> {
        if !ctx.ray_query {
            return Err(Error::Gpu(format!(
                "{} offers no ray queries (wgpu's EXPERIMENTAL_RAY_QUERY): the driver row needs \
                 a driver that has them, such as lavapipe from Mesa 25",
                ctx.adapter
            )));
        }
        let tri_bytes = layout.arrays().tris;
        let n = tri_bytes.len() / std::mem::size_of::<LeafTri>();
        let max = ctx.limits.max_blas_primitive_count;
        let triangles = u32::try_from(n)
            .ok()
            .filter(|&t| t <= max && t.checked_mul(3).is_some())
            .ok_or_else(|| {
                Error::Gpu(format!(
                    "{n} triangles are more than {} builds into one acceleration structure \
                     ({max}, max_blas_primitive_count)",
                    ctx.adapter.name
                ))
            })?;
        ctx.check_binding("the leaf triangles", tri_bytes.len() as u64)?;
        // An empty array still binds one word.
        let zero = [0u8; 48];
        let tris = ctx.buffer_with(
            "driver triangles",
            if n == 0 { &zero } else { tri_bytes },
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::BLAS_INPUT,
        );
        let entries = [
            wgpu::BindGroupLayoutEntry {
                binding: bindings::DRIVER_SCENE,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::AccelerationStructure {
                    vertex_return: false,
                },
                count: None,
            },
            storage_entry(bindings::TRI_WORDS, true),
            storage_entry(bindings::TRACE_RAYS, true),
            storage_entry(bindings::TRACE_HITS, false),
            dynamic_uniform_entry(bindings::TRACE_PARAMS, 8),
        ];
        let kernel = Kernel::new(
            ctx,
            "driver trace",
            "trace",
            &shaders::driver_trace_source(),
            &entries,
            false,
        )?;
        let mut tracer = DriverTracer {
            ctx,
            tris,
            triangles,
            tlas: None,
            kernel,
            pipelines: [None, None],
            build_ms: 0.0,
        };
        if triangles > 0 {
            tracer.build()?;
        }
        Ok(tracer)
    }

    /// Wall time the driver took to build its acceleration structure, ms.
    pub fn build_ms(&self) -> f64 {
        self.build_ms
    }

    fn build(&mut self) -> Result<()> {
        let ctx = self.ctx;
        let start = Instant::now();
        let size = wgpu::BlasTriangleGeometrySizeDescriptor {
            vertex_format: wgpu::VertexFormat::Float32x3,
            vertex_count: 3 * self.triangles,
            index_format: None,
            index_count: None,
            flags: wgpu::AccelerationStructureGeometryFlags::OPAQUE,
        };
        let tlas = super::plumbing::scoped(ctx, "building the driver's structure", || {
            let blas = ctx.device.create_blas(
                &wgpu::CreateBlasDescriptor {
                    label: Some("driver blas"),
                    flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                    update_mode: wgpu::AccelerationStructureUpdateMode::Build,
                },
                wgpu::BlasGeometrySizeDescriptors::Triangles {
                    descriptors: vec![size.clone()],
                },
            );
            let mut tlas = ctx.device.create_tlas(&wgpu::CreateTlasDescriptor {
                label: Some("driver tlas"),
                flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                update_mode: wgpu::AccelerationStructureUpdateMode::Build,
                max_instances: 1,
            });
            // The identity transform, rows of a 3×4 matrix.
            let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
            tlas[0] = Some(wgpu::TlasInstance::new(&blas, identity, 0, 0xff));
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.build_acceleration_structures(
                std::iter::once(&wgpu::BlasBuildEntry {
                    blas: &blas,
                    geometry: wgpu::BlasGeometries::TriangleGeometries(vec![
                        wgpu::BlasTriangleGeometry {
                            size: &size,
                            vertex_buffer: &self.tris,
                            first_vertex: 0,
                            vertex_stride: VERTEX_STRIDE,
                            index_buffer: None,
                            first_index: None,
                            transform_buffer: None,
                            transform_buffer_offset: None,
                        },
                    ]),
                }),
                std::iter::once(&tlas),
            );
            ctx.queue.submit([enc.finish()]);
            tlas
        })?;
        wait(ctx)?;
        self.tlas = Some(tlas);
        self.build_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    fn pipeline(&mut self, query: Query, workgroup_size: u32) -> Result<wgpu::ComputePipeline> {
        let slot = usize::from(query == Query::Any);
        if let Some(p) = &self.pipelines[slot] {
            return Ok(p.clone());
        }
        let any = if query == Query::Any { 1.0 } else { 0.0 };
        let constants = [("ANY_HIT", any), ("WORKGROUP_SIZE", workgroup_size as f64)];
        let p = self.kernel.pipeline(self.ctx, &constants, false)?;
        self.pipelines[slot] = Some(p.clone());
        Ok(p)
    }

    /// Traces rays with the driver's ray queries (workgroups of 64); returns hits (original
    /// triangle indices, [`Hit::miss`] on a miss or an invalid ray) and timings.
    pub fn trace(&mut self, rays: &[Ray], query: Query) -> Result<(Vec<Hit>, Timings)> {
        const WORKGROUP: u32 = 64;
        let start = Instant::now();
        let Some(tlas) = self.tlas.clone() else {
            let misses = rays.iter().map(|r| Hit::miss(r.tmax)).collect();
            let wall_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok((
                misses,
                Timings {
                    gpu_ms: None,
                    wall_ms,
                },
            ));
        };
        let pipeline = self.pipeline(query, WORKGROUP)?;
        let ctx = self.ctx;
        let mut hits = Vec::with_capacity(rays.len());
        let mut gpu_ns = Some(0.0f64);
        for part in rays.chunks(batch_len(ctx, rays.len())) {
            let chunks = Chunks::new(ctx, part.len() as u32, CHUNK, 8);
            let params = chunks.uniforms(|offset, count| TraceParams { offset, count });
            let zero = [0u8; 32];
            let ray_bytes: &[u8] = if part.is_empty() {
                &zero
            } else {
                bytemuck::cast_slice(part)
            };
            let ray_buf = ctx.buffer_with("rays", ray_bytes, wgpu::BufferUsages::STORAGE);
            let param_buf = ctx.buffer_with("params", &params, wgpu::BufferUsages::UNIFORM);
            let hit_size = part.len() as u64 * 16;
            let hit_buf = output_buffer(ctx, "hits", hit_size);
            let bind = self.kernel.bind(
                ctx,
                &[
                    wgpu::BindGroupEntry {
                        binding: bindings::DRIVER_SCENE,
                        resource: tlas.as_binding(),
                    },
                    buffer_binding(bindings::TRI_WORDS, &self.tris),
                    buffer_binding(bindings::TRACE_RAYS, &ray_buf),
                    buffer_binding(bindings::TRACE_HITS, &hit_buf),
                    uniform_binding(bindings::TRACE_PARAMS, &param_buf, 8),
                ],
            )?;
            let timer = Timer::new(ctx, chunks.count());
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            chunks.record(&mut enc, &pipeline, &bind, WORKGROUP, timer.as_ref());
            if let Some(t) = &timer {
                t.resolve(&mut enc);
            }
            let mut from = vec![(&hit_buf, hit_size)];
            if let Some(t) = &timer {
                from.push((t.buffer(), t.buffer().size()));
            }
            let readback = Readback::record(ctx, &mut enc, &from);
            ctx.queue.submit([enc.finish()]);
            let parts = readback.read(ctx)?;
            hits.extend(bytemuck::pod_collect_to_vec::<u8, Hit>(&parts[0]));
            let ns = timer.map(|_| Timer::nanoseconds(ctx, &parts[1]));
            gpu_ns = gpu_ns.zip(ns).map(|(a, b)| a + b);
        }
        let timings = Timings {
            gpu_ms: gpu_ns.map(|ns| ns * 1e-6),
            wall_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        Ok((hits, timings))
    }
}
