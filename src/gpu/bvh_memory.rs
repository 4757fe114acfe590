//! A layout's arrays on the device, in one of two kinds of memory.
//! `shaders/lib/traversal.wgsl` declares both and reads one, chosen by its `BVH_TEXTURES`
//! override; the other pair of bindings gets a one-word placeholder.

use crate::accel::{GpuForm, LeafTri};
use crate::error::{Error, Result};

use super::bindings;
use super::context::UPLOAD_SLICE;
use super::plumbing::{storage_entry, texel_entry};
use super::GpuContext;
use crate::util::human_bytes;

/// Where the kernels read nodes and triangles from (and the render kernel its shading
/// triangles). The words are the same; only the kind of binding differs: a texture holds
/// more than one storage binding may (lavapipe: 128 MiB).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum BvhMemory {
    /// Read-only storage buffers.
    Buffers,
    /// Read-only rgba32uint storage textures, TEXEL_ROW texels a row.
    /// lavapipe loads these with a gather instead of a per-lane loop: ~18% more rays/s there.
    #[cfg_attr(
        feature = "cli",
        value(help = "Read-only storage textures (lavapipe gathers their loads: faster there)")
    )]
    #[default]
    Textures,
}

/// Texels (16-byte words) per texture row (generated into the WGSL prelude).
pub const TEXEL_ROW: u32 = 4096;

/// Nodes and triangles uploaded in the chosen memory.
pub struct GpuBvh {
    /// Where they live.
    pub memory: BvhMemory,
    node_buf: wgpu::Buffer,
    tri_buf: wgpu::Buffer,
    /// The node and triangle textures (placeholders in buffer memory), for writes over
    /// part of them.
    node_texture: wgpu::Texture,
    tri_texture: wgpu::Texture,
    node_tex: wgpu::TextureView,
    tri_tex: wgpu::TextureView,
}

impl GpuBvh {
    /// Validates and uploads a layout's arrays (with no triangle, one unused zero triangle
    /// is bound); refuses an invalid layout (trusted modules rely on its indices) and sizes
    /// the device cannot bind, naming the size and the limit.
    pub fn upload(ctx: &GpuContext, layout: &dyn GpuForm, memory: BvhMemory) -> Result<GpuBvh> {
        layout
            .validate()
            .map_err(|e| Error::Gpu(format!("refusing to upload an invalid BVH: {e}")))?;
        let arrays = layout.arrays();
        let pad: [LeafTri; 1] = [bytemuck::Zeroable::zeroed()];
        let nodes: &[u8] = arrays.nodes;
        let tris: &[u8] = if arrays.tris.is_empty() {
            bytemuck::cast_slice(&pad)
        } else {
            arrays.tris
        };
        // Both sizes checked before either array is uploaded.
        fits(ctx, memory, "the BVH nodes", nodes.len())?;
        fits(ctx, memory, "the triangles", tris.len())?;
        let (node_buf, node_texture) = words_in_memory(ctx, memory, "the BVH nodes", nodes)?;
        let (tri_buf, tri_texture) = words_in_memory(ctx, memory, "the triangles", tris)?;
        let bvh = GpuBvh {
            memory,
            node_buf,
            tri_buf,
            node_tex: node_texture.create_view(&Default::default()),
            tri_tex: tri_texture.create_view(&Default::default()),
            node_texture,
            tri_texture,
        };
        Ok(bvh)
    }

    /// Writes `bytes` (whole 16-byte words) over the node words from word `first` on, in
    /// either memory: for a structure whose part changed in place
    /// ([`GpuTwoLevel::moved`](crate::accel::instances::GpuTwoLevel::moved)). The caller
    /// has checked that the words so written make a valid structure.
    pub fn write_node_words(&self, ctx: &GpuContext, first: u32, bytes: &[u8]) -> Result<()> {
        self.write_words(ctx, (&self.node_buf, &self.node_texture), first, bytes)
    }

    /// [`GpuBvh::write_node_words`] for the triangles' words.
    pub fn write_tri_words(&self, ctx: &GpuContext, first: u32, bytes: &[u8]) -> Result<()> {
        self.write_words(ctx, (&self.tri_buf, &self.tri_texture), first, bytes)
    }

    /// Writes `bytes` over the words of one array (its buffer and texture) from `first` on.
    fn write_words(
        &self,
        ctx: &GpuContext,
        array: (&wgpu::Buffer, &wgpu::Texture),
        first: u32,
        bytes: &[u8],
    ) -> Result<()> {
        write_words(ctx, self.memory, array, first, bytes)
    }

    /// The override constant that tells traversal.wgsl which bindings to read.
    pub fn override_constant(&self) -> (&'static str, f64) {
        let on = self.memory == BvhMemory::Textures;
        ("BVH_TEXTURES", if on { 1.0 } else { 0.0 })
    }

    /// Bind-group-layout entries of traversal.wgsl's four bindings.
    pub fn layout_entries() -> [wgpu::BindGroupLayoutEntry; 4] {
        [
            storage_entry(bindings::NODE_WORDS, true),
            storage_entry(bindings::TRI_WORDS, true),
            texel_entry(bindings::NODE_TEXELS),
            texel_entry(bindings::TRI_TEXELS),
        ]
    }

    /// Bind-group entries matching [`GpuBvh::layout_entries`].
    pub fn bind_entries(&self) -> [wgpu::BindGroupEntry<'_>; 4] {
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        [
            entry(bindings::NODE_WORDS, self.node_buf.as_entire_binding()),
            entry(bindings::TRI_WORDS, self.tri_buf.as_entire_binding()),
            entry(
                bindings::NODE_TEXELS,
                wgpu::BindingResource::TextureView(&self.node_tex),
            ),
            entry(
                bindings::TRI_TEXELS,
                wgpu::BindingResource::TextureView(&self.tri_tex),
            ),
        ]
    }
}

/// Writes `bytes` (whole 16-byte words) over the words of one array of `memory` (its buffer
/// and texture, as [`words_in_memory`] made them) from word `first` on; refuses words past
/// the array.
pub(crate) fn write_words(
    ctx: &GpuContext,
    memory: BvhMemory,
    (buffer, texture): (&wgpu::Buffer, &wgpu::Texture),
    first: u32,
    bytes: &[u8],
) -> Result<()> {
    let words = bytes.len() / 16;
    if words * 16 != bytes.len() {
        return Err(Error::Usage("words are 16 bytes each".into()));
    }
    match memory {
        BvhMemory::Buffers => {
            let end = (first as u64 + words as u64) * 16;
            if end > buffer.size() {
                return Err(Error::Usage(format!(
                    "words {first}..{} lie past the uploaded {} words",
                    first as u64 + words as u64,
                    buffer.size() / 16
                )));
            }
            ctx.queue.write_buffer(buffer, first as u64 * 16, bytes);
        }
        BvhMemory::Textures => {
            let row = TEXEL_ROW as usize;
            let (mut at, mut rest) = (first as usize, bytes);
            let rows = texture.height() as usize;
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
                let mut to = texture.as_image_copy();
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

/// 16-byte words (`what`, for messages) in `memory`: a storage buffer and a placeholder
/// texture, or a placeholder buffer and a storage texture; refuses sizes the device cannot
/// bind, naming the size and the limit.
pub(crate) fn words_in_memory(
    ctx: &GpuContext,
    memory: BvhMemory,
    what: &str,
    bytes: &[u8],
) -> Result<(wgpu::Buffer, wgpu::Texture)> {
    let word = [0u8; 16];
    // COPY_DST: a part may be written over later (GpuBvh::write_node_words).
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
    let storage = |label: &str, bytes: &[u8]| ctx.buffer_with(label, bytes, usage);
    fits(ctx, memory, what, bytes.len())?;
    Ok(match memory {
        BvhMemory::Buffers => (storage(what, bytes), texels(ctx, "unused texels", &word)?),
        BvhMemory::Textures => (storage("unused words", &word), texels(ctx, what, bytes)?),
    })
}

/// Refuses `len` bytes of words (`what`, for messages) that `memory` cannot hold on this
/// device (one storage binding, or a texture of [`TEXEL_ROW`] texels a row), naming the size
/// and the limit.
fn fits(ctx: &GpuContext, memory: BvhMemory, what: &str, len: usize) -> Result<()> {
    if memory == BvhMemory::Buffers {
        return ctx.check_binding(what, len as u64);
    }
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
/// with zeros (its size checked by [`fits`]).
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
    // In slices of whole rows, each waited for (see UPLOAD_SLICE).
    let slice_rows = (UPLOAD_SLICE / row_bytes).max(1);
    for first in (0..full).step_by(slice_rows) {
        let rows = slice_rows.min(full - first);
        let slice = &bytes[first * row_bytes..(first + rows) * row_bytes];
        let mut at = texture.as_image_copy();
        at.origin.y = first as u32;
        ctx.queue.write_texture(at, slice, layout, size(rows));
        ctx.finish_writes();
    }
    let rest = &bytes[full * row_bytes..];
    if !rest.is_empty() {
        let mut last = rest.to_vec();
        last.resize(row_bytes, 0);
        let mut at = texture.as_image_copy();
        at.origin.y = full as u32;
        ctx.queue.write_texture(at, &last, layout, size(1));
    }
    Ok(texture)
}
