//! The WGSL readers of the word arrays in buffer memory: `node_buffer_word(i)`,
//! `tri_buffer_word(i)` and, in the render kernel, `shade_buffer_word(i)`, `texel(i)` and the
//! accumulator's `accum_load(i)` and `accum_store(i, value)`. An array in one
//! storage binding is read straight; one bound in several parts
//! ([`WordArray`](super::word_array::WordArray)) declares its further parts and picks one by
//! the word index's high bits. Generated, not written once in WGSL, because WGSL cannot
//! declare bindings by an override constant: a kernel declares exactly the parts its arrays
//! have, so a device with wgpu's default limits (8 storage buffers a stage) still runs every
//! scene that fits one binding an array.

use std::fmt::Write;

use crate::error::{Error, Result};
use crate::util::human_bytes;

use super::bindings::{self, ArrayBindings};
use super::GpuContext;

/// How many parts each word array of a kernel is bound in, and the words of one part
/// (2^`shift`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferParts {
    /// Parts of the node words.
    pub nodes: u32,
    /// Parts of the triangle words.
    pub tris: u32,
    /// Parts of the shading words (render kernel).
    pub shades: u32,
    /// Parts of the texels (render kernel).
    pub texels: u32,
    /// Parts of the accumulator (render kernel).
    pub accum: u32,
    /// log2 of the words of one part.
    pub shift: u32,
}

/// One word array's WGSL names and bindings.
struct Array {
    /// Part 0's variable, declared in the WGSL source.
    var: &'static str,
    /// The reader function generated.
    reader: &'static str,
    /// The WGSL element type.
    ty: &'static str,
    /// The writer function generated, for an array the kernel writes (read_write).
    writer: Option<&'static str>,
    bindings: ArrayBindings,
}

const NODES: Array = Array {
    var: "node_words",
    reader: "node_buffer_word",
    ty: "vec4<u32>",
    writer: None,
    bindings: bindings::NODE_ARRAY,
};
const TRIS: Array = Array {
    var: "tri_words",
    reader: "tri_buffer_word",
    ty: "vec4<u32>",
    writer: None,
    bindings: bindings::TRI_ARRAY,
};
const SHADES: Array = Array {
    var: "shade_words",
    reader: "shade_buffer_word",
    ty: "vec4<u32>",
    writer: None,
    bindings: bindings::SHADE_ARRAY,
};
const TEXELS: Array = Array {
    var: "texels",
    reader: "texel",
    ty: "vec4<f32>",
    writer: None,
    bindings: bindings::TEXEL_ARRAY,
};
const ACCUM: Array = Array {
    var: "accum",
    reader: "accum_load",
    ty: "vec4<f32>",
    writer: Some("accum_store"),
    bindings: bindings::ACCUM_ARRAY,
};

impl BufferParts {
    /// Every array in one binding: the kernels as they are checked without a device.
    pub const WHOLE: BufferParts = BufferParts {
        nodes: 1,
        tris: 1,
        shades: 1,
        texels: 1,
        accum: 1,
        shift: 31,
    };

    /// The node and triangle arrays' readers (every kernel that traverses a BVH).
    pub fn bvh_wgsl(&self) -> String {
        let mut s = reader(&NODES, self.nodes, self.shift);
        s += &reader(&TRIS, self.tris, self.shift);
        s
    }

    /// The shading words' and the texels' readers and the accumulator's reader and writer
    /// (the render kernel).
    pub fn render_wgsl(&self) -> String {
        reader(&SHADES, self.shades, self.shift)
            + &reader(&TEXELS, self.texels, self.shift)
            + &reader(&ACCUM, self.accum, self.shift)
    }

    /// Refuses a kernel (`kernel`, for messages; `base` storage buffers of its own with
    /// each array in one part; the shading words', texels' and accumulator's parts counted
    /// when `render`)
    /// that binds more storage buffers than the device allows a shader stage.
    pub fn check(&self, ctx: &GpuContext, kernel: &str, base: u32, render: bool) -> Result<()> {
        let mut extra = self.nodes + self.tris - 2;
        if render {
            extra += self.shades + self.texels + self.accum - 3;
        }
        let (need, max) = (
            base + extra,
            ctx.limits.max_storage_buffers_per_shader_stage,
        );
        if need > max {
            let why = match extra {
                0 => String::new(),
                _ => format!(
                    ", {extra} of them for arrays bigger than one binding of {}",
                    human_bytes(16u64 << self.shift)
                ),
            };
            return Err(Error::Gpu(format!(
                "the {kernel} kernel would bind {need} storage buffers{why}, but {} allows \
                 {max} a shader stage (max_storage_buffers_per_shader_stage); use --bvh-memory \
                 textures (for the BVH and shading words), a smaller scene or image, or \
                 --device cpu",
                ctx.adapter.name
            )));
        }
        Ok(())
    }
}

/// The reader of `array` bound in `parts` parts of 2^`shift` words (and its writer, where
/// the kernel writes it).
fn reader(array: &Array, parts: u32, shift: u32) -> String {
    let (var, f, ty) = (array.var, array.reader, array.ty);
    let access = if array.writer.is_some() {
        "read_write"
    } else {
        "read"
    };
    let mut s = String::new();
    if parts > 1 {
        s += &format!("// {var} in {parts} parts of 2^{shift} words (gpu::word_array)\n");
    }
    for k in 1..parts {
        let binding = array.bindings.parts + k;
        // Writing to a String cannot fail.
        let _ = writeln!(
            s,
            "@group(0) @binding({binding}) var<storage, {access}> {var}_{k}: array<{ty}>;"
        );
    }
    let _ = writeln!(s, "fn {f}(i: u32) -> {ty} {{");
    s += &by_part(var, parts, shift, |v, j| format!("return {v}[{j}];"));
    s += "}\n";
    if let Some(w) = array.writer {
        let _ = writeln!(s, "fn {w}(i: u32, value: {ty}) {{");
        s += &by_part(var, parts, shift, |v, j| format!("{v}[{j}] = value;"));
        s += "}\n";
    }
    s
}

/// The WGSL variable of part `k` of the array `name`.
pub(super) fn part_var(name: &str, k: u32) -> String {
    match k {
        0 => name.to_string(),
        k => format!("{name}_{k}"),
    }
}

/// A function body doing `step(part's variable, index within it)` on word i of `var`, bound
/// in `parts` parts of 2^`shift` words: straight where there is one part, else in the part
/// the index's high bits name.
pub(super) fn by_part(
    var: &str,
    parts: u32,
    shift: u32,
    step: impl Fn(&str, &str) -> String,
) -> String {
    if parts <= 1 {
        return format!("    {}\n", step(var, "i"));
    }
    let mask = (1u64 << shift) - 1;
    let mut s = format!("    let j = i & {mask}u;\n    switch i >> {shift}u {{\n");
    for k in 0..parts {
        let v = part_var(var, k);
        let case = match k == parts - 1 {
            true => "default".to_string(),
            false => format!("case {k}u"),
        };
        let _ = writeln!(s, "        {case}: {{ {} }}", step(&v, "j"));
    }
    s + "    }\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_split_reader_parses_and_picks_parts_by_the_high_bits() {
        let parts = BufferParts {
            nodes: 3,
            tris: 1,
            shades: 2,
            texels: 2,
            accum: 3,
            shift: 8,
        };
        let wgsl = parts.bvh_wgsl() + &parts.render_wgsl();
        assert!(wgsl.contains("switch i >> 8u"), "{wgsl}");
        assert!(wgsl.contains("let j = i & 255u;"), "{wgsl}");
        assert!(
            wgsl.contains("default: { return node_words_2[j]; }"),
            "{wgsl}"
        );
        assert!(wgsl.contains("return tri_words[i];"), "{wgsl}");
        assert!(wgsl.contains("fn texel(i: u32) -> vec4<f32>"), "{wgsl}");
        assert!(wgsl.contains("default: { accum_2[j] = value; }"), "{wgsl}");
        assert!(wgsl.contains("var<storage, read_write> accum_1"), "{wgsl}");
        let decls = "@group(0) @binding(0) var<storage, read> node_words: array<vec4<u32>>;\n\
                     @group(0) @binding(1) var<storage, read> tri_words: array<vec4<u32>>;\n\
                     @group(0) @binding(2) var<storage, read> shade_words: array<vec4<u32>>;\n\
                     @group(0) @binding(3) var<storage, read> texels: array<vec4<f32>>;\n\
                     @group(0) @binding(4) var<storage, read_write> accum: array<vec4<f32>>;\n";
        let module = naga::front::wgsl::parse_str(&format!("{decls}{wgsl}"));
        assert!(module.is_ok(), "{wgsl}");
    }
}
