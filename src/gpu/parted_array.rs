//! A storage array a kernel reaches only through generated WGSL accessors, so that it may be
//! bound in several parts where one storage binding cannot hold it (DESIGN: arrays beyond one
//! binding are split, not refused). The array stays one buffer; part k binds bytes
//! [k·2^s, (k+1)·2^s) of it, 2^s the largest power of two one binding holds. The accessors
//! pick the part by the element index's high bits:
//!
//! - `NAME_at(i)` reads element i; `NAME_set(i, v)` writes it (a read-write array);
//! - `NAME_load(i)`, `NAME_store(i, v)`, `NAME_max(i, v)` and `NAME_add(i, v)` (the last two
//!   returning the old value) for an array of `atomic<u32>`.
//!
//! The word arrays of the trace and render kernels have their own readers
//! ([`BufferParts`](super::BufferParts)); these serve kernels whose arrays hold other
//! element types (the GPU BVH build).

use std::fmt::Write;

use super::buffer_parts::{by_part, part_var};
use super::plumbing::storage_entry;
use super::GpuContext;
use crate::error::{Error, Result};
use crate::util::human_bytes;

/// How a kernel module reaches an array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Access {
    /// `NAME_at` only (bound read-only).
    Read,
    /// `NAME_at` and `NAME_set`.
    ReadWrite,
    /// `atomic<u32>` elements: `NAME_load`, `NAME_store`, `NAME_max`, `NAME_add`.
    Atomic,
}

/// Most parts one array may be bound in.
pub(crate) const MAX_PARTS: u32 = 32;

/// One storage array of a kernel module: its WGSL name and element type, how the module
/// reaches it, and the binding of its part 0 (part k at [`PartedArray::part_binding`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PartedArray {
    pub name: &'static str,
    /// `u32`, `f32`, `vec2<u32>` or `vec4<u32>` (`u32` for an atomic array).
    pub ty: &'static str,
    pub access: Access,
    /// Part 0's binding (see [`PartedArray::part_binding`]).
    pub binding: u32,
}

/// Bindings of parts k ≥ 1 start here: part k of the array at binding b is at
/// `PART_BINDINGS + MAX_PARTS·b + k` (below wgpu's 1,000 bindings a group for b ≤ 27).
pub(crate) const PART_BINDINGS: u32 = 100;

impl PartedArray {
    /// Bytes of one element.
    pub fn element_bytes(&self) -> u64 {
        match self.ty {
            "vec2<u32>" => 8,
            "vec4<u32>" => 16,
            _ => 4,
        }
    }

    /// The binding of part `k`.
    pub const fn part_binding(&self, k: u32) -> u32 {
        match k {
            0 => self.binding,
            k => PART_BINDINGS + MAX_PARTS * self.binding + k,
        }
    }

    /// The declarations of its `parts` parts (of 2^`byte_shift` bytes each) and its
    /// accessors.
    pub fn wgsl(&self, parts: u32, byte_shift: u32) -> String {
        let (name, ty) = (self.name, self.ty);
        let shift = byte_shift - self.element_bytes().ilog2();
        let (access, element) = match self.access {
            Access::Read => ("read", ty.to_string()),
            Access::ReadWrite => ("read_write", ty.to_string()),
            Access::Atomic => ("read_write", format!("atomic<{ty}>")),
        };
        let mut s = String::new();
        for k in 0..parts {
            let var = part_var(name, k);
            let b = self.part_binding(k);
            // Writing to a String cannot fail.
            let _ = writeln!(
                s,
                "@group(0) @binding({b}) var<storage, {access}> {var}: array<{element}>;"
            );
        }
        let mut function = |signature: String, step: &dyn Fn(&str, &str) -> String| {
            let _ = writeln!(s, "fn {name}_{signature} {{");
            s += &by_part(name, parts, shift, step);
            s += "}\n";
        };
        match self.access {
            Access::Read | Access::ReadWrite => {
                function(format!("at(i: u32) -> {ty}"), &|v, j| {
                    format!("return {v}[{j}];")
                });
                if self.access == Access::ReadWrite {
                    function(format!("set(i: u32, value: {ty})"), &|v, j| {
                        format!("{v}[{j}] = value;")
                    });
                }
            }
            Access::Atomic => {
                function(format!("load(i: u32) -> {ty}"), &|v, j| {
                    format!("return atomicLoad(&{v}[{j}]);")
                });
                function(format!("store(i: u32, value: {ty})"), &|v, j| {
                    format!("atomicStore(&{v}[{j}], value);")
                });
                function(format!("max(i: u32, value: {ty}) -> {ty}"), &|v, j| {
                    format!("return atomicMax(&{v}[{j}], value);")
                });
                function(format!("add(i: u32, value: {ty}) -> {ty}"), &|v, j| {
                    format!("return atomicAdd(&{v}[{j}], value);")
                });
            }
        }
        s
    }

    /// The layout entries of its parts, for an array of `bytes`.
    pub fn layout_entries(&self, ctx: &GpuContext, bytes: u64) -> Vec<wgpu::BindGroupLayoutEntry> {
        let read_only = self.access == Access::Read;
        (0..parts(ctx, bytes))
            .map(|k| storage_entry(self.part_binding(k), read_only))
            .collect()
    }

    /// The bind-group entries of its parts in `buffer`.
    pub fn bind_entries<'b>(
        &self,
        ctx: &GpuContext,
        buffer: &'b wgpu::Buffer,
    ) -> Vec<wgpu::BindGroupEntry<'b>> {
        let (size, part) = (buffer.size(), 1u64 << byte_shift(ctx));
        (0..parts(ctx, size))
            .map(|k| {
                let offset = k as u64 * part;
                wgpu::BindGroupEntry {
                    binding: self.part_binding(k),
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer,
                        offset,
                        size: wgpu::BufferSize::new(part.min(size - offset)),
                    }),
                }
            })
            .collect()
    }

    /// Refuses an array of `bytes` (`what`, for messages) that one buffer bound in at most
    /// [`MAX_PARTS`] parts cannot hold on this device, or whose elements a u32 cannot
    /// index, naming the size and the limit.
    pub fn check(&self, ctx: &GpuContext, what: &str, bytes: u64) -> Result<()> {
        let part = 1u64 << byte_shift(ctx);
        let max = (ctx.limits.max_buffer_size)
            .min(part * MAX_PARTS as u64)
            .min(self.element_bytes() << 32);
        if bytes > max {
            return Err(Error::Gpu(format!(
                "{what} need {} but {} holds at most {} in one array (max_buffer_size {}, \
                 {MAX_PARTS} storage bindings of {}, 2^32 elements); use a smaller scene or \
                 build on the CPU",
                human_bytes(bytes),
                ctx.adapter.name,
                human_bytes(max),
                human_bytes(ctx.limits.max_buffer_size),
                human_bytes(part),
            )));
        }
        Ok(())
    }
}

/// log2 of the bytes one part holds: the largest power of two that one storage binding
/// (and one buffer) holds, at least the storage offset alignment.
pub(crate) fn byte_shift(ctx: &GpuContext) -> u32 {
    let l = &ctx.limits;
    let bytes = l
        .max_storage_buffer_binding_size
        .min(l.max_buffer_size)
        .max(16);
    let align = (l.min_storage_buffer_offset_alignment as u64).max(16);
    bytes.ilog2().max(align.next_power_of_two().ilog2()).min(31)
}

/// The parts an array of `bytes` is bound in.
pub(crate) fn parts(ctx: &GpuContext, bytes: u64) -> u32 {
    bytes.div_ceil(1u64 << byte_shift(ctx)).max(1) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parted_accessors_parse_and_pick_parts_by_the_high_bits() {
        let arrays = [
            PartedArray {
                name: "boxes",
                ty: "u32",
                access: Access::Atomic,
                binding: 3,
            },
            PartedArray {
                name: "info",
                ty: "vec4<u32>",
                access: Access::ReadWrite,
                binding: 4,
            },
            PartedArray {
                name: "xs",
                ty: "f32",
                access: Access::Read,
                binding: 5,
            },
        ];
        // Parts of 2^10 bytes: 256 u32s, 64 vec4s.
        let wgsl: String = arrays.iter().map(|a| a.wgsl(3, 10)).collect();
        assert!(wgsl.contains("switch i >> 8u"), "{wgsl}");
        assert!(wgsl.contains("switch i >> 6u"), "{wgsl}");
        assert!(
            wgsl.contains("default: { return atomicMax(&boxes_2[j], value); }"),
            "{wgsl}"
        );
        assert!(
            wgsl.contains("@group(0) @binding(229) var<storage, read_write> info_1"),
            "{wgsl}"
        );
        assert!(
            wgsl.contains("var<storage, read> xs_2: array<f32>"),
            "{wgsl}"
        );
        let one: String = arrays.iter().map(|a| a.wgsl(1, 10)).collect();
        assert!(one.contains("return xs[i];"), "{one}");
        for src in [wgsl, one] {
            let module = naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::empty(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{src}\n{e:?}"));
        }
    }
}
