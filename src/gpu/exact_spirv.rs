//! The SPIR-V lancer hands a Vulkan driver: naga's translation of a kernel, specialised by its
//! override constants, in which the driver may not round differently from the CPU.
//!
//! WGSL cannot forbid a driver to fuse `a * b + c` into one fused multiply-add (naga emits no
//! `NoContraction`), and Vulkan lets a driver divide and take square roots to within a few
//! ulps. A hardware driver does both (on an NVIDIA H200, 0.4 % of the bunny's closest hits
//! came back a few ulps off the CPU's), so the kernels could not be the CPU's program bit for
//! bit. Here every floating-point add, subtract, multiply, divide and dot product is
//! decorated `NoContraction` (the driver must round each alone, as IEEE 754 does), and where
//! the device has 64-bit floats every f32 division and square root is taken in f64 and
//! rounded once to f32. A quotient of normal f32s lies at least about 2⁻⁴⁹ (relative) from
//! any point halfway between two f32s, a square root about 2⁻⁵¹: an f64 result within a few
//! f64 ulps (2⁻⁵³) rounds to the correctly rounded f32, the CPU's. Vulkan itself promises
//! f64 only "at least the precision of single precision" and leaves denormals and the
//! rounding mode to the driver, so this is a practice checked on each driver, not a
//! guarantee: lavapipe (tests/exact_arithmetic.rs) and an NVIDIA H200 (every layout's
//! answers identical to the CPU twin's, 2026-12-04).

use crate::error::{Error, Result};

/// A kernel's WGSL parsed and validated once; [`ExactModule::spirv`] specialises it.
pub struct ExactModule {
    module: naga::Module,
    info: naga::valid::ModuleInfo,
}

// SPIR-V opcodes and operands used here (SPIR-V 1.6 specification, §3).
const OP_EXT_INST_IMPORT: u32 = 11;
const OP_EXT_INST: u32 = 12;
const OP_CAPABILITY: u32 = 17;
const OP_TYPE_FLOAT: u32 = 22;
const OP_TYPE_VECTOR: u32 = 23;
const OP_FUNCTION: u32 = 54;
const OP_DECORATE: u32 = 71;
const OP_FCONVERT: u32 = 115;
const OP_FDIV: u32 = 136;
const CAPABILITY_FLOAT64: u32 = 10;
const DECORATION_NO_CONTRACTION: u32 = 42;
const GLSL_SQRT: u32 = 31;
/// Float arithmetic a driver could fuse with its neighbour: FAdd, FSub, FMul, FDiv, FRem,
/// FMod, VectorTimesScalar, MatrixTimesScalar, VectorTimesMatrix, MatrixTimesVector,
/// MatrixTimesMatrix, Dot.
const CONTRACTIBLE: [u32; 12] = [129, 131, 133, 136, 140, 141, 142, 143, 144, 145, 146, 148];
/// Opcodes of the sections before the types (capabilities, extensions, imports, memory
/// model, entry points, execution modes, debug names and annotations).
const PREAMBLE: [u32; 22] = [
    2, 3, 4, 5, 6, 7, 10, 11, 14, 15, 16, 17, 71, 72, 73, 74, 75, 330, 331, 332, 5632, 5633,
];

impl ExactModule {
    /// Parses and validates `source` with the capabilities wgpu grants a device of
    /// `features` (wgpu checks nothing in a module it is handed as SPIR-V, so a kernel the
    /// device cannot run is refused here, by name, not left to the driver). The downlevel
    /// flags, which only grant capabilities no compute kernel uses (cube arrays,
    /// multisampled shading, f16 in f32), are taken as none.
    pub fn new(label: &str, source: &str, features: wgpu::Features) -> Result<ExactModule> {
        let module = naga::front::wgsl::parse_str(source)
            .map_err(|e| Error::Gpu(format!("the {label} kernel: {}", e.emit_to_string(source))))?;
        let info = wgpu_naga_bridge::create_validator(
            features,
            wgpu::DownlevelFlags::empty(),
            naga::valid::ValidationFlags::all(),
        )
        .validate(&module)
        .map_err(|e| Error::Gpu(format!("the {label} kernel: {}", e.emit_to_string(source))))?;
        Ok(ExactModule { module, info })
    }

    /// SPIR-V (version 1.3) of compute entry point `entry` with `constants` substituted for
    /// its overrides, every float operation `NoContraction`, and — with `f64` — f32 division
    /// and square root through f64. `trusted` drops naga's bounds checks and loop bounding
    /// (see [`Kernel::new`](super::plumbing::Kernel::new)). `bindings` are group 0's binding
    /// numbers in its layout: wgpu's Vulkan backend numbers a set's descriptors 0, 1, 2, …
    /// in the order of their WGSL bindings, and the SPIR-V must name them so.
    pub fn spirv(
        &self,
        entry: &str,
        constants: &[(&str, f64)],
        bindings: &[u32],
        trusted: bool,
        f64: bool,
    ) -> Result<Vec<u32>> {
        let mut values = naga::back::PipelineConstants::default();
        for (name, value) in constants {
            values.insert((*name).to_string(), *value);
        }
        let stage = naga::ShaderStage::Compute;
        let (module, info) = naga::back::pipeline_constants::process_overrides(
            &self.module,
            &self.info,
            Some((stage, entry)),
            &values,
        )
        .map_err(|e| Error::Gpu(format!("specialising {entry}: {e}")))?;
        let check = match trusted {
            true => naga::proc::BoundsCheckPolicy::Unchecked,
            false => naga::proc::BoundsCheckPolicy::Restrict,
        };
        let mut sorted = bindings.to_vec();
        sorted.sort_unstable();
        let binding_map = sorted
            .iter()
            .enumerate()
            .map(|(i, &binding)| {
                let at = naga::ResourceBinding { group: 0, binding };
                let info = naga::back::spv::BindingInfo {
                    descriptor_set: 0,
                    binding: i as u32,
                    binding_array_size: None,
                };
                (at, info)
            })
            .collect();
        let options = naga::back::spv::Options {
            binding_map,
            fake_missing_bindings: false,
            lang_version: (1, 3),
            flags: naga::back::spv::WriterFlags::empty(),
            bounds_check_policies: naga::proc::BoundsCheckPolicies {
                index: check,
                buffer: check,
                image_load: check,
                binding_array: naga::proc::BoundsCheckPolicy::Unchecked,
            },
            force_loop_bounding: !trusted,
            ..Default::default()
        };
        let pipeline = naga::back::spv::PipelineOptions {
            shader_stage: stage,
            entry_point: entry.to_string(),
        };
        let words = naga::back::spv::write_vec(&module, &info, &options, Some(&pipeline))
            .map_err(|e| Error::Gpu(format!("translating {entry} to SPIR-V: {e}")))?;
        exact(&words, f64).map_err(|e| Error::Gpu(format!("{entry}: {e}")))
    }
}

/// One instruction's words (its first word holds its length and opcode).
fn opcode(first: u32) -> u32 {
    first & 0xffff
}

fn instruction(op: u32, operands: &[u32]) -> Vec<u32> {
    let mut words = vec![((operands.len() as u32 + 1) << 16) | op];
    words.extend_from_slice(operands);
    words
}

/// The fewest words an instruction this pass reads may have (its operands included).
fn min_len(op: u32) -> usize {
    match op {
        OP_CAPABILITY => 2,
        OP_TYPE_FLOAT | OP_EXT_INST_IMPORT => 3,
        OP_TYPE_VECTOR => 4,
        OP_EXT_INST => 5,
        op if CONTRACTIBLE.contains(&op) => 4,
        _ => 1,
    }
}

/// `words` (a SPIR-V module) with every contractible float operation decorated
/// `NoContraction` and, with `f64`, f32 division and square root taken through f64.
pub(crate) fn exact(words: &[u32], f64: bool) -> std::result::Result<Vec<u32>, String> {
    if words.len() < 5 || words[0] != 0x0723_0203 {
        return Err("not a SPIR-V module".into());
    }
    let mut bound = words[3];
    let mut fresh = || {
        bound += 1;
        bound - 1
    };
    // Split into instructions.
    let mut code: Vec<Vec<u32>> = Vec::new();
    let mut at = 5;
    while at < words.len() {
        let len = (words[at] >> 16) as usize;
        if len == 0 || at + len > words.len() || len < min_len(opcode(words[at])) {
            return Err(format!("a malformed instruction at word {at}"));
        }
        code.push(words[at..at + len].to_vec());
        at += len;
    }
    // The f32 and f64 types (scalar, and vectors with their widths) and the GLSL.std.450
    // import. A type may be declared once: the module's own f64 types are reused.
    let mut f32_id = None;
    let mut f32_vectors: Vec<(u32, u32)> = Vec::new(); // (id, components)
    let mut own_f64 = None;
    let mut own_f64_vectors: Vec<(u32, u32)> = Vec::new();
    let mut glsl = None;
    for ins in &code {
        match opcode(ins[0]) {
            OP_TYPE_FLOAT if ins[2] == 32 => f32_id = Some(ins[1]),
            OP_TYPE_FLOAT if ins[2] == 64 => own_f64 = Some(ins[1]),
            OP_TYPE_VECTOR if Some(ins[2]) == f32_id => f32_vectors.push((ins[1], ins[3])),
            OP_TYPE_VECTOR if Some(ins[2]) == own_f64 => own_f64_vectors.push((ins[1], ins[3])),
            OP_EXT_INST_IMPORT => {
                let name: Vec<u8> = ins[2..].iter().flat_map(|w| w.to_le_bytes()).collect();
                if name.starts_with(b"GLSL.std.450\0") {
                    glsl = Some(ins[1]);
                }
            }
            _ => {}
        }
    }
    let float_type = |t: u32| Some(t) == f32_id || f32_vectors.iter().any(|v| v.0 == t);
    // f64 twins of the f32 types (f32 id, f64 id, width, made here), declared only if a
    // division or square root needs them.
    let f64_id = own_f64.unwrap_or_else(&mut fresh);
    let f64_vectors: Vec<(u32, u32, u32, bool)> = f32_vectors
        .iter()
        .map(|&(id, n)| match own_f64_vectors.iter().find(|v| v.1 == n) {
            Some(&(own, _)) => (id, own, n, false),
            None => (id, fresh(), n, true),
        })
        .collect();
    let wide = |t: u32| -> u32 {
        f64_vectors
            .iter()
            .find(|v| v.0 == t)
            .map_or(f64_id, |v| v.1)
    };
    let mut widened = false;
    let mut decorations = Vec::new();
    let mut out: Vec<Vec<u32>> = Vec::with_capacity(code.len());
    for ins in code {
        let op = opcode(ins[0]);
        let float_result = ins.len() > 2 && float_type(ins[1]);
        let sqrt =
            op == OP_EXT_INST && ins.len() == 6 && Some(ins[3]) == glsl && ins[4] == GLSL_SQRT;
        if f64 && float_result && (op == OP_FDIV || sqrt) {
            // result = FConvert(op(FConvert(a) [, FConvert(b)])) in f64.
            let (ty, result) = (ins[1], ins[2]);
            let ty64 = wide(ty);
            let args: Vec<u32> = if sqrt {
                vec![ins[5]]
            } else {
                ins[3..5].to_vec()
            };
            let mut args64 = Vec::new();
            for a in args {
                let id = fresh();
                out.push(instruction(OP_FCONVERT, &[ty64, id, a]));
                args64.push(id);
            }
            let q = fresh();
            if sqrt {
                out.push(instruction(
                    OP_EXT_INST,
                    &[ty64, q, ins[3], GLSL_SQRT, args64[0]],
                ));
            } else {
                out.push(instruction(OP_FDIV, &[ty64, q, args64[0], args64[1]]));
                // Exact in f64 too: no rewriting it back into an f32 division.
                decorations.push(instruction(OP_DECORATE, &[q, DECORATION_NO_CONTRACTION]));
            }
            out.push(instruction(OP_FCONVERT, &[ty, result, q]));
            widened = true;
            continue;
        }
        if CONTRACTIBLE.contains(&op) && float_result {
            decorations.push(instruction(
                OP_DECORATE,
                &[ins[2], DECORATION_NO_CONTRACTION],
            ));
        }
        out.push(ins);
    }
    if widened {
        // The f64 types made here, right after the f64 scalar type (the module's own, or one
        // made here right after the f32 scalar type): each after its component.
        let after = own_f64.or(f32_id);
        let Some(pos) = out
            .iter()
            .position(|i| opcode(i[0]) == OP_TYPE_FLOAT && Some(i[1]) == after)
        else {
            return Err("an f32 division without an f32 type".into());
        };
        let mut types = Vec::new();
        if own_f64.is_none() {
            types.push(instruction(OP_TYPE_FLOAT, &[f64_id, 64]));
        }
        types.extend(
            f64_vectors
                .iter()
                .filter(|v| v.3)
                .map(|&(_, id, n, _)| instruction(OP_TYPE_VECTOR, &[id, f64_id, n])),
        );
        let _ = out.splice(pos + 1..pos + 1, types);
        let has = out
            .iter()
            .any(|i| opcode(i[0]) == OP_CAPABILITY && i[1] == CAPABILITY_FLOAT64);
        if !has {
            out.insert(0, instruction(OP_CAPABILITY, &[CAPABILITY_FLOAT64]));
        }
    }
    // The decorations go at the end of the annotations, before the first type.
    let first_type = out
        .iter()
        .position(|i| !PREAMBLE.contains(&opcode(i[0])))
        .unwrap_or(out.len());
    if out
        .iter()
        .take(first_type)
        .any(|i| opcode(i[0]) == OP_FUNCTION)
    {
        return Err("a function before the types".into());
    }
    let _ = out.splice(first_type..first_type, decorations);
    let mut result = words[..5].to_vec();
    result[3] = bound;
    for ins in out {
        result.extend(ins);
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SOURCE: &str = "
        @group(0) @binding(3) var<storage, read> inputs: array<vec4<f32>>;
        @group(0) @binding(7) var<storage, read_write> outputs: array<vec4<f32>>;
        override SCALE: f32 = 1.0;
        @compute @workgroup_size(64)
        fn main(@builtin(global_invocation_id) id: vec3<u32>) {
            let x = inputs[id.x];
            let v = x.xyz * x.w;
            outputs[id.x] = vec4<f32>(x.x * x.y + x.z, x.x / x.y, sqrt(abs(x.z)), v.x / SCALE);
        }";

    fn ops(words: &[u32]) -> Vec<Vec<u32>> {
        let mut out = Vec::new();
        let mut at = 5;
        while at < words.len() {
            let len = (words[at] >> 16) as usize;
            out.push(words[at..at + len].to_vec());
            at += len;
        }
        out
    }

    fn count(words: &[u32], op: u32) -> usize {
        ops(words).iter().filter(|i| opcode(i[0]) == op).count()
    }

    #[test]
    fn every_float_operation_is_marked_and_divisions_go_through_f64() {
        let m = ExactModule::new("test", SOURCE, wgpu::Features::empty()).unwrap();
        let plain = m
            .spirv("main", &[("SCALE", 2.0)], &[3, 7], false, false)
            .unwrap();
        let wide = m
            .spirv("main", &[("SCALE", 2.0)], &[3, 7], false, true)
            .unwrap();
        // FMul, FAdd, two FDiv and the vector product (VectorTimesScalar): five, each
        // decorated once.
        let no_contraction = |w: &[u32]| {
            ops(w)
                .iter()
                .filter(|i| opcode(i[0]) == OP_DECORATE && i[2] == DECORATION_NO_CONTRACTION)
                .count()
        };
        assert_eq!(no_contraction(&plain), 5);
        assert_eq!(count(&plain, OP_FDIV), 2);
        // With f64: the two divisions and the square root each become f64 work between
        // conversions (two in and one out for a division, one in and one out for the root);
        // the f64 divisions are decorated instead of the f32 ones.
        assert_eq!(no_contraction(&wide), 5);
        assert_eq!(count(&wide, OP_FDIV), 2);
        assert_eq!(count(&wide, OP_FCONVERT), 2 * 3 + 2);
        let caps: Vec<u32> = ops(&wide)
            .iter()
            .filter(|i| opcode(i[0]) == OP_CAPABILITY)
            .map(|i| i[1])
            .collect();
        assert!(caps.contains(&CAPABILITY_FLOAT64), "{caps:?}");
        let f64_types = ops(&wide)
            .iter()
            .filter(|i| opcode(i[0]) == OP_TYPE_FLOAT && i[2] == 64)
            .count();
        assert_eq!(f64_types, 1);
        // The ids made here lie below the header's bound, and none is made twice.
        let bound = wide[3];
        let made: Vec<u32> = ops(&wide)
            .iter()
            .filter_map(|i| match opcode(i[0]) {
                OP_TYPE_FLOAT | OP_TYPE_VECTOR => Some(i[1]),
                OP_FCONVERT | OP_FDIV | OP_EXT_INST => Some(i[2]),
                _ => None,
            })
            .collect();
        assert!(made.iter().all(|&id| id < bound), "{made:?} {bound}");
        let mut unique = made.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), made.len());
        // The bindings are renumbered as wgpu's Vulkan backend numbers them: 3 → 0, 7 → 1.
        let bindings: Vec<u32> = ops(&wide)
            .iter()
            .filter(|i| opcode(i[0]) == OP_DECORATE && i[2] == 33)
            .map(|i| i[3])
            .collect();
        assert_eq!(bindings, [0, 1]);
    }

    #[test]
    fn a_module_that_is_not_spirv_is_refused() {
        assert!(exact(&[1, 2, 3], true).is_err());
        assert!(exact(&[0x0723_0203, 0, 0, 1, 0, 0xffff_0011], true).is_err());
        // An OpTypeFloat of one word: too short to read, refused (not a panic).
        assert!(exact(&[0x0723_0203, 0, 0, 1, 0, 0x0001_0016], true).is_err());
    }

    /// A module with f64 types of its own keeps them, declared once, and its f32
    /// divisions still go through f64.
    #[test]
    fn a_modules_own_f64_types_are_reused() {
        let source = "
            @group(0) @binding(0) var<storage, read_write> data: array<vec2<f32>>;
            @compute @workgroup_size(1)
            fn main() {
                let x = data[0];
                let wide = f64(x.x) * 2.0lf;
                data[0] = vec2<f32>(x.x / x.y, f32(wide));
            }";
        let m = ExactModule::new("test", source, wgpu::Features::SHADER_F64).unwrap();
        let words = m.spirv("main", &[], &[0], false, true).unwrap();
        let f64_types = ops(&words)
            .iter()
            .filter(|i| opcode(i[0]) == OP_TYPE_FLOAT && i[2] == 64)
            .count();
        assert_eq!(f64_types, 1);
        assert_eq!(count(&words, OP_FDIV), 1);
        // The division: two in, one out; the module's own: f64(x.x) and f32(wide).
        assert_eq!(count(&words, OP_FCONVERT), 3 + 2);
    }

    /// A kernel the device's features do not allow (f64, subgroup operations) is refused by
    /// name, as wgpu refuses its WGSL; with the feature it passes.
    #[test]
    fn a_kernel_beyond_the_devices_features_is_refused() {
        let f64_source = "
            @group(0) @binding(0) var<storage, read_write> data: array<f32>;
            @compute @workgroup_size(1)
            fn main() { data[0] = f32(f64(data[0]) * 2.0lf); }";
        let subgroup_source = "
            @group(0) @binding(0) var<storage, read_write> data: array<f32>;
            @compute @workgroup_size(32)
            fn main(@builtin(local_invocation_index) i: u32) {
                data[i] = subgroupAdd(data[i]);
            }";
        for (source, feature) in [
            (f64_source, wgpu::Features::SHADER_F64),
            (subgroup_source, wgpu::Features::SUBGROUP),
        ] {
            let refused = ExactModule::new("wide", source, wgpu::Features::empty())
                .err()
                .expect("validated without the feature");
            assert!(refused.to_string().contains("the wide kernel"), "{refused}");
            assert!(
                ExactModule::new("wide", source, feature).is_ok(),
                "{feature:?}"
            );
        }
    }

    /// WGSL's dot() and cross() — like fma(), length(), normalize() and the rest — are the
    /// driver's own arithmetic (fused on a hardware GPU, whatever NoContraction says): no
    /// kernel may call them (common.wgsl's dot3 and cross3 are the CPU's operations).
    #[test]
    fn no_kernel_calls_the_drivers_own_arithmetic() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut files = Vec::new();
        let mut dirs = vec![root.join("src"), root.join("shaders")];
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    dirs.push(p);
                } else if p.extension().is_some_and(|x| x == "wgsl") {
                    files.push(p);
                }
            }
        }
        assert!(files.len() > 20, "{files:?}");
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for (n, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                let calls = |name: &str| {
                    code.match_indices(name).any(|(i, _)| {
                        let before = code[..i].chars().last();
                        !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                    })
                };
                const DRIVERS: [&str; 11] = [
                    "dot(",
                    "cross(",
                    "fma(",
                    "length(",
                    "normalize(",
                    "distance(",
                    "mix(",
                    "inverseSqrt(",
                    "smoothstep(",
                    "reflect(",
                    "refract(",
                ];
                assert!(
                    !DRIVERS.iter().any(|f| calls(f)),
                    "{}:{}: {line}",
                    f.display(),
                    n + 1
                );
            }
        }
    }
}
