//! Where wgpu has no Vulkan backend (Apple, the web), nothing is imported in place: every
//! upload copies. The same functions as the Vulkan version (`host_import.rs`), each
//! answering that it cannot.

use super::GpuContext;

/// Never: no adapter here imports host memory.
pub(crate) fn wanted(_: &wgpu::Adapter) -> bool {
    false
}

/// Never: no device here imports host memory.
pub(crate) fn enabled(_: &wgpu::Device) -> bool {
    false
}

/// Refused: there is no Vulkan device to open.
pub(crate) fn open(
    _: &wgpu::Adapter,
    _: &wgpu::DeviceDescriptor<'_>,
) -> std::result::Result<(wgpu::Device, wgpu::Queue), String> {
    Err("no Vulkan backend".into())
}

/// None: the caller copies.
///
/// # Safety
/// None needed; the signature is the Vulkan version's.
pub(crate) unsafe fn texture(
    _: &GpuContext,
    _: &str,
    _: &[u8],
    _: usize,
    _: impl Send + Sync + 'static,
) -> Option<wgpu::Texture> {
    None
}

/// None: the caller copies.
///
/// # Safety
/// None needed; the signature is the Vulkan version's.
pub(crate) unsafe fn buffer(
    _: &GpuContext,
    _: &str,
    _: &[u8],
    _: usize,
    _: impl Send + Sync + 'static,
) -> Option<(wgpu::Buffer, u64)> {
    None
}
