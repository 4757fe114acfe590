//! The GPU renderer: the scene uploaded once, one pipeline per effect set (override
//! constants of shaders/render.wgsl), samples accumulated over many short dispatches.

use std::collections::HashMap;

use glam::Vec3;

use super::effects::EffectSet;
use super::integrator::CameraFrame;
use super::scene::{Light, RenderScene};
use super::scene_file::{Integrator, MaterialKind};
use crate::accel::bvh::FlatBvh;
use crate::error::{Error, Result};
use crate::gpu::{shaders, storage_entry, BvhMemory, GpuBvh, GpuContext};

/// Pixels per dispatch: keeps every dispatch short on a software rasteriser.
const CHUNK: u32 = 1 << 16;
const WORKGROUP: u32 = 64;

/// A triangle by original index, for shading (WGSL `Shade`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuShade {
    pub v0: [f32; 3],
    pub material: u32,
    pub v1: [f32; 3],
    pub _pad1: u32,
    pub v2: [f32; 3],
    pub _pad2: u32,
    pub uv0: [f32; 2],
    pub uv1: [f32; 2],
    pub uv2: [f32; 2],
    pub _pad3: [u32; 2],
}

/// WGSL `Material`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuMaterial {
    pub albedo: [f32; 3],
    pub kind: u32,
    pub emission: [f32; 3],
    pub ior: f32,
    pub tex_offset: u32,
    pub tex_width: u32,
    pub tex_height: u32,
    pub has_tex: u32,
}

/// WGSL `Light`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    pub v: [f32; 3],
    pub kind: u32,
    pub power: [f32; 3],
    pub _pad: u32,
}

/// WGSL `Params` (uniform).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RenderParams {
    pub eye: [f32; 3],
    pub width: u32,
    pub fwd: [f32; 3],
    pub height: u32,
    pub right: [f32; 3],
    pub inv_w2: f32,
    pub up: [f32; 3],
    pub inv_h2: f32,
    pub background: [f32; 3],
    pub seed: u32,
    pub sample: u32,
    pub offset: u32,
    pub count: u32,
    pub max_bounces: u32,
    pub integrator: u32,
    pub n_lights: u32,
    pub n_emitters: u32,
    pub emit_total: f32,
    pub ao_distance: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

pub struct GpuRenderer<'a> {
    ctx: &'a GpuContext,
    bvh: GpuBvh,
    bind: wgpu::BindGroup,
    accum: wgpu::Buffer,
    params: wgpu::Buffer,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    pipelines: HashMap<EffectSet, wgpu::ComputePipeline>,
    base: RenderParams,
    pixels: u32,
    align: u32,
}

fn kind_code(k: MaterialKind) -> u32 {
    match k {
        MaterialKind::Diffuse => 0,
        MaterialKind::Mirror => 1,
        MaterialKind::Glass => 2,
        MaterialKind::Emissive => 3,
    }
}

impl<'a> GpuRenderer<'a> {
    /// Validates and uploads the BVH (in the default memory) and the scene; the
    /// accumulation buffer starts at zero.
    pub fn new(ctx: &'a GpuContext, scene: &RenderScene, flat: &FlatBvh) -> Result<Self> {
        Self::with_memory(ctx, scene, flat, BvhMemory::default())
    }

    /// As [`GpuRenderer::new`], with the BVH in the given memory.
    pub fn with_memory(
        ctx: &'a GpuContext,
        scene: &RenderScene,
        flat: &FlatBvh,
        memory: BvhMemory,
    ) -> Result<Self> {
        let bvh = GpuBvh::upload(ctx, flat, memory)?;
        let pixels = scene.camera.width * scene.camera.height;
        let shades: Vec<GpuShade> = (scene.mesh.triangles.iter().enumerate())
            .map(|(i, t)| {
                let uv = scene.uvs[i];
                GpuShade {
                    v0: t.v[0].into(),
                    material: scene.material_of[i],
                    _pad1: 0,
                    v1: t.v[1].into(),
                    _pad2: 0,
                    v2: t.v[2].into(),
                    uv0: uv[0].into(),
                    uv1: uv[1].into(),
                    uv2: uv[2].into(),
                    _pad3: [0; 2],
                }
            })
            .collect();
        let mut texels: Vec<[f32; 4]> = Vec::new();
        let mut tex_at = Vec::new();
        for t in &scene.textures {
            tex_at.push(texels.len() as u32);
            texels.extend(t.texels.iter().map(|c| c.extend(1.0).to_array()));
        }
        if texels.is_empty() {
            texels.push([0.0; 4]);
        }
        let materials: Vec<GpuMaterial> = (scene.materials.iter())
            .map(|m| {
                let (off, w, h) = m.texture.map_or((0, 0, 0), |t| {
                    (tex_at[t], scene.textures[t].width, scene.textures[t].height)
                });
                GpuMaterial {
                    albedo: m.albedo.into(),
                    kind: kind_code(m.kind),
                    emission: m.emission.into(),
                    ior: m.ior,
                    tex_offset: off,
                    tex_width: w,
                    tex_height: h,
                    has_tex: m.texture.is_some() as u32,
                }
            })
            .collect();
        let mut lights: Vec<GpuLight> = (scene.lights.iter())
            .map(|l| match *l {
                Light::Point {
                    position,
                    intensity,
                } => GpuLight {
                    v: position.into(),
                    kind: 0,
                    power: intensity.into(),
                    _pad: 0,
                },
                Light::Directional {
                    direction,
                    irradiance,
                } => GpuLight {
                    v: direction.into(),
                    kind: 1,
                    power: irradiance.into(),
                    _pad: 0,
                },
            })
            .collect();
        let n_lights = lights.len() as u32;
        lights.push(bytemuck::Zeroable::zeroed());
        let mut emitters: Vec<[u32; 2]> = (scene.emitters.iter().zip(&scene.emitter_cdf))
            .map(|(&p, &c)| [p, c.to_bits()])
            .collect();
        let n_emitters = emitters.len() as u32;
        emitters.push([0; 2]);

        let accum_bytes = pixels as u64 * 16;
        // Bindings 2..=6 (0, 1, 10 and 11 are the BVH's).
        let sized: [(&str, &[u8]); 5] = [
            ("the shading triangles", bytemuck::cast_slice(&shades)),
            ("the materials", bytemuck::cast_slice(&materials)),
            ("the lights", bytemuck::cast_slice(&lights)),
            ("the emitters", bytemuck::cast_slice(&emitters)),
            ("the textures", bytemuck::cast_slice(&texels)),
        ];
        for (what, bytes) in &sized {
            ctx.check_binding(what, bytes.len() as u64)?;
        }
        ctx.check_binding("the image accumulator", accum_bytes)?;
        let dev = &ctx.device;
        let buffers: Vec<wgpu::Buffer> = (sized.iter())
            .map(|(what, bytes)| ctx.buffer_with(what, bytes, wgpu::BufferUsages::STORAGE))
            .collect();
        let accum = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("accum"),
            size: accum_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let align = ctx.limits.min_uniform_buffer_offset_alignment.max(128);
        let chunks = pixels.div_ceil(CHUNK);
        let params = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render params"),
            size: (chunks * align) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut entries: Vec<wgpu::BindGroupLayoutEntry> = GpuBvh::layout_entries().into();
        entries.extend((2..7).map(|b| storage_entry(b, true)));
        entries.push(storage_entry(7, false));
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 8,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(128),
            },
            count: None,
        });
        let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render"),
            entries: &entries,
        });
        let mut bind_entries: Vec<wgpu::BindGroupEntry> = bvh.bind_entries().into();
        bind_entries.extend(
            (buffers.iter().zip(2..)).map(|(b, binding)| wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }),
        );
        bind_entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: accum.as_entire_binding(),
        });
        bind_entries.push(wgpu::BindGroupEntry {
            binding: 8,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &params,
                offset: 0,
                size: wgpu::BufferSize::new(128),
            }),
        });
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render"),
            layout: &layout,
            entries: &bind_entries,
        });
        let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("render"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let src = shaders::render_source();
        let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("render.wgsl"),
            source: wgpu::ShaderSource::Wgsl(src.as_str().into()),
        });
        let f = CameraFrame::new(scene);
        let s = &scene.settings;
        let base = RenderParams {
            eye: f.eye.into(),
            width: scene.camera.width,
            fwd: f.fwd.into(),
            height: scene.camera.height,
            right: f.right.into(),
            inv_w2: f.inv_w2,
            up: f.up.into(),
            inv_h2: f.inv_h2,
            background: s.background.into(),
            seed: s.seed,
            max_bounces: s.max_bounces,
            integrator: match s.integrator {
                Integrator::Direct => 0,
                Integrator::Path => 1,
                Integrator::Ao => 2,
            },
            n_lights,
            n_emitters,
            emit_total: scene.emitter_cdf.last().copied().unwrap_or(0.0),
            ao_distance: s.ao_distance,
            ..RenderParams::default()
        };
        Ok(GpuRenderer {
            ctx,
            bvh,
            bind,
            accum,
            params,
            pipeline_layout,
            module,
            pipelines: HashMap::new(),
            base,
            pixels,
            align,
        })
    }

    fn pipeline(&mut self, fx: EffectSet) -> wgpu::ComputePipeline {
        let (dev, pl, module) = (&self.ctx.device, &self.pipeline_layout, &self.module);
        let memory = self.bvh.override_constant();
        self.pipelines
            .entry(fx)
            .or_insert_with(|| {
                let mut constants: Vec<(&str, f64)> = (fx.flags().iter())
                    .map(|&(name, on)| (name, if on { 1.0 } else { 0.0 }))
                    .collect();
                constants.push(("WORKGROUP_SIZE", WORKGROUP as f64));
                constants.push(memory);
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("render"),
                    layout: Some(pl),
                    module,
                    entry_point: Some("render"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    cache: None,
                })
            })
            .clone()
    }

    /// Adds sample number `sample` of every pixel to the accumulator and waits for it.
    /// Returns the GPU's wall time for the pass in milliseconds.
    pub fn add_sample(&mut self, fx: EffectSet, sample: u32) -> Result<f64> {
        let start = std::time::Instant::now();
        let pipeline = self.pipeline(fx);
        let chunks = self.pixels.div_ceil(CHUNK);
        let mut bytes = vec![0u8; (chunks * self.align) as usize];
        for c in 0..chunks {
            let p = RenderParams {
                sample,
                offset: c * CHUNK,
                count: (self.pixels - c * CHUNK).min(CHUNK),
                ..self.base
            };
            let at = (c * self.align) as usize;
            bytes[at..at + 128].copy_from_slice(bytemuck::bytes_of(&p));
        }
        self.ctx.queue.write_buffer(&self.params, 0, &bytes);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        for c in 0..chunks {
            let count = (self.pixels - c * CHUNK).min(CHUNK);
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &self.bind, &[c * self.align]);
            pass.dispatch_workgroups(count.div_ceil(WORKGROUP), 1, 1);
        }
        self.ctx.queue.submit([enc.finish()]);
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("GPU did not finish: {e}")))?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    /// The accumulated sums, one per pixel, row-major.
    pub fn read_accum(&self) -> Result<Vec<Vec3>> {
        let dev = &self.ctx.device;
        let size = self.pixels as u64 * 16;
        let readback = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("accum readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = dev.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&self.accum, 0, &readback, 0, size);
        self.ctx.queue.submit([enc.finish()]);
        readback.slice(..).map_async(wgpu::MapMode::Read, |r| {
            if let Err(e) = r {
                eprintln!("error: GPU readback failed: {e}");
            }
        });
        dev.poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("GPU did not finish: {e}")))?;
        let view = readback
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("GPU readback failed: {e}")))?;
        let px: &[[f32; 4]] = bytemuck::cast_slice(&view);
        Ok(px.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect())
    }
}
