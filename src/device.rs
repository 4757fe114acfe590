//! Where work runs: the CPU, or a GPU adapter (lavapipe included). [`Device::open`] makes
//! the choice and returns the reason for any fallback as a value; the caller decides
//! whether and how to tell a person.

use crate::error::Result;
use crate::gpu::GpuContext;

/// What the caller asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum DeviceChoice {
    /// A hardware GPU adapter when one opens, else the CPU: where the only adapter is a
    /// software one (lavapipe), the CPU tracers are faster than it. `WGPU_ADAPTER_NAME`
    /// naming an adapter selects it, software or not. The reason for the CPU is kept in
    /// [`Device::fallback`].
    #[cfg_attr(
        feature = "cli",
        value(
            help = "A hardware GPU when one opens, else the CPU (saying why; a software \
                    adapter such as lavapipe is slower than the CPU tracer)"
        )
    )]
    #[default]
    Auto,
    /// A GPU adapter, or an error.
    Gpu,
    /// The CPU tracers and renderer.
    Cpu,
}

/// An opened device.
pub struct Device {
    gpu: Option<GpuContext>,
    fallback: Option<String>,
}

impl Device {
    /// Opens the device `choice` asks for. `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` choose
    /// among adapters (see [`GpuContext::new`]).
    pub fn open(choice: DeviceChoice) -> Result<Device> {
        match choice {
            DeviceChoice::Cpu => Ok(Device::cpu()),
            DeviceChoice::Gpu => Ok(Device::gpu(GpuContext::new()?)),
            DeviceChoice::Auto => match GpuContext::new_hardware() {
                Ok(Ok(ctx)) => Ok(Device::gpu(ctx)),
                Ok(Err(software)) => {
                    let why = format!(
                        "the only GPU adapter is {}, a software rasteriser slower than the \
                         CPU tracer; --device gpu forces it",
                        software.name
                    );
                    log::debug!("using the CPU: {why}");
                    Ok(Device {
                        gpu: None,
                        fallback: Some(why),
                    })
                }
                Err(e) => Device::or_cpu(Err(e)),
            },
        }
    }

    /// A GPU adapter when one opens, a software one included, else the CPU (the reason
    /// kept in [`Device::fallback`]): what a benchmark measures beside the CPU.
    pub fn open_any() -> Result<Device> {
        Device::or_cpu(GpuContext::new())
    }

    /// The GPU that opened, else the CPU with the reason; an adapter asked for by name and
    /// not found is the user's error, not a reason to fall back silently.
    fn or_cpu(opened: Result<GpuContext>) -> Result<Device> {
        match opened {
            Ok(ctx) => Ok(Device::gpu(ctx)),
            Err(e) if std::env::var_os("WGPU_ADAPTER_NAME").is_some() => Err(e),
            // A bad WGPU_BACKEND or WGPU_POWER_PREF is the user's to fix, under auto too.
            Err(e @ crate::Error::Usage(_)) => Err(e),
            Err(e) => {
                log::info!("no GPU: {e}");
                Ok(Device {
                    gpu: None,
                    fallback: Some(e.to_string()),
                })
            }
        }
    }

    /// The CPU.
    pub fn cpu() -> Device {
        Device {
            gpu: None,
            fallback: None,
        }
    }

    /// An already opened GPU: one lancer opened ([`GpuContext::new`]), or the application's
    /// own wgpu device and queue ([`GpuContext::from_wgpu`]).
    ///
    /// ```no_run
    /// # fn main() -> lancer::Result<()> {
    /// use lancer::gpu::{wgpu, GpuContext};
    /// # let (device, queue): (wgpu::Device, wgpu::Queue) = unimplemented!();
    /// // `device` and `queue`: the application's, from its own adapter.
    /// let device = lancer::Device::gpu(GpuContext::from_wgpu(device, queue)?);
    /// # Ok(())
    /// # }
    /// ```
    pub fn gpu(ctx: GpuContext) -> Device {
        Device {
            gpu: Some(ctx),
            fallback: None,
        }
    }

    /// The GPU context, or None on the CPU.
    pub fn gpu_context(&self) -> Option<&GpuContext> {
        self.gpu.as_ref()
    }

    /// Whether work runs on the CPU.
    pub fn is_cpu(&self) -> bool {
        self.gpu.is_none()
    }

    /// Why `Auto` chose the CPU: no adapter opened, or the only one is a software
    /// rasteriser (None when it did not choose the CPU).
    pub fn fallback(&self) -> Option<&str> {
        self.fallback.as_deref()
    }

    /// Logs where work runs, as info lines (the CPU is a normal place to run, and reports
    /// name their adapter): why `Auto` chose the CPU, and that a software adapter's GPU
    /// timings are a CPU's.
    pub fn log_choice(&self) {
        if let Some(why) = self.fallback() {
            log::info!("using the CPU: {why}");
        }
        if let Some(g) = self.gpu.as_ref().filter(|g| g.adapter.software) {
            log::info!(
                "{} is a software adapter (CPU); GPU timings are not a GPU's",
                g.adapter
            );
        }
    }

    /// A software adapter: its GPU timings are a CPU's.
    pub fn is_software(&self) -> bool {
        self.gpu.as_ref().is_some_and(|g| g.adapter.software)
    }
}

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.gpu {
            Some(g) => write!(f, "gpu: {}", g.adapter),
            None => write!(f, "cpu ({} threads)", rayon::current_num_threads()),
        }
    }
}
