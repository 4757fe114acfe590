//! The wgpu plumbing every kernel shares: modules and pipelines with override constants
//! (validation errors caught and returned), bind-group entries, chunked dispatch with
//! optional timestamp queries, and readback.

use super::exact_spirv::ExactModule;
use super::GpuContext;
use crate::error::{Error, Result};

/// Runs `f` inside validation and out-of-memory error scopes: a wgpu error becomes an
/// `Err` naming `what` instead of a panic in the uncaptured-error handler.
pub fn scoped<T>(ctx: &GpuContext, what: &str, f: impl FnOnce() -> T) -> Result<T> {
    let oom = ctx.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    let errors = [validation.pop(), oom.pop()];
    for e in errors {
        if let Some(e) = pollster::block_on(e) {
            return Err(Error::Gpu(format!("{what}: {e}")));
        }
    }
    Ok(value)
}

/// A storage-buffer layout entry for a compute kernel.
pub fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
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

/// A uniform layout entry with a dynamic offset (one uniform per dispatch chunk).
pub fn dynamic_uniform_entry(binding: u32, size: u64) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: wgpu::BufferSize::new(size),
        },
        count: None,
    }
}

/// A read-only rgba32uint storage-texture layout entry.
pub fn texel_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::ReadOnly,
            format: wgpu::TextureFormat::Rgba32Uint,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// A bind-group entry for a whole buffer.
pub fn buffer_binding(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A bind-group entry for one `size`-byte uniform of a dynamic-offset buffer.
pub fn uniform_binding(binding: u32, buffer: &wgpu::Buffer, size: u64) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer,
            offset: 0,
            size: wgpu::BufferSize::new(size),
        }),
    }
}

/// A compute kernel: one WGSL source, its bind-group layout, and its shader modules, with
/// pipelines made per set of override constants: on a device with
/// [`exact_spirv`](GpuContext::exact_spirv), from lancer's own SPIR-V of the source (which
/// the driver may not round differently from the CPU); elsewhere from wgpu's modules
/// (checked, and trusted when asked for).
pub struct Kernel {
    label: &'static str,
    entry: &'static str,
    /// The bind-group layout of group 0.
    pub layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    modules: Modules,
    /// Group 0's binding numbers.
    bindings: Vec<u32>,
    /// The caller vouched for the kernel's indices (`Kernel::new`'s `trusted`).
    trusted: bool,
}

/// Where a kernel's pipelines come from.
enum Modules {
    /// lancer's SPIR-V, specialised per pipeline.
    Exact(Box<ExactModule>),
    /// wgpu's translation: checked, and trusted when asked for.
    Wgsl {
        checked: wgpu::ShaderModule,
        trusted: Option<wgpu::ShaderModule>,
    },
}

impl Kernel {
    /// Compiles `source`. With `trusted`, also a module without bounds checks and loop
    /// bounding: the caller vouches that every index the kernel reads is in range (the
    /// layout validated its arrays, and every ray/pixel index is guarded by a count).
    pub fn new(
        ctx: &GpuContext,
        label: &'static str,
        entry: &'static str,
        source: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
        trusted: bool,
    ) -> Result<Kernel> {
        let exact = match ctx.exact_spirv {
            true => Some(ExactModule::new(label, source, ctx.device.features())?),
            false => None,
        };
        scoped(ctx, &format!("compiling the {label} kernel"), || {
            let dev = &ctx.device;
            let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            });
            let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let desc = || wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            };
            let modules = match exact {
                Some(m) => Modules::Exact(Box::new(m)),
                None => Modules::Wgsl {
                    checked: dev.create_shader_module(desc()),
                    // SAFETY: see the doc comment; callers pass `trusted` only for
                    // validated data.
                    trusted: trusted.then(|| unsafe {
                        dev.create_shader_module_trusted(
                            desc(),
                            wgpu::ShaderRuntimeChecks::unchecked(),
                        )
                    }),
                },
            };
            Kernel {
                label,
                entry,
                layout,
                pipeline_layout,
                modules,
                bindings: entries.iter().map(|e| e.binding).collect(),
                trusted,
            }
        })
    }

    /// A pipeline specialised by `constants`, from the trusted module when asked for (and
    /// compiled), else the checked one.
    pub fn pipeline(
        &self,
        ctx: &GpuContext,
        constants: &[(&str, f64)],
        trusted: bool,
    ) -> Result<wgpu::ComputePipeline> {
        let what = format!("specialising the {} kernel", self.label);
        let exact;
        let (module, constants) = match &self.modules {
            Modules::Exact(m) => {
                let spirv = m.spirv(
                    self.entry,
                    constants,
                    &self.bindings,
                    trusted && self.trusted,
                    ctx.exact_division,
                )?;
                let desc = wgpu::ShaderModuleDescriptorPassthrough {
                    label: Some(self.label),
                    entry_points: std::borrow::Cow::Owned(vec![
                        wgpu::PassthroughShaderEntryPoint {
                            name: self.entry.into(),
                            workgroup_size: (0, 0, 0),
                        },
                    ]),
                    spirv: Some(std::borrow::Cow::Owned(spirv)),
                    ..Default::default()
                };
                // SAFETY: the SPIR-V is naga's translation of a module naga validated, with
                // only decorations and f64 conversions added (gpu::exact_spirv).
                exact = scoped(ctx, &what, || unsafe {
                    ctx.device.create_shader_module_passthrough(desc)
                })?;
                (&exact, &[][..])
            }
            Modules::Wgsl {
                checked,
                trusted: t,
            } => match (t, trusted) {
                (Some(m), true) => (m, constants),
                _ => (checked, constants),
            },
        };
        scoped(ctx, &what, || {
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(self.label),
                    layout: Some(&self.pipeline_layout),
                    module,
                    entry_point: Some(self.entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants,
                        ..Default::default()
                    },
                    cache: None,
                })
        })
    }

    /// A bind group of group 0.
    pub fn bind(
        &self,
        ctx: &GpuContext,
        entries: &[wgpu::BindGroupEntry],
    ) -> Result<wgpu::BindGroup> {
        scoped(
            ctx,
            &format!("binding the {} kernel's buffers", self.label),
            || {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(self.label),
                    layout: &self.layout,
                    entries,
                })
            },
        )
    }
}

/// Items per dispatch chunk and their uniforms: chunk c covers [c·chunk, c·chunk + count).
pub struct Chunks {
    /// Items per chunk.
    pub chunk: u32,
    /// Items in all.
    pub items: u32,
    /// Byte stride of the per-chunk uniforms (the device's dynamic-offset alignment).
    pub align: u32,
}

impl Chunks {
    /// Splits `items` into chunks of at most `chunk`, with uniforms `align`-ed.
    pub fn new(ctx: &GpuContext, items: u32, chunk: u32, uniform_size: u32) -> Chunks {
        // Each chunk's uniforms start at a multiple of the device's dynamic-offset alignment
        // (a power of two) and do not overlap the next chunk's.
        let align =
            uniform_size.next_multiple_of(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
        Chunks {
            chunk,
            items,
            align,
        }
    }

    /// Number of chunks (at least one).
    pub fn count(&self) -> u32 {
        self.items.div_ceil(self.chunk).max(1)
    }

    /// (first item, item count) of chunk `c`.
    pub fn range(&self, c: u32) -> (u32, u32) {
        let first = c * self.chunk;
        (first, (self.items - first.min(self.items)).min(self.chunk))
    }

    /// The uniforms of every chunk, each `align`-ed, from `make(first, count)`.
    pub fn uniforms<P: bytemuck::Pod>(&self, make: impl Fn(u32, u32) -> P) -> Vec<u8> {
        let mut bytes = vec![0u8; (self.count() * self.align) as usize];
        for c in 0..self.count() {
            let (first, count) = self.range(c);
            let p = make(first, count);
            let at = (c * self.align) as usize;
            bytes[at..at + std::mem::size_of::<P>()].copy_from_slice(bytemuck::bytes_of(&p));
        }
        bytes
    }

    /// Records one compute pass per chunk into `enc`, each with its dynamic uniform offset
    /// and `workgroup`-sized groups, timed when `timer` is given.
    pub fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        bind: &wgpu::BindGroup,
        workgroup: u32,
        timer: Option<&Timer>,
    ) {
        for c in 0..self.count() {
            let (_, count) = self.range(c);
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: timer.map(|t| t.writes(c)),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[c * self.align]);
            pass.dispatch_workgroups(count.max(1).div_ceil(workgroup.max(1)), 1, 1);
        }
    }
}

/// Timestamp queries around each of `passes` compute passes.
pub struct Timer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    passes: u32,
}

impl Timer {
    /// A timer for `passes` passes, or None when the device has no timestamp queries or
    /// there are too many passes for one query set.
    pub fn new(ctx: &GpuContext, passes: u32) -> Option<Timer> {
        if !ctx.timestamps || passes * 2 > wgpu::QUERY_SET_MAX_QUERIES {
            return None;
        }
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("dispatch times"),
            ty: wgpu::QueryType::Timestamp,
            count: passes * 2,
        });
        let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamps"),
            size: passes as u64 * 16,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(Timer {
            set,
            resolve,
            passes,
        })
    }

    fn writes(&self, pass: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * pass),
            end_of_pass_write_index: Some(2 * pass + 1),
        }
    }

    /// Records the resolve of every query into the timer's buffer.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..self.passes * 2, &self.resolve, 0);
    }

    /// The buffer [`Timer::resolve`] writes, for [`Readback`].
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.resolve
    }

    /// Sum of the passes' GPU nanoseconds from the resolved timestamps.
    pub fn nanoseconds(ctx: &GpuContext, resolved: &[u8]) -> f64 {
        let ts: &[u64] = bytemuck::cast_slice(resolved);
        let period = ctx.queue.get_timestamp_period() as f64;
        ts.chunks(2)
            .map(|p| p[1].saturating_sub(p[0]) as f64 * period)
            .sum()
    }
}

/// Copies of device buffers made readable on the host.
pub struct Readback {
    parts: Vec<(wgpu::Buffer, u64)>,
}

impl Readback {
    /// Records copies of the first `size` bytes of each buffer into mappable buffers.
    pub fn record(
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        from: &[(&wgpu::Buffer, u64)],
    ) -> Readback {
        let parts = from
            .iter()
            .map(|&(src, size)| {
                let dst = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size: size.max(4),
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                if size > 0 {
                    enc.copy_buffer_to_buffer(src, 0, &dst, 0, size);
                }
                (dst, size)
            })
            .collect();
        Readback { parts }
    }

    /// Waits for the device and returns each buffer's bytes, in the order recorded.
    pub fn read(self, ctx: &GpuContext) -> Result<Vec<Vec<u8>>> {
        self.read_with(ctx, |views| views.iter().map(|v| v.to_vec()).collect())
    }

    /// Waits for the device and hands `f` each buffer's bytes, in the order recorded,
    /// straight from the mapped memory (no copy of its own: what `f` keeps, it copies).
    pub fn read_with<T>(self, ctx: &GpuContext, f: impl FnOnce(&[&[u8]]) -> T) -> Result<T> {
        for (b, _) in &self.parts {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                if let Err(e) = r {
                    log::error!("GPU readback failed: {e}");
                }
            });
        }
        wait(ctx)?;
        let views = self
            .parts
            .iter()
            .map(|(b, _)| {
                b.get_mapped_range(..)
                    .map_err(|e| Error::Gpu(format!("GPU readback failed: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        let bytes: Vec<&[u8]> = views
            .iter()
            .zip(&self.parts)
            .map(|(v, (_, size))| &v[..*size as usize])
            .collect();
        Ok(f(&bytes))
    }
}

/// Waits until the device has finished all submitted work; an error the device reported
/// outside an error scope since the last wait is returned here.
pub fn wait(ctx: &GpuContext) -> Result<()> {
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("GPU did not finish: {e}")))?;
    let first = match ctx.uncaptured.lock() {
        Ok(mut errors) => errors.drain(..).next(),
        Err(_) => Some("an error handler panicked".to_string()),
    };
    match first {
        Some(e) => Err(Error::Gpu(e)),
        None => Ok(()),
    }
}

/// A storage buffer (zeroed by wgpu) that kernels write, the host reads back and may clear.
pub fn output_buffer(ctx: &GpuContext, label: &str, size: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
