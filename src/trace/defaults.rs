//! The layout a device traces with when none is asked for: the fastest one `lancer bench
//! layouts` measured on that kind of device. The book's "Defaults" page
//! (docs/src/defaults.md) gives the run that chose each and its numbers.

use crate::accel::bvh::layouts::LayoutKind;
use crate::device::Device;

/// The CPU's default: the fastest CPU twin of `bench layouts` on every ray set of the
/// Stanford bunny (bvh8: eight boxes a node tested in one AVX2 vector, the fewest nodes a
/// ray), 0.79× Embree 3 on primary rays against dfs-sign's 0.54× (2026-11-25).
pub const CPU_LAYOUT: LayoutKind = LayoutKind::Bvh8;

/// A software adapter's default (lavapipe: wgpu's device type `Cpu`): cwbvh, the fastest
/// per-ray kernel of `bench layouts` on every ray set of the bunny on Mesa 25 (2026-11-25;
/// docs/src/defaults.md gives the runs).
pub const SOFTWARE_GPU_LAYOUT: LayoutKind = LayoutKind::Cwbvh;

/// A hardware GPU's default: dfs-sign, not yet chosen by a measurement. The first `bench
/// layouts` on a hardware GPU (an NVIDIA H200, the bunny at 256×256, 2026-12-04) found it
/// the slowest binary layout there; it stays until a run over more meshes picks its
/// successor, being also `lancer build`'s default and what the GPU-built LBVH flattens into
/// (docs/src/defaults.md).
pub const GPU_LAYOUT: LayoutKind = LayoutKind::DfsSign;

/// The layout `device` traces with by default: [`CPU_LAYOUT`] on the CPU,
/// [`SOFTWARE_GPU_LAYOUT`] on a software adapter, [`GPU_LAYOUT`] on a hardware GPU.
pub fn default_layout(device: &Device) -> LayoutKind {
    match device.gpu_context() {
        None => CPU_LAYOUT,
        Some(ctx) if ctx.adapter.software => SOFTWARE_GPU_LAYOUT,
        Some(_) => GPU_LAYOUT,
    }
}
