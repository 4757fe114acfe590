//! Every WGSL module parses and validates with naga (no GPU needed), and every GPU-visible
//! struct's field offsets and size equal those of its #[repr(C)] Rust twin.

use std::mem::{offset_of, size_of};

use lancer::accel::bvh::{GpuNode, GpuTri};
use lancer::geometry::{Hit, Ray};
use lancer::gpu::shaders;

fn module(src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)))
}

#[test]
fn all_shaders_validate() {
    for (name, src) in shaders::all() {
        let m = module(&src);
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&m)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
    }
}

/// (member name, offset) list and size of a WGSL struct.
fn wgsl_layout(m: &naga::Module, name: &str) -> (Vec<(String, u32)>, u32) {
    let ty = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("struct {name} not in WGSL"))
        .1;
    match &ty.inner {
        naga::TypeInner::Struct { members, span } => (
            members
                .iter()
                .map(|mb| (mb.name.clone().unwrap(), mb.offset))
                .collect(),
            *span,
        ),
        _ => panic!("{name} is not a struct"),
    }
}

fn check(m: &naga::Module, name: &str, rust_size: usize, rust: &[(&str, usize)]) {
    let (members, size) = wgsl_layout(m, name);
    assert_eq!(
        size as usize, rust_size,
        "{name}: WGSL size {size}, Rust {rust_size}"
    );
    assert_eq!(members.len(), rust.len(), "{name}: member count");
    for ((wn, wo), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!(wn, rn, "{name}: member order");
        assert_eq!(
            *wo as usize, *ro,
            "{name}.{wn}: WGSL offset {wo}, Rust {ro}"
        );
    }
}

#[test]
fn gpu_structs_match_rust() {
    let m = module(&shaders::traverse_source());
    check(
        &m,
        "Node",
        size_of::<GpuNode>(),
        &[
            ("lo", offset_of!(GpuNode, lo)),
            ("a", offset_of!(GpuNode, a)),
            ("hi", offset_of!(GpuNode, hi)),
            ("b", offset_of!(GpuNode, b)),
        ],
    );
    check(
        &m,
        "Tri",
        size_of::<GpuTri>(),
        &[
            ("v0", offset_of!(GpuTri, v0)),
            ("prim", offset_of!(GpuTri, prim)),
            ("v1", offset_of!(GpuTri, v1)),
            ("pad1", offset_of!(GpuTri, _pad1)),
            ("v2", offset_of!(GpuTri, v2)),
            ("pad2", offset_of!(GpuTri, _pad2)),
        ],
    );
    check(
        &m,
        "Ray",
        size_of::<Ray>(),
        &[
            ("origin", offset_of!(Ray, origin)),
            ("tmin", offset_of!(Ray, tmin)),
            ("dir", offset_of!(Ray, dir)),
            ("tmax", offset_of!(Ray, tmax)),
        ],
    );
    check(
        &m,
        "Hit",
        size_of::<Hit>(),
        &[
            ("t", offset_of!(Hit, t)),
            ("prim", offset_of!(Hit, prim)),
            ("u", offset_of!(Hit, u)),
            ("v", offset_of!(Hit, v)),
        ],
    );
    use lancer::gpu::Params;
    check(
        &m,
        "Params",
        size_of::<Params>(),
        &[
            ("offset", offset_of!(Params, offset)),
            ("count", offset_of!(Params, count)),
        ],
    );
    assert_eq!(size_of::<GpuNode>(), 32);
}

#[test]
fn render_structs_match_rust() {
    use lancer::render::{GpuLight, GpuMaterial, GpuShade, RenderParams};
    let m = module(&shaders::render_source());
    macro_rules! fields {
        ($t:ty; $($w:literal => $f:ident),*) => {
            &[$(($w, offset_of!($t, $f))),*]
        };
    }
    check(
        &m,
        "Shade",
        size_of::<GpuShade>(),
        fields!(GpuShade;
        "v0" => v0, "material" => material, "v1" => v1, "pad1" => _pad1, "v2" => v2,
        "pad2" => _pad2, "uv0" => uv0, "uv1" => uv1, "uv2" => uv2, "pad3" => _pad3),
    );
    check(
        &m,
        "Material",
        size_of::<GpuMaterial>(),
        fields!(GpuMaterial;
        "albedo" => albedo, "kind" => kind, "emission" => emission, "ior" => ior,
        "tex_offset" => tex_offset, "tex_width" => tex_width, "tex_height" => tex_height,
        "has_tex" => has_tex),
    );
    check(
        &m,
        "Light",
        size_of::<GpuLight>(),
        fields!(GpuLight;
        "v" => v, "kind" => kind, "power" => power, "pad" => _pad),
    );
    check(
        &m,
        "Params",
        size_of::<RenderParams>(),
        fields!(RenderParams;
        "eye" => eye, "width" => width, "fwd" => fwd, "height" => height, "right" => right,
        "inv_w2" => inv_w2, "up" => up, "inv_h2" => inv_h2, "background" => background,
        "seed" => seed, "sample" => sample, "offset" => offset, "count" => count,
        "max_bounces" => max_bounces, "integrator" => integrator, "n_lights" => n_lights,
        "n_emitters" => n_emitters, "emit_total" => emit_total, "ao_distance" => ao_distance,
        "pad0" => _pad0, "pad1" => _pad1, "pad2" => _pad2),
    );
    assert_eq!(size_of::<RenderParams>(), 128);
}

#[test]
fn texel_row_matches_rust() {
    let m = module(&shaders::traverse_source());
    let (_, c) = (m.constants.iter())
        .find(|(_, c)| c.name.as_deref() == Some("TEXEL_ROW"))
        .expect("TEXEL_ROW not in bvh.wgsl");
    match m.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => {
            assert_eq!(
                v,
                lancer::gpu::TEXEL_ROW,
                "WGSL TEXEL_ROW vs gpu::TEXEL_ROW"
            )
        }
        ref e => panic!("TEXEL_ROW is not a u32 literal: {e:?}"),
    }
}
