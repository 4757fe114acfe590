//! One place that opens a headless GPU device.

use crate::util::human_bytes;
use std::sync::{Arc, Mutex};

use wgpu::util::DeviceExt;

use crate::error::{Error, Result};

/// What the adapter is, for `--stats`, benches and warnings.
#[derive(Clone, Debug)]
pub struct AdapterReport {
    /// The adapter's name (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    pub name: String,
    /// Driver name and version.
    pub driver: String,
    /// Backend (Vulkan, Metal, …).
    pub backend: String,
    /// A software adapter (a CPU pretending to be a GPU, like lavapipe).
    pub software: bool,
}

impl std::fmt::Display for AdapterReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}, {})", self.name, self.driver, self.backend)
    }
}

/// Bytes one upload slice stages. wgpu copies every write into a staging buffer of its
/// own, freed once the device has done the copy; big arrays go up in slices of this size
/// ([`SlicedWrites`]: the device copies one while the next is staged), so that the process
/// holds two slices besides the array rather than a second copy of it (on a software
/// adapter, a third: the device memory is the process's).
pub(crate) const UPLOAD_SLICE: usize = 32 << 20;

/// A headless device and queue (a clone shares them): opened by lancer
/// ([`GpuContext::new`]) or the application's own ([`GpuContext::from_wgpu`]).
#[derive(Clone)]
pub struct GpuContext {
    /// The wgpu device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is.
    pub adapter: AdapterReport,
    /// The adapter's limits (requested in full).
    pub limits: wgpu::Limits,
    /// Timestamp queries are available (GPU times in benches and `--stats`).
    pub timestamps: bool,
    /// Subgroup operations are enabled (the adapter has `Features::SUBGROUP`), with the
    /// adapter's range of subgroup sizes; None without them.
    pub subgroups: Option<SubgroupSizes>,
    /// The driver's own ray queries are enabled (the adapter has wgpu's
    /// `Features::EXPERIMENTAL_RAY_QUERY`): the reference row [`DriverTracer`] runs.
    ///
    /// [`DriverTracer`]: super::DriverTracer
    pub ray_query: bool,
    /// Kernels are compiled by lancer into SPIR-V the driver may not round differently from
    /// the CPU (every float operation `NoContraction`; see `gpu::exact_spirv`): a Vulkan
    /// device with wgpu's `Features::PASSTHROUGH_SHADERS`. Elsewhere wgpu translates the
    /// WGSL and a driver may fuse a multiply-add, so answers can differ from the CPU's by
    /// a few ulps (`lancer check` shows where).
    pub exact_spirv: bool,
    /// With [`exact_spirv`](Self::exact_spirv), f32 division and square root are taken
    /// through f64 (the device has `Features::SHADER_F64`): correctly rounded, as on the CPU,
    /// wherever the driver's f64 is as accurate as IEEE's (Vulkan promises less; `lancer
    /// check` tests a driver).
    pub exact_division: bool,
    /// Arrays that nothing changes once uploaded (a flattened layout's, traced by
    /// [`Tracer`](crate::Tracer)) are read where the host holds them instead of being
    /// copied: a Vulkan CPU adapter (lavapipe) opened with `VK_EXT_external_memory_host`,
    /// whose memory is the host's. Set where the device can; clear it to copy them anyway.
    pub import_host_memory: bool,
    /// Errors the device reported outside an error scope since the last [`wait`], which
    /// returns the first of them (so no GPU error passes silently).
    ///
    /// [`wait`]: super::plumbing::wait
    pub(crate) uncaptured: Arc<Mutex<Vec<String>>>,
}

/// The smallest and largest subgroup (SIMD width) the adapter may run a kernel with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubgroupSizes {
    /// Fewest invocations a subgroup may have (wgpu's `AdapterInfo::subgroup_min_size`).
    pub min: u32,
    /// Most invocations a subgroup may have (wgpu's `AdapterInfo::subgroup_max_size`).
    pub max: u32,
}

/// Storage buffers the trace kernel binds (nodes, triangles, rays, hits, statistics).
const MIN_STORAGE_BUFFERS: u32 = super::trace::TRACE_STORAGE_BUFFERS;

const INSTALL_HINT: &str = "no GPU adapter found; install a Vulkan driver (on Debian/Ubuntu: \
apt-get install mesa-vulkan-drivers libvulkan1, which includes the lavapipe software driver) \
or use --device cpu";

impl GpuContext {
    /// Opens an adapter without a window. Honours `WGPU_BACKEND` (e.g. vulkan, gl),
    /// `WGPU_ADAPTER_NAME` (a case-insensitive substring of the adapter name) and
    /// `WGPU_POWER_PREF` (low, high or none; default high).
    pub fn new() -> Result<GpuContext> {
        pollster::block_on(async { Self::on(pick_adapter(&instance()?).await?).await })
    }

    /// Opens the adapter [`GpuContext::new`] would when it is a hardware one (or the one
    /// `WGPU_ADAPTER_NAME` names); where it is a software one (a CPU driver such as
    /// lavapipe), another adapter that is not, and where there is none, `Ok(Err(report))` of
    /// the software one, without opening a device.
    pub fn new_hardware() -> Result<std::result::Result<GpuContext, AdapterReport>> {
        pollster::block_on(async {
            let instance = instance()?;
            let adapter = pick_adapter(&instance).await?;
            let software = |a: &wgpu::Adapter| a.get_info().device_type == wgpu::DeviceType::Cpu;
            if std::env::var_os("WGPU_ADAPTER_NAME").is_some() || !software(&adapter) {
                return Ok(Ok(Self::on(adapter).await?));
            }
            // wgpu ranks hardware adapters first, except under WGPU_POWER_PREF=none.
            let others = instance.enumerate_adapters(wgpu::Backends::all()).await;
            match others.into_iter().find(|a| !software(a)) {
                Some(hardware) => Ok(Ok(Self::on(hardware).await?)),
                None => Ok(Err(report_of(&adapter.get_info()))),
            }
        })
    }

    /// Wraps an application's own wgpu device and queue (created from an adapter of any
    /// backend, with any descriptor): lancer then traces and renders on them, sharing them
    /// with the application. The `wgpu` crate must be the one lancer builds
    /// ([`lancer::gpu::wgpu`](crate::gpu::wgpu), wgpu 30).
    ///
    /// lancer uses only the features and limits the device was created with, read back
    /// from it (`Device::features`, `Device::limits`, `Device::adapter_info`): timestamp
    /// queries (`Features::TIMESTAMP_QUERY`) for GPU times, subgroup operations
    /// (`Features::SUBGROUP`) for the subgroup traversal, and the driver's ray queries
    /// (`Features::EXPERIMENTAL_RAY_QUERY`) for [`DriverTracer`](super::DriverTracer),
    /// each where the device has it and done without where it has not. Its buffers are
    /// bounded by the device's limits: request `adapter.limits()` to trace the largest
    /// meshes, as [`GpuContext::new`] does (a mesh beyond the limits is refused, naming the
    /// limit).
    ///
    /// lancer's own errors are caught in error scopes and returned. The device's handler
    /// for errors outside any scope stays the application's (wgpu's default one panics);
    /// [`GpuContext::catch_uncaptured_errors`] hands it to lancer instead.
    ///
    /// Refuses a device whose limits leave no room for lancer's trace kernel (fewer than
    /// five storage buffers per shader stage, or no compute shaders).
    pub fn from_wgpu(device: wgpu::Device, queue: wgpu::Queue) -> Result<GpuContext> {
        let info = device.adapter_info();
        let report = report_of(&info);
        let features = device.features();
        let limits = device.limits();
        // The trace kernel binds five storage buffers (the BVH in buffer memory); a device
        // made with downlevel limits (4) or without compute shaders cannot run it.
        if limits.max_storage_buffers_per_shader_stage < MIN_STORAGE_BUFFERS
            || limits.max_compute_workgroups_per_dimension == 0
        {
            return Err(Error::Gpu(format!(
                "the device on {report} allows {} storage buffers per shader stage and {} \
                 compute workgroups per dimension; lancer's kernels need at least \
                 {MIN_STORAGE_BUFFERS} (8 to render) and compute shaders: create the device \
                 with wgpu::Limits::default() or the adapter's limits",
                limits.max_storage_buffers_per_shader_stage,
                limits.max_compute_workgroups_per_dimension
            )));
        }
        Ok(GpuContext {
            limits,
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            subgroups: features
                .contains(wgpu::Features::SUBGROUP)
                .then_some(SubgroupSizes {
                    min: info.subgroup_min_size,
                    max: info.subgroup_max_size,
                }),
            ray_query: features.contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY),
            exact_spirv: exact_spirv(info.backend, features),
            exact_division: exact_spirv(info.backend, features)
                && features.contains(wgpu::Features::SHADER_F64),
            import_host_memory: super::host_import::enabled(&device),
            device,
            queue,
            adapter: report,
            uncaptured: Arc::new(Mutex::new(Vec::new())),
        })
    }

    /// Sets the device's handler for errors outside any error scope to lancer's, which logs
    /// each and keeps it for the next wait to return as an `Err` (what [`GpuContext::new`]
    /// does). It replaces the handler the device had, the application's included: call it
    /// on a device from [`GpuContext::from_wgpu`] only where lancer may take that over.
    pub fn catch_uncaptured_errors(&self) {
        let sink = Arc::clone(&self.uncaptured);
        self.device.on_uncaptured_error(Arc::new(move |e| {
            log::error!("GPU error: {e}");
            if let Ok(mut errors) = sink.lock() {
                errors.push(e.to_string());
            }
        }));
    }

    async fn on(adapter: wgpu::Adapter) -> Result<GpuContext> {
        let info = adapter.get_info();
        let report = report_of(&info);
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        // Subgroups only where the adapter has them: kernels that use them are optional.
        let subgroups = adapter
            .features()
            .contains(wgpu::Features::SUBGROUP)
            .then_some(SubgroupSizes {
                min: info.subgroup_min_size,
                max: info.subgroup_max_size,
            });
        let mut features = wgpu::Features::empty();
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        if subgroups.is_some() {
            features |= wgpu::Features::SUBGROUP;
        }
        // Ray queries only where the adapter reports them: the driver row is optional, and
        // wgpu guards the feature behind an explicit opt-in.
        let ray_query = adapter
            .features()
            .contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY);
        let mut experimental_features = wgpu::ExperimentalFeatures::disabled();
        if ray_query {
            features |= wgpu::Features::EXPERIMENTAL_RAY_QUERY;
            // SAFETY: wgpu asks callers to acknowledge that its experimental ray-query API
            // may still have bugs. lancer uses it only for the driver's reference traversal
            // (gpu::driver), never for its own kernels, and checks its answers with the
            // f64 oracle (`lancer check`, tests/driver.rs).
            experimental_features = unsafe { wgpu::ExperimentalFeatures::enabled() };
        }
        // lancer's own SPIR-V (gpu::exact_spirv) where the adapter takes it: the kernels
        // then round as the CPU does; f64 for exact division where the adapter has it.
        if exact_spirv(info.backend, adapter.features()) {
            features |= wgpu::Features::PASSTHROUGH_SHADERS;
            features |= adapter.features() & wgpu::Features::SHADER_F64;
        }
        let exact_division = features.contains(wgpu::Features::SHADER_F64);
        let limits = adapter.limits();
        let desc = wgpu::DeviceDescriptor {
            label: Some("lancer"),
            required_features: features,
            required_limits: limits.clone(),
            experimental_features,
            ..Default::default()
        };
        // A CPU adapter that can import host memory is opened with that extension: the
        // arrays are then handed to it in place (gpu::host_import).
        let opened = match super::host_import::wanted(&adapter) {
            true => super::host_import::open(&adapter, &desc)
                .inspect_err(|e| log::debug!("{report}: opened without host imports ({e})"))
                .ok(),
            false => None,
        };
        let import_host_memory = opened.is_some();
        let (device, queue) = match opened {
            Some(opened) => opened,
            None => adapter
                .request_device(&desc)
                .await
                .map_err(|e| Error::Gpu(format!("could not open a device on {}: {e}", report)))?,
        };
        let ctx = GpuContext {
            device,
            queue,
            adapter: report,
            limits,
            timestamps,
            subgroups,
            ray_query,
            exact_spirv: features.contains(wgpu::Features::PASSTHROUGH_SHADERS),
            exact_division,
            import_host_memory,
            uncaptured: Arc::new(Mutex::new(Vec::new())),
        };
        // Errors outside an error scope (gpu::plumbing::scoped) are logged and kept for the
        // next wait to return, never a panic.
        ctx.catch_uncaptured_errors();
        Ok(ctx)
    }

    /// Why a kernel of `layout` (a subgroup traversal when `layout_has_one`) cannot walk
    /// subgroup by subgroup here in workgroups of `workgroup_size`: the adapter has no
    /// subgroup operations, the layout no subgroup traversal, or the workgroup is not a
    /// whole number of the adapter's largest subgroups. None when it can.
    pub fn subgroup_unavailable(
        &self,
        layout: &str,
        layout_has_one: bool,
        workgroup_size: u32,
    ) -> Option<String> {
        let adapter = &self.adapter.name;
        let Some(sizes) = self.subgroups else {
            return Some(format!("{adapter} has no subgroup operations"));
        };
        if !layout_has_one {
            return Some(format!("the {layout} layout has no subgroup traversal"));
        }
        // Full subgroups: the traversal spreads its work over every lane.
        if !workgroup_size.is_multiple_of(sizes.max) {
            return Some(format!(
                "workgroup size {workgroup_size} is not a multiple of {adapter}'s largest \
                 subgroup ({} lanes)",
                sizes.max
            ));
        }
        None
    }

    /// A buffer created holding `contents`, with `usage` (e.g. STORAGE or UNIFORM). Contents
    /// over 32 MiB (`UPLOAD_SLICE`) go up in slices (`SlicedWrites`).
    pub fn buffer_with(
        &self,
        label: &str,
        contents: &[u8],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let aligned = (contents.len() as u64).is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        if contents.len() <= UPLOAD_SLICE || !aligned {
            return self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                });
        }
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: contents.len() as u64,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut slices = SlicedWrites::new(self);
        for (i, slice) in contents.chunks(UPLOAD_SLICE).enumerate() {
            let offset = (i * UPLOAD_SLICE) as u64;
            self.queue.write_buffer(&buffer, offset, slice);
            slices.submitted();
        }
        self.finish_writes();
        buffer
    }

    /// Lets the device do the queued writes, so that wgpu frees their staging memory.
    /// (Writes in slices: [`SlicedWrites`].)
    pub(crate) fn finish_writes(&self) {
        self.queue.submit([]);
        // A poll that waits without a timeout cannot fail; device errors are reported by
        // the next `plumbing::wait`.
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }

    /// Refuses a buffer the device cannot bind, naming the size and the limit.
    pub fn check_binding(&self, what: &str, bytes: u64) -> Result<()> {
        let limit = self
            .limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size);
        if bytes > limit {
            return Err(Error::Gpu(format!(
                "{what} need {} but {} binds at most {} per storage buffer \
                 (max_storage_buffer_binding_size); use a smaller scene or --device cpu",
                human_bytes(bytes),
                self.adapter.name,
                human_bytes(limit)
            )));
        }
        Ok(())
    }
}

/// Whether lancer compiles its kernels to SPIR-V itself (gpu::exact_spirv) on a device of
/// `backend` with `features`: Vulkan with passthrough shaders, unless `LANCER_WGSL=1` asks
/// for wgpu's own translation (to measure or compare it).
pub(crate) fn exact_spirv(backend: wgpu::Backend, features: wgpu::Features) -> bool {
    backend == wgpu::Backend::Vulkan
        && features.contains(wgpu::Features::PASSTHROUGH_SHADERS)
        && std::env::var_os("LANCER_WGSL").is_none_or(|v| v != "1")
}

/// The adapter `WGPU_ADAPTER_NAME` names, else the one wgpu prefers under `WGPU_POWER_PREF`.
async fn pick_adapter(instance: &wgpu::Instance) -> Result<wgpu::Adapter> {
    match std::env::var("WGPU_ADAPTER_NAME") {
        Ok(want) => {
            let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
            let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
            adapters
                .into_iter()
                .find(|a| {
                    a.get_info()
                        .name
                        .to_lowercase()
                        .contains(&want.to_lowercase())
                })
                .ok_or_else(|| {
                    Error::Gpu(format!(
                        "WGPU_ADAPTER_NAME={want} matches none of the adapters: [{}]",
                        names.join(", ")
                    ))
                })
        }
        Err(_) => instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::from_env()
                    .unwrap_or(wgpu::PowerPreference::HighPerformance),
                ..Default::default()
            })
            .await
            .map_err(|_| Error::Gpu(INSTALL_HINT.into())),
    }
}

fn report_of(info: &wgpu::AdapterInfo) -> AdapterReport {
    AdapterReport {
        name: info.name.clone(),
        driver: format!("{} {}", info.driver, info.driver_info)
            .trim()
            .to_string(),
        backend: format!("{:?}", info.backend),
        software: info.device_type == wgpu::DeviceType::Cpu,
    }
}

/// The wgpu instance every adapter comes from: `WGPU_BACKEND` honoured, else the primary
/// APIs only (the GL backend probes window systems and prints noise on headless machines;
/// `WGPU_BACKEND=gl` still selects it).
pub(crate) fn instance() -> Result<wgpu::Instance> {
    check_environment()?;
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if std::env::var_os("WGPU_BACKEND").is_none() {
        desc.backends = wgpu::Backends::PRIMARY;
    }
    Ok(wgpu::Instance::new(desc))
}

/// Refuses a `WGPU_BACKEND` naming no backend wgpu knows (wgpu would only log it and find
/// no adapter), and a `WGPU_POWER_PREF` other than low, high or none (wgpu would ignore it).
fn check_environment() -> Result<()> {
    if let Ok(pref) = std::env::var("WGPU_POWER_PREF") {
        if !["low", "high", "none"].contains(&pref.to_lowercase().as_str()) {
            return Err(Error::Usage(format!(
                "WGPU_POWER_PREF={pref}: use low, high or none, or unset it"
            )));
        }
    }
    let Ok(value) = std::env::var("WGPU_BACKEND") else {
        return Ok(());
    };
    const NAMES: [&str; 11] = [
        "vulkan", "vk", "dx12", "d3d12", "metal", "mtl", "opengl", "gles", "gl", "webgpu", "noop",
    ];
    for name in value.split(',') {
        let name = name.trim().to_lowercase();
        if !NAMES.contains(&name.as_str()) {
            return Err(Error::Usage(format!(
                "WGPU_BACKEND={value}: '{name}' is not a backend; use vulkan, gl, metal or dx12 \
                 (comma-separated), or unset it"
            )));
        }
    }
    Ok(())
}

/// Writes queued in slices: each slice is submitted as it is queued and the one before it
/// waited for, so that the device copies one slice while the next is staged, and no more
/// than two slices' staging memory is held.
pub(crate) struct SlicedWrites<'c> {
    ctx: &'c GpuContext,
    pending: Option<wgpu::SubmissionIndex>,
}

impl<'c> SlicedWrites<'c> {
    pub(crate) fn new(ctx: &'c GpuContext) -> Self {
        SlicedWrites { ctx, pending: None }
    }

    /// Submits the slice just queued and waits for the one before.
    pub(crate) fn submitted(&mut self) {
        let index = self.ctx.queue.submit([]);
        if let Some(before) = self.pending.replace(index) {
            // A wait without a timeout fails only after a failed submission, whose error the
            // next `plumbing::wait` reports.
            let _ = self.ctx.device.poll(wgpu::PollType::Wait {
                submission_index: Some(before),
                timeout: None,
            });
        }
    }
}
