//! Arrays handed to the device in place, where its memory is the host's: on a Vulkan CPU
//! adapter (lavapipe) with `VK_EXT_external_memory_host`, a layout's node and triangle
//! words are imported as device memory where the flatten wrote them, instead of being
//! copied twice (into wgpu's staging memory, then into the driver's), which on a CPU device
//! is a copy from one place in RAM to another, and fresh pages for both.
//!
//! Only arrays that nothing writes while the device holds them are imported (the caller
//! says so); the owner of their memory is kept alive until wgpu destroys the texture or
//! buffer, which it does once the device is done with it. Anything this cannot do (another
//! backend, a hardware adapter, a driver without the extension, an array whose allocation
//! leaves no room for the texture's last row, a layout or alignment the driver chooses
//! otherwise) is answered with None, and the caller copies as before.

use std::ffi::c_void;

use ash::vk;
use wgpu::hal;
use wgpu::hal::api::Vulkan;

use super::{GpuContext, TEXEL_ROW};

/// The Vulkan extension this needs, enabled where the adapter has it
/// ([`GpuContext::new`] on a CPU adapter).
pub(crate) const EXTENSION: &std::ffi::CStr = ash::ext::external_memory_host::NAME;

/// Whether lancer opens `adapter` with [`EXTENSION`]: a Vulkan adapter that is a CPU and
/// has it.
pub(crate) fn wanted(adapter: &wgpu::Adapter) -> bool {
    if adapter.get_info().device_type != wgpu::DeviceType::Cpu {
        return false;
    }
    // SAFETY: the hal adapter is only read.
    let Some(hal_adapter) = (unsafe { adapter.as_hal::<Vulkan>() }) else {
        return false;
    };
    hal_adapter
        .physical_device_capabilities()
        .supports_extension(EXTENSION)
}

/// Opens `adapter` (see [`wanted`]) as `request_device` would, with [`EXTENSION`] enabled
/// besides the extensions wgpu enables itself.
pub(crate) fn open(
    adapter: &wgpu::Adapter,
    desc: &wgpu::DeviceDescriptor<'_>,
) -> std::result::Result<(wgpu::Device, wgpu::Queue), String> {
    // SAFETY: the hal adapter is the one `adapter` wraps; the device it opens is handed to
    // `create_device_from_hal` on the same adapter, with the same features and limits.
    unsafe {
        let hal_adapter = adapter.as_hal::<Vulkan>().ok_or("not a Vulkan adapter")?;
        let add = Box::new(|args: hal::vulkan::CreateDeviceCallbackArgs<'_, '_, '_>| {
            if !args.extensions.contains(&EXTENSION) {
                args.extensions.push(EXTENSION);
            }
        });
        let open = hal_adapter
            .open_with_callback(
                desc.required_features,
                &desc.required_limits,
                &desc.memory_hints,
                Some(add),
            )
            .map_err(|e| e.to_string())?;
        drop(hal_adapter);
        adapter
            .create_device_from_hal(open, desc)
            .map_err(|e| e.to_string())
    }
}

/// Whether `device` (an application's, [`GpuContext::from_wgpu`]) is a Vulkan CPU device
/// with [`EXTENSION`] enabled.
pub(crate) fn enabled(device: &wgpu::Device) -> bool {
    if device.adapter_info().device_type != wgpu::DeviceType::Cpu {
        return false;
    }
    // SAFETY: the hal device is only read.
    unsafe { device.as_hal::<Vulkan>() }
        .is_some_and(|d| d.enabled_device_extensions().contains(&EXTENSION))
}

/// The Vulkan objects an import needs, read from the context's device.
struct Vk {
    instance: ash::Instance,
    physical: vk::PhysicalDevice,
    device: ash::Device,
    host: ash::ext::external_memory_host::Device,
    /// `minImportedHostPointerAlignment`: imports start and end on such a boundary.
    align: u64,
    /// The driver is lavapipe (see the module's documentation).
    lavapipe: bool,
}

/// A Vulkan object made here over imported memory.
#[derive(Clone, Copy)]
enum Made {
    Image(vk::Image),
    Buffer(vk::Buffer),
}

/// Destroys `made` and frees its memory, if any: on a path that does not hand it to wgpu,
/// or from wgpu's drop callback once it has destroyed its texture or buffer.
///
/// # Safety
/// `made` and `memory` are `device`'s, and nothing uses them any more.
unsafe fn release(device: &ash::Device, made: Made, memory: Option<vk::DeviceMemory>) {
    // SAFETY: the caller's promise.
    unsafe {
        match made {
            Made::Image(image) => device.destroy_image(image, None),
            Made::Buffer(buffer) => device.destroy_buffer(buffer, None),
        }
        if let Some(m) = memory {
            device.free_memory(m, None);
        }
    }
}

/// wgpu's drop callback for `made` over `memory`: releases both, then `keep` (what owns the
/// imported pages).
fn drop_callback(
    device: &ash::Device,
    made: Made,
    memory: vk::DeviceMemory,
    keep: impl Send + Sync + 'static,
) -> hal::DropCallback {
    let device = device.clone();
    Box::new(move || {
        // SAFETY: wgpu calls this once it has destroyed its texture or buffer, after the
        // device is done with it.
        unsafe { release(&device, made, Some(memory)) };
        drop(keep);
    })
}

/// The handle type of host memory imports.
const HOST: vk::ExternalMemoryHandleTypeFlags =
    vk::ExternalMemoryHandleTypeFlags::HOST_ALLOCATION_EXT;

impl Vk {
    /// Where the context's device imports host memory and may
    /// ([`GpuContext::import_host_memory`]).
    fn of(ctx: &GpuContext) -> Option<Vk> {
        if !ctx.import_host_memory || !enabled(&ctx.device) {
            return None;
        }
        // SAFETY: the hal device is only read; the ash handles cloned from it stay valid
        // while the wgpu device lives, which outlives every import (they are its objects).
        unsafe {
            let hal_device = ctx.device.as_hal::<Vulkan>()?;
            let instance = hal_device.shared_instance().raw_instance().clone();
            let physical = hal_device.raw_physical_device();
            let device = hal_device.raw_device().clone();
            let mut host_props = vk::PhysicalDeviceExternalMemoryHostPropertiesEXT::default();
            let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut host_props);
            instance.get_physical_device_properties2(physical, &mut props);
            let align = host_props.min_imported_host_pointer_alignment.max(1);
            if !align.is_power_of_two() {
                return None;
            }
            let host = ash::ext::external_memory_host::Device::new(&instance, &device);
            Some(Vk {
                instance,
                physical,
                device,
                host,
                align,
                lavapipe: ctx.device.adapter_info().driver == "llvmpipe",
            })
        }
    }

    /// Whether a linear rgba32uint storage image of 4096 × `rows` texels can be made over
    /// imported host memory.
    fn image_importable(&self, rows: u32) -> bool {
        let mut external = vk::PhysicalDeviceExternalImageFormatInfo::default().handle_type(HOST);
        let info = vk::PhysicalDeviceImageFormatInfo2::default()
            .format(vk::Format::R32G32B32A32_UINT)
            .ty(vk::ImageType::TYPE_2D)
            .tiling(vk::ImageTiling::LINEAR)
            .usage(vk::ImageUsageFlags::STORAGE)
            .push_next(&mut external);
        let mut external_props = vk::ExternalImageFormatProperties::default();
        let mut props = vk::ImageFormatProperties2::default().push_next(&mut external_props);
        // SAFETY: valid structures for the device's own physical device.
        let asked = unsafe {
            self.instance.get_physical_device_image_format_properties2(
                self.physical,
                &info,
                &mut props,
            )
        };
        let extent = props.image_format_properties.max_extent;
        let features = external_props
            .external_memory_properties
            .external_memory_features;
        asked.is_ok()
            && features.contains(vk::ExternalMemoryFeatureFlags::IMPORTABLE)
            && extent.width >= TEXEL_ROW
            && extent.height >= rows
    }

    /// Whether a storage buffer can be made over imported host memory.
    fn buffer_importable(&self) -> bool {
        let info = vk::PhysicalDeviceExternalBufferInfo::default()
            .usage(vk::BufferUsageFlags::STORAGE_BUFFER)
            .handle_type(HOST);
        let mut props = vk::ExternalBufferProperties::default();
        // SAFETY: valid structures for the device's own physical device.
        unsafe {
            self.instance
                .get_physical_device_external_buffer_properties(self.physical, &info, &mut props)
        };
        let features = props.external_memory_properties.external_memory_features;
        features.contains(vk::ExternalMemoryFeatureFlags::IMPORTABLE)
    }

    /// Device memory over the host pages that hold `[ptr, ptr + size)` (from the page
    /// holding `ptr`, to the end of the page holding the last byte), with the offset of
    /// `ptr` in it; None where the driver refuses it or `type_bits` allows no memory type
    /// it offers for them.
    ///
    /// # Safety
    /// `[ptr, ptr + size)` must be allocated memory that outlives the returned memory and
    /// that nothing writes while the device reads it.
    unsafe fn import(
        &self,
        ptr: *const u8,
        size: u64,
        type_bits: u32,
    ) -> Option<(vk::DeviceMemory, u64)> {
        let addr = ptr as u64;
        let base = addr & !(self.align - 1);
        let offset = addr - base;
        let len = (offset + size).div_ceil(self.align) * self.align;
        let handle = HOST;
        let mut props = vk::MemoryHostPointerPropertiesEXT::default();
        // SAFETY: the caller's promise; the pages from `base` to `base + len` hold part of
        // the allocation, so they are mapped.
        unsafe {
            let query = self.host.fp().get_memory_host_pointer_properties_ext;
            let asked = query(
                self.host.device(),
                handle,
                base as *const c_void,
                &mut props,
            );
            if asked != vk::Result::SUCCESS {
                return None;
            }
            let types = props.memory_type_bits & type_bits;
            if types == 0 {
                return None;
            }
            let mut from_host = vk::ImportMemoryHostPointerInfoEXT::default()
                .handle_type(handle)
                .host_pointer(base as *mut c_void);
            let info = vk::MemoryAllocateInfo::default()
                .allocation_size(len)
                .memory_type_index(types.trailing_zeros())
                .push_next(&mut from_host);
            let memory = self.device.allocate_memory(&info, None).ok()?;
            Some((memory, offset))
        }
    }
}

/// `bytes` (whole 16-byte words, `room` bytes allocated from their start) as an rgba32uint
/// storage texture of [`TEXEL_ROW`] texels a row, read in place; `keep` (what owns the
/// memory) is dropped once wgpu has destroyed the texture. None where this device cannot
/// (see the module's documentation): the caller copies instead.
///
/// # Safety
/// `bytes` and the `room` bytes from their start must stay allocated while `keep` lives,
/// and nothing may write them meanwhile.
pub(crate) unsafe fn texture(
    ctx: &GpuContext,
    what: &str,
    bytes: &[u8],
    room: usize,
    keep: impl Send + Sync + 'static,
) -> Option<wgpu::Texture> {
    let vk = Vk::of(ctx)?;
    let row_bytes = TEXEL_ROW as u64 * 16;
    let rows = u32::try_from((bytes.len() as u64).div_ceil(row_bytes).max(1)).ok()?;
    if !vk.lavapipe || !vk.image_importable(rows) {
        return None;
    }
    let mut external = vk::ExternalMemoryImageCreateInfo::default().handle_types(HOST);
    let info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(vk::Format::R32G32B32A32_UINT)
        .extent(vk::Extent3D {
            width: TEXEL_ROW,
            height: rows,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::LINEAR)
        .usage(vk::ImageUsageFlags::STORAGE)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED)
        .push_next(&mut external);
    // SAFETY: the image is destroyed below on every path that does not hand it to wgpu;
    // the memory imported is the caller's, as promised.
    unsafe {
        let image = vk.device.create_image(&info, None).ok()?;
        let destroy = |memory| {
            release(&vk.device, Made::Image(image), memory);
            None
        };
        let req = vk.device.get_image_memory_requirements(image);
        let sub = vk::ImageSubresource {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            array_layer: 0,
        };
        let layout = vk.device.get_image_subresource_layout(image, sub);
        // The texels must lie where the words are: row after row, from the first byte, and
        // the image's memory within the allocation, starting on its alignment (which must
        // divide the import's, so that the offset into the imported pages keeps it).
        let in_place = layout.offset == 0 && layout.row_pitch == row_bytes;
        let align = req.alignment.max(1);
        let aligned = align <= vk.align && (bytes.as_ptr() as u64).is_multiple_of(align);
        if !in_place || !aligned || req.size > room as u64 {
            log::debug!(
                "{what}: not imported (row pitch {}, offset {}, alignment {align}, {} bytes \
                 needed of {room})",
                layout.row_pitch,
                layout.offset,
                req.size
            );
            return destroy(None);
        }
        let Some((memory, offset)) = vk.import(bytes.as_ptr(), req.size, req.memory_type_bits)
        else {
            return destroy(None);
        };
        if vk.device.bind_image_memory(image, memory, offset).is_err() {
            return destroy(Some(memory));
        }
        let Some(hal_device) = ctx.device.as_hal::<Vulkan>() else {
            return destroy(Some(memory));
        };
        let size = wgpu::Extent3d {
            width: TEXEL_ROW,
            height: rows,
            depth_or_array_layers: 1,
        };
        let hal_desc = hal::TextureDescriptor {
            label: Some(what),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Uint,
            usage: wgpu::TextureUses::STORAGE_READ_ONLY,
            memory_flags: hal::MemoryFlags::empty(),
            view_formats: Vec::new(),
        };
        let on_drop = drop_callback(&vk.device, Made::Image(image), memory, keep);
        let hal_texture = hal_device.texture_from_raw(
            image,
            &hal_desc,
            Some(on_drop),
            hal::vulkan::TextureMemory::External,
        );
        drop(hal_device);
        let desc = wgpu::TextureDescriptor {
            label: Some(what),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Uint,
            usage: wgpu::TextureUsages::STORAGE_BINDING,
            view_formats: &[],
        };
        // In the undefined layout, as made: wgpu moves it to the storage layout on first
        // use, and counts it initialised (it is never cleared).
        Some(ctx.device.create_texture_from_hal::<Vulkan>(
            hal_texture,
            &desc,
            wgpu::TextureUses::UNINITIALIZED,
        ))
    }
}

/// `bytes` (whole 16-byte words, `room` bytes allocated from their start) as a storage
/// buffer read in place, as [`texture`] does, and the byte of the buffer they start at: a
/// buffer's memory must start on the driver's alignment (lavapipe: 64 bytes), so it starts
/// that far before the words where they are not so aligned (the bindings then start at
/// the words). None where this device cannot; `keep` is dropped once wgpu has destroyed the
/// buffer.
///
/// # Safety
/// As for [`texture`].
pub(crate) unsafe fn buffer(
    ctx: &GpuContext,
    what: &str,
    bytes: &[u8],
    room: usize,
    keep: impl Send + Sync + 'static,
) -> Option<(wgpu::Buffer, u64)> {
    let vk = Vk::of(ctx)?;
    if !vk.buffer_importable() {
        return None;
    }
    let create = |size: u64| {
        let mut external = vk::ExternalMemoryBufferCreateInfo::default().handle_types(HOST);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(vk::BufferUsageFlags::STORAGE_BUFFER)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .push_next(&mut external);
        // SAFETY: a valid create info on the context's device; destroyed below unless
        // handed to wgpu.
        unsafe { vk.device.create_buffer(&info, None).ok() }
    };
    // SAFETY: as in `texture`.
    unsafe {
        // The alignment does not depend on the size: asked of a buffer of the words' size.
        let probe = create(bytes.len() as u64)?;
        let align = vk
            .device
            .get_buffer_memory_requirements(probe)
            .alignment
            .max(1);
        vk.device.destroy_buffer(probe, None);
        let start = bytes.as_ptr() as u64 % align;
        let offsets = ctx.limits.min_storage_buffer_offset_alignment.max(1) as u64;
        if !start.is_multiple_of(offsets) {
            log::debug!("{what}: not imported (at {start} bytes past a buffer's alignment)");
            return None;
        }
        let size = start + bytes.len() as u64;
        let raw = create(size)?;
        let destroy = |memory| {
            release(&vk.device, Made::Buffer(raw), memory);
            None
        };
        let req = vk.device.get_buffer_memory_requirements(raw);
        // The buffer's first byte, `start` bytes before the words, lies in the page that
        // holds the words' first byte (align ≤ the import alignment), so it is mapped.
        let first = bytes.as_ptr().wrapping_sub(start as usize);
        let fits = req.size <= start + room as u64 && req.alignment <= vk.align;
        if !fits || !(first as u64).is_multiple_of(req.alignment.max(1)) {
            log::debug!("{what}: not imported ({} bytes needed of {room})", req.size);
            return destroy(None);
        }
        let Some((memory, offset)) = vk.import(first, req.size, req.memory_type_bits) else {
            return destroy(None);
        };
        if vk.device.bind_buffer_memory(raw, memory, offset).is_err() {
            return destroy(Some(memory));
        }
        let on_drop = drop_callback(&vk.device, Made::Buffer(raw), memory, keep);
        let hal_buffer = hal::vulkan::Buffer::from_raw_externally_owned(raw, on_drop);
        let buffer = ctx.device.create_buffer_from_hal::<Vulkan>(
            hal_buffer,
            &wgpu::BufferDescriptor {
                label: Some(what),
                size,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            },
        );
        Some((buffer, start))
    }
}
