//! A layout's arrays on the device, in one of two kinds of memory.
//! `shaders/lib/traversal.wgsl` declares both and reads one, chosen by its `BVH_TEXTURES`
//! override; the other pair of bindings gets a one-word placeholder. An array bigger than
//! one storage binding is bound in parts (`gpu::word_array`).

use std::sync::Arc;

use crate::accel::{GpuForm, LeafTri};
use crate::error::{Error, Result};

use super::word_array::{self, WordArray};
use super::{bindings, BufferParts, GpuContext};

/// Where the kernels read nodes and triangles from (and the render kernel its shading
/// triangles). The words are the same; only the kind of binding differs. Either holds more
/// than one storage binding may (lavapipe: 128 MiB): a texture up to its largest size, a
/// buffer bound in parts (`gpu::word_array`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum BvhMemory {
    /// Read-only storage buffers (an array bigger than one binding is bound in parts).
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
    nodes: WordArray,
    tris: WordArray,
    /// log2 of the words of a buffer part ([`word_array::part_shift`]).
    shift: u32,
}

impl GpuBvh {
    /// Validates and uploads a layout's arrays (with no triangle, one unused zero triangle
    /// is bound); refuses an invalid layout (trusted modules rely on its indices) and sizes
    /// the device cannot hold, naming the size and the limit.
    // Validated before the copies, not beside them (tried: ~30 ms sooner at 4M triangles on
    // lavapipe, but the device's new memory then met the flatten's freed memory before the
    // allocator had returned it: peak 820-920 MB against 700 MB).
    pub fn upload(ctx: &GpuContext, layout: &dyn GpuForm, memory: BvhMemory) -> Result<GpuBvh> {
        Self::upload_with(ctx, layout, memory, None)
    }

    /// [`GpuBvh::upload`] of a layout nothing changes while it is uploaded: where the
    /// device's memory is the host's (a CPU adapter such as lavapipe, with
    /// `VK_EXT_external_memory_host`), its arrays are read where they lie instead of being
    /// copied, and the layout is held until the device is done with them. Its words cannot
    /// then be written over ([`GpuBvh::write_node_words`] refuses).
    pub fn upload_shared(
        ctx: &GpuContext,
        layout: &Arc<dyn GpuForm>,
        memory: BvhMemory,
    ) -> Result<GpuBvh> {
        Self::upload_with(ctx, layout.as_ref(), memory, Some(layout))
    }

    fn upload_with(
        ctx: &GpuContext,
        layout: &dyn GpuForm,
        memory: BvhMemory,
        keep: Option<&Arc<dyn GpuForm>>,
    ) -> Result<GpuBvh> {
        layout
            .validate()
            .map_err(|e| Error::Gpu(format!("refusing to upload an invalid BVH: {e}")))?;
        let arrays = layout.arrays();
        let pad: [LeafTri; 1] = [bytemuck::Zeroable::zeroed()];
        let nodes: &[u8] = arrays.nodes;
        let (tris, tris_room): (&[u8], usize) = if arrays.tris.is_empty() {
            (bytemuck::cast_slice(&pad), 0)
        } else {
            (arrays.tris, arrays.room()[1])
        };
        // Both sizes checked before either array is uploaded.
        WordArray::check(ctx, memory, "the BVH nodes", nodes.len())?;
        WordArray::check(ctx, memory, "the triangles", tris.len())?;
        let upload = |what: &str, bytes: &[u8], room: usize| match keep {
            // SAFETY: the arrays are the layout's, which the Arc handed on keeps allocated,
            // and nothing writes a layout behind an Arc (GpuForm has no &mut method, and
            // the clone kept makes Arc::get_mut fail).
            Some(keep) if room >= bytes.len() => unsafe {
                WordArray::upload_in_place(ctx, memory, what, (bytes, room), keep.clone())
            },
            _ => WordArray::upload(ctx, memory, what, bytes),
        };
        Ok(GpuBvh {
            memory,
            nodes: upload("the BVH nodes", nodes, arrays.room()[0])?,
            tris: upload("the triangles", tris, tris_room)?,
            shift: word_array::part_shift(ctx),
        })
    }

    /// The parts [`GpuBvh::upload`] would bind `layout`'s arrays in, in `memory` (the render
    /// kernel's arrays left at one), their sizes checked as it checks them: to check a
    /// kernel's bindings before anything is uploaded.
    pub fn checked_parts(
        ctx: &GpuContext,
        layout: &dyn GpuForm,
        memory: BvhMemory,
    ) -> Result<BufferParts> {
        let arrays = layout.arrays();
        // With no triangle, one unused zero triangle is bound (see upload).
        let tris = arrays.tris.len().max(std::mem::size_of::<LeafTri>());
        WordArray::check(ctx, memory, "the BVH nodes", arrays.nodes.len())?;
        WordArray::check(ctx, memory, "the triangles", tris)?;
        let parts = |len: usize| word_array::parts_for(ctx, memory, len as u64);
        Ok(BufferParts {
            nodes: parts(arrays.nodes.len()),
            tris: parts(tris),
            shift: word_array::part_shift(ctx),
            ..BufferParts::WHOLE
        })
    }

    /// Writes `bytes` (whole 16-byte words) over the node words from word `first` on, in
    /// either memory: for a structure whose part changed in place
    /// ([`GpuTwoLevel::moved`](crate::accel::instances::GpuTwoLevel::moved)). The caller
    /// has checked that the words so written make a valid structure.
    pub fn write_node_words(&self, ctx: &GpuContext, first: u32, bytes: &[u8]) -> Result<()> {
        self.nodes.write(ctx, first, bytes)
    }

    /// [`GpuBvh::write_node_words`] for the triangles' words.
    pub fn write_tri_words(&self, ctx: &GpuContext, first: u32, bytes: &[u8]) -> Result<()> {
        self.tris.write(ctx, first, bytes)
    }

    /// Whether the nodes and the triangles are read where the host holds them
    /// ([`GpuBvh::upload_shared`]) rather than copied.
    pub fn in_place(&self) -> [bool; 2] {
        [self.nodes.in_place(), self.tris.in_place()]
    }

    /// The override constant that tells traversal.wgsl which bindings to read.
    pub fn override_constant(&self) -> (&'static str, f64) {
        let on = self.memory == BvhMemory::Textures;
        ("BVH_TEXTURES", if on { 1.0 } else { 0.0 })
    }

    /// The parts the node and triangle buffers are bound in (the render kernel's arrays left
    /// at one), which the kernel's source must be generated for ([`BufferParts::bvh_wgsl`]).
    pub fn parts(&self) -> BufferParts {
        BufferParts {
            nodes: self.nodes.parts(),
            tris: self.tris.parts(),
            shift: self.shift,
            ..BufferParts::WHOLE
        }
    }

    /// Bind-group-layout entries of traversal.wgsl's bindings: each buffer part and the
    /// texture of both arrays.
    pub fn layout_entries(&self) -> Vec<wgpu::BindGroupLayoutEntry> {
        let mut entries = self.nodes.layout_entries(bindings::NODE_ARRAY);
        entries.extend(self.tris.layout_entries(bindings::TRI_ARRAY));
        entries
    }

    /// Bind-group entries matching [`GpuBvh::layout_entries`].
    pub fn bind_entries(&self) -> Vec<wgpu::BindGroupEntry<'_>> {
        let mut entries = self.nodes.bind_entries(bindings::NODE_ARRAY);
        entries.extend(self.tris.bind_entries(bindings::TRI_ARRAY));
        entries
    }
}
