//! One array of 16-byte words on the device, in either BVH memory: a storage buffer, or a
//! read-only rgba32uint storage texture of [`TEXEL_ROW`] texels a row. The kernels declare
//! both kinds; the one not used is a one-word placeholder.
//!
//! One storage binding holds at most `max_storage_buffer_binding_size` (lavapipe: 128 MiB). A
//! bigger array in buffer memory stays one buffer, bound in parts of 2^[`part_shift`] words;
//! the kernel reads it through the WGSL reader [`BufferParts`](super::BufferParts) generates
//! for that many parts.

use crate::error::{Error, Result};
use crate::util::human_bytes;

use super::bindings::ArrayBindings;
use super::context::{SlicedWrites, UPLOAD_SLICE};
use super::plumbing::{storage_entry, texel_entry};
use super::{BvhMemory, GpuContext, TEXEL_ROW};

/// Most parts one array may be bound in (their binding numbers are
/// [`ArrayBindings::parts`]` + k`, 100 below the next array's).
pub const MAX_PARTS: u32 = 64;
const _: () = assert!(MAX_PARTS < 100);

/// Most words an array may have: the kernels index them with a u32.
const MAX_WORDS: u64 = 1 << 32;

/// 16-byte words in one of the two memories (see the module's documentation).
pub(crate) struct WordArray {
    memory: BvhMemory,
    /// The kernel writes it (its parts are bound read-write).
    writable: bool,
    buffer: wgpu::Buffer,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    /// The buffer's byte ranges its parts bind (one part: the whole buffer).
    parts: Vec<(u64, u64)>,
    /// The words are read where the host holds them ([`WordArray::upload_in_place`]).
    in_place: bool,
}

/// The words one buffer part holds, as a power of two: the largest that one storage binding
/// (and one buffer) holds, at least the storage offset alignment.
pub(crate) fn part_shift(ctx: &GpuContext) -> u32 {
    let l = &ctx.limits;
    let words = (l.max_storage_buffer_binding_size.min(l.max_buffer_size) / 16).max(1);
    let align_words = (l.min_storage_buffer_offset_alignment as u64 / 16).max(1);
    words
        .ilog2()
        .max(align_words.next_power_of_two().ilog2())
        .min(31)
}

impl WordArray {
    /// Uploads `bytes` (whole 16-byte words; `what` names them in messages; none: one zero
    /// word) into `memory`; refuses sizes the device cannot hold, naming the size and the
    /// limit.
    pub fn upload(
        ctx: &GpuContext,
        memory: BvhMemory,
        what: &str,
        bytes: &[u8],
    ) -> Result<WordArray> {
        let word = [0u8; 16];
        // A binding is never empty.
        let bytes = if bytes.is_empty() { &word[..] } else { bytes };
        // COPY_DST: a part may be written over later (WordArray::write).
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        WordArray::check(ctx, memory, what, bytes.len())?;
        let (buffer, texture) = match memory {
            BvhMemory::Buffers => {
                let unused = texels(ctx, "unused texels", &word)?;
                (ctx.buffer_with(what, bytes, usage), unused)
            }
            BvhMemory::Textures => {
                let unused = ctx.buffer_with("unused words", &word, usage);
                (unused, texels(ctx, what, bytes)?)
            }
        };
        Ok(WordArray::bound(
            ctx,
            what,
            memory,
            false,
            (buffer, texture),
            0,
        ))
    }

    /// [`WordArray::upload`], but where the device's memory is the host's and can take the
    /// array in place (`gpu::host_import`), `bytes` are read where they lie instead of being
    /// copied: `room` bytes are allocated from their start, and `keep`, which owns them, is
    /// held until the device is done with them. Such an array cannot be written over
    /// ([`WordArray::write`] refuses it).
    ///
    /// # Safety
    /// `bytes` and the `room` bytes from their start must stay allocated while `keep` lives,
    /// and nothing may write them meanwhile.
    pub unsafe fn upload_in_place(
        ctx: &GpuContext,
        memory: BvhMemory,
        what: &str,
        (bytes, room): (&[u8], usize),
        keep: impl Send + Sync + 'static,
    ) -> Result<WordArray> {
        WordArray::check(ctx, memory, what, bytes.len())?;
        let word = [0u8; 16];
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        // SAFETY: the caller's promise.
        let imported = unsafe {
            match memory {
                _ if bytes.is_empty() => None,
                BvhMemory::Buffers => super::host_import::buffer(ctx, what, bytes, room, keep)
                    .map(|(b, start)| (b, texels(ctx, "unused texels", &word), start)),
                BvhMemory::Textures => super::host_import::texture(ctx, what, bytes, room, keep)
                    .map(|t| (ctx.buffer_with("unused words", &word, usage), Ok(t), 0)),
            }
        };
        let Some((buffer, texture, start)) = imported else {
            return WordArray::upload(ctx, memory, what, bytes);
        };
        log::debug!("{what} ({}) read in place", human_bytes(bytes.len() as u64));
        let mut array = WordArray::bound(ctx, what, memory, false, (buffer, texture?), start);
        array.in_place = true;
        Ok(array)
    }

    /// A zeroed storage buffer of `len` bytes (whole 16-byte words; `what` names them in
    /// messages) that the kernel writes and the host reads back, bound in parts where one
    /// binding cannot hold it; refuses sizes the device cannot hold, naming the limit.
    pub fn output(ctx: &GpuContext, what: &str, len: u64) -> Result<WordArray> {
        check_buffer(ctx, what, len)?;
        let buffer = super::plumbing::output_buffer(ctx, what, len);
        let texture = texels(ctx, "unused texels", &[0u8; 16])?;
        Ok(WordArray::bound(
            ctx,
            what,
            BvhMemory::Buffers,
            true,
            (buffer, texture),
            0,
        ))
    }

    /// The array made of its buffer and texture: the buffer's parts from byte `start` on
    /// (logged where there are several) and the texture's view.
    fn bound(
        ctx: &GpuContext,
        what: &str,
        memory: BvhMemory,
        writable: bool,
        (buffer, texture): (wgpu::Buffer, wgpu::Texture),
        start: u64,
    ) -> WordArray {
        let part_bytes = 16u64 << part_shift(ctx);
        let size = buffer.size() - start;
        let parts: Vec<(u64, u64)> = (0..parts_for(ctx, BvhMemory::Buffers, size) as u64)
            .map(|k| {
                (
                    start + k * part_bytes,
                    part_bytes.min(size - k * part_bytes),
                )
            })
            .collect();
        if parts.len() > 1 {
            log::info!(
                "{what} ({}) bound in {} storage bindings of at most {}",
                human_bytes(size),
                parts.len(),
                human_bytes(part_bytes)
            );
        }
        WordArray {
            memory,
            writable,
            view: texture.create_view(&Default::default()),
            buffer,
            texture,
            parts,
            in_place: false,
        }
    }

    /// Whether the words are read where the host holds them
    /// ([`WordArray::upload_in_place`]).
    pub fn in_place(&self) -> bool {
        self.in_place
    }

    /// The buffer (in texture memory, a placeholder): to clear or read back.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Refuses `len` bytes of words (`what`, for messages) that `memory` cannot hold on this
    /// device, naming the size and the limit.
    pub fn check(ctx: &GpuContext, memory: BvhMemory, what: &str, len: usize) -> Result<()> {
        match memory {
            BvhMemory::Buffers => check_buffer(ctx, what, len as u64),
            BvhMemory::Textures => check_texture(ctx, what, len),
        }
    }

    /// The parts its buffer is bound in (1 in texture memory, and for any array one
    /// binding holds).
    pub fn parts(&self) -> u32 {
        self.parts.len() as u32
    }

    /// Bind-group-layout entries of its bindings: each buffer part, and the texture where
    /// the array has a binding for one.
    pub fn layout_entries(&self, at: ArrayBindings) -> Vec<wgpu::BindGroupLayoutEntry> {
        let mut entries: Vec<_> = (0..self.parts())
            .map(|k| storage_entry(part_binding(at, k), !self.writable))
            .collect();
        entries.extend(at.texels.map(texel_entry));
        entries
    }

    /// Bind-group entries matching [`WordArray::layout_entries`].
    pub fn bind_entries(&self, at: ArrayBindings) -> Vec<wgpu::BindGroupEntry<'_>> {
        let mut entries: Vec<_> = (self.parts.iter().enumerate())
            .map(|(k, &(offset, size))| wgpu::BindGroupEntry {
                binding: part_binding(at, k as u32),
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &self.buffer,
                    offset,
                    size: wgpu::BufferSize::new(size),
                }),
            })
            .collect();
        entries.extend(at.texels.map(|binding| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(&self.view),
        }));
        entries
    }

    /// Writes `bytes` (whole 16-byte words) over the words from word `first` on; refuses
    /// words past the array.
    pub fn write(&self, ctx: &GpuContext, first: u32, bytes: &[u8]) -> Result<()> {
        let words = bytes.len() / 16;
        if words * 16 != bytes.len() {
            return Err(Error::Usage("words are 16 bytes each".into()));
        }
        if self.in_place {
            return Err(Error::Usage(
                "these words are read in place from the host and cannot be written over".into(),
            ));
        }
        match self.memory {
            BvhMemory::Buffers => {
                let end = (first as u64 + words as u64) * 16;
                if end > self.buffer.size() {
                    return Err(Error::Usage(format!(
                        "words {first}..{} lie past the uploaded {} words",
                        first as u64 + words as u64,
                        self.buffer.size() / 16
                    )));
                }
                ctx.queue
                    .write_buffer(&self.buffer, first as u64 * 16, bytes);
            }
            BvhMemory::Textures => {
                let row = TEXEL_ROW as usize;
                let (mut at, mut rest) = (first as usize, bytes);
                let rows = self.texture.height() as usize;
                if (at + words).div_ceil(row) > rows {
                    return Err(Error::Usage(format!(
                        "words {first}..{} lie past the uploaded texture",
                        at + words
                    )));
                }
                // One write per row touched: its part of the words.
                while !rest.is_empty() {
                    let (x, y) = (at % row, at / row);
                    let n = (row - x).min(rest.len() / 16);
                    let mut to = self.texture.as_image_copy();
                    to.origin = wgpu::Origin3d {
                        x: x as u32,
                        y: y as u32,
                        z: 0,
                    };
                    let layout = wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some((n * 16) as u32),
                        rows_per_image: None,
                    };
                    let size = wgpu::Extent3d {
                        width: n as u32,
                        height: 1,
                        depth_or_array_layers: 1,
                    };
                    ctx.queue.write_texture(to, &rest[..n * 16], layout, size);
                    (at, rest) = (at + n, &rest[n * 16..]);
                }
            }
        }
        ctx.finish_writes();
        Ok(())
    }
}

/// The parts an array of `len` bytes is bound in, in `memory` (1 in texture memory).
pub(crate) fn parts_for(ctx: &GpuContext, memory: BvhMemory, len: u64) -> u32 {
    match memory {
        BvhMemory::Buffers => len.div_ceil(16u64 << part_shift(ctx)).max(1) as u32,
        BvhMemory::Textures => 1,
    }
}

/// The binding of part `k` of an array bound at `at`.
fn part_binding(at: ArrayBindings, k: u32) -> u32 {
    match k {
        0 => at.words,
        k => at.parts + k,
    }
}

/// Refuses `len` bytes of words (`what`, for messages) that one buffer bound in at most
/// [`MAX_PARTS`] parts cannot hold on this device, naming the size and the limits.
fn check_buffer(ctx: &GpuContext, what: &str, len: u64) -> Result<()> {
    let part = 16u64 << part_shift(ctx);
    let max = (ctx.limits.max_buffer_size)
        .min(part * MAX_PARTS as u64)
        .min(16 * MAX_WORDS);
    if len > max {
        return Err(Error::Gpu(format!(
            "{what} need {} but {} holds at most {} in one buffer (max_buffer_size {}, \
             {MAX_PARTS} storage bindings of {}, 2^32 words); use --bvh-memory textures (for \
             the BVH and shading words), a smaller scene or image, or --device cpu",
            human_bytes(len),
            ctx.adapter.name,
            human_bytes(max),
            human_bytes(ctx.limits.max_buffer_size),
            human_bytes(part),
        )));
    }
    Ok(())
}

/// Refuses `len` bytes of words (`what`, for messages) that a texture of [`TEXEL_ROW`] texels
/// a row cannot hold on this device, naming the size and the limit.
fn check_texture(ctx: &GpuContext, what: &str, len: usize) -> Result<()> {
    let rows = (len / 16).div_ceil(TEXEL_ROW as usize).max(1);
    let max = ctx.limits.max_texture_dimension_2d as usize;
    if rows > max || TEXEL_ROW as usize > max {
        return Err(Error::Gpu(format!(
            "{what} need a texture of {TEXEL_ROW}×{rows} texels ({}) but {} allows at most \
             {max}×{max} (max_texture_dimension_2d); use --bvh-memory buffers, a smaller scene \
             or --device cpu",
            human_bytes(len as u64),
            ctx.adapter.name,
        )));
    }
    Ok(())
}

/// An rgba32uint texture holding `bytes` (a multiple of 16) row by row, the last row padded
/// with zeros (its size checked by [`check_texture`]).
fn texels(ctx: &GpuContext, what: &str, bytes: &[u8]) -> Result<wgpu::Texture> {
    let words = bytes.len() / 16;
    let rows = words.div_ceil(TEXEL_ROW as usize).max(1);
    let size = |rows: usize| wgpu::Extent3d {
        width: TEXEL_ROW,
        height: rows as u32,
        depth_or_array_layers: 1,
    };
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(what),
        size: size(rows),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Uint,
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    // Full rows straight from the caller's bytes; only the last, partial row is copied (the
    // rest of a new texture is zero).
    let row_bytes = TEXEL_ROW as usize * 16;
    let full = bytes.len() / row_bytes;
    let layout = wgpu::TexelCopyBufferLayout {
        offset: 0,
        bytes_per_row: Some(row_bytes as u32),
        rows_per_image: None,
    };
    // In slices of whole rows, the device copying one while the next is staged (SlicedWrites).
    let slice_rows = (UPLOAD_SLICE / row_bytes).max(1);
    let mut slices = SlicedWrites::new(ctx);
    for first in (0..full).step_by(slice_rows) {
        let rows = slice_rows.min(full - first);
        let slice = &bytes[first * row_bytes..(first + rows) * row_bytes];
        let mut at = texture.as_image_copy();
        at.origin.y = first as u32;
        ctx.queue.write_texture(at, slice, layout, size(rows));
        slices.submitted();
    }
    let rest = &bytes[full * row_bytes..];
    if !rest.is_empty() {
        let mut last = rest.to_vec();
        last.resize(row_bytes, 0);
        let mut at = texture.as_image_copy();
        at.origin.y = full as u32;
        ctx.queue.write_texture(at, &last, layout, size(1));
    }
    ctx.finish_writes();
    Ok(texture)
}
