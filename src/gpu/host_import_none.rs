//! Where wgpu has no Vulkan backend (Apple, the web), nothing is imported in place: every
//! upload copies (see the Vulkan version, `host_import.rs`).

use super::GpuContext;

pub(crate) fn wanted(_: &wgpu::Adapter) -> bool {
    false
}

pub(crate) fn enabled(_: &wgpu::Device) -> bool {
    false
}

pub(crate) fn open(
    _: &wgpu::Adapter,
    _: &wgpu::DeviceDescriptor<'_>,
) -> std::result::Result<(wgpu::Device, wgpu::Queue), String> {
    Err("no Vulkan backend".into())
}

pub(crate) unsafe fn texture(
    _: &GpuContext,
    _: &str,
    _: &[u8],
    _: usize,
    _: impl Send + Sync + 'static,
) -> Option<wgpu::Texture> {
    None
}

pub(crate) unsafe fn buffer(
    _: &GpuContext,
    _: &str,
    _: &[u8],
    _: usize,
    _: impl Send + Sync + 'static,
) -> Option<wgpu::Buffer> {
    None
}
