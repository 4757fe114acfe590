//! Every WGSL module parses and validates with naga (no GPU needed) for every layout, every
//! GPU-visible struct's field offsets and size equal those of its #[repr(C)] Rust twin, and
//! every constant shared with Rust reads back in WGSL as the Rust value.

use std::mem::{offset_of, size_of};

use glam::Vec3;
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::accel::{GpuForm, LeafTri};
use lancer::geometry::{Hit, Ray, Triangle};
use lancer::gpu::shaders::{self, Shared};
use lancer::gpu::BufferParts;
use lancer::mesh::Mesh;
use lancer::render::kernel::{all_kernels, render_constants};

fn module(src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)))
}

/// Every layout, flattened over a small mesh.
fn layouts() -> Vec<Box<dyn GpuForm>> {
    let mesh = Mesh::from_triangles(vec![
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
        Triangle::new(Vec3::Z, Vec3::X, Vec3::Y),
    ]);
    let bvh = build(&mesh, &BuildOptions::default());
    LayoutKind::ALL
        .iter()
        .map(|&k| flatten(k, &bvh, &mesh))
        .collect()
}

fn check(src: &str, name: &str, rust_size: usize, rust: &[(&str, usize)]) {
    shaders::check_struct(src, name, rust_size, rust).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn all_shaders_validate() {
    for layout in layouts() {
        // Each array in one binding, and bound in parts (the readers generated for them).
        let split = BufferParts {
            nodes: 3,
            tris: 2,
            shades: 2,
            texels: 4,
            accum: 2,
            shift: 8,
        };
        let kernels: Vec<_> = [BufferParts::WHOLE, split]
            .iter()
            .flat_map(|parts| all_kernels(layout.as_ref(), parts))
            .collect();
        for (name, src) in kernels {
            validated(&src, &format!("{} {name}", layout.name()));
        }
    }
}

/// The module of `src`, parsed and validated (panics naming `what` otherwise).
fn validated(src: &str, what: &str) -> naga::Module {
    let m = module(src);
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&m)
    .unwrap_or_else(|e| panic!("{what}: {}", e.emit_to_string(src)));
    m
}

#[test]
fn the_gpu_lbvh_kernels_validate() {
    validated(&lancer::gpu::lbvh_source(), "lbvh");
}

#[test]
fn gpu_structs_match_rust() {
    let layout = &layouts()[0];
    let src = shaders::trace_source(layout.as_ref(), &BufferParts::WHOLE);
    check(
        &src,
        "Tri",
        size_of::<LeafTri>(),
        &[
            ("v0", offset_of!(LeafTri, v0)),
            ("prim", offset_of!(LeafTri, prim)),
            ("v1", offset_of!(LeafTri, v1)),
            ("pad1", offset_of!(LeafTri, pad1)),
            ("v2", offset_of!(LeafTri, v2)),
            ("pad2", offset_of!(LeafTri, pad2)),
        ],
    );
    check(
        &src,
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
        &src,
        "Hit",
        size_of::<Hit>(),
        &[
            ("t", offset_of!(Hit, t)),
            ("prim", offset_of!(Hit, prim)),
            ("u", offset_of!(Hit, u)),
            ("v", offset_of!(Hit, v)),
        ],
    );
    use lancer::gpu::TraceParams;
    check(
        &src,
        "Params",
        size_of::<TraceParams>(),
        &[
            ("offset", offset_of!(TraceParams, offset)),
            ("count", offset_of!(TraceParams, count)),
        ],
    );
}

#[test]
fn render_structs_match_rust() {
    use lancer::render::{GpuLight, GpuMaterial, GpuShade, RenderParams};
    let layout = &layouts()[0];
    let src = lancer::render::kernel::render_source(layout.as_ref(), &BufferParts::WHOLE);
    let m = &src;
    macro_rules! fields {
        ($t:ty; $($w:literal => $f:ident),*) => {
            &[$(($w, offset_of!($t, $f))),*]
        };
    }
    check(
        m,
        "Shade",
        size_of::<GpuShade>(),
        fields!(GpuShade;
        "v0" => v0, "material" => material, "v1" => v1, "n0" => n0, "v2" => v2,
        "n1" => n1, "uv0" => uv0, "uv1" => uv1, "uv2" => uv2, "n2" => n2, "tangent" => tangent),
    );
    check(
        m,
        "Material",
        size_of::<GpuMaterial>(),
        fields!(GpuMaterial;
        "albedo" => albedo, "kind" => kind, "emission" => emission, "ior" => ior,
        "tex_offset" => tex_offset, "tex_width" => tex_width, "tex_height" => tex_height,
        "flags" => flags, "metallic" => metallic, "roughness" => roughness,
        "mr_offset" => mr_offset, "emission_offset" => emission_offset, "mr_width" => mr_width,
        "mr_height" => mr_height, "emission_width" => emission_width,
        "emission_height" => emission_height, "normal_offset" => normal_offset,
        "normal_width" => normal_width, "normal_height" => normal_height,
        "normal_scale" => normal_scale, "alpha" => alpha, "alpha_cutoff" => alpha_cutoff,
        "occlusion_offset" => occlusion_offset, "occlusion_width" => occlusion_width,
        "occlusion_height" => occlusion_height, "occlusion_strength" => occlusion_strength,
        "uv_maps" => uv_maps, "pad2" => _pad2),
    );
    check(
        m,
        "Light",
        size_of::<GpuLight>(),
        fields!(GpuLight;
        "v" => v, "kind" => kind, "power" => power, "offset" => offset,
        "axis" => axis, "scale" => scale),
    );
    check(
        m,
        "Params",
        size_of::<RenderParams>(),
        fields!(RenderParams;
        "eye" => eye, "width" => width, "fwd" => fwd, "height" => height, "right" => right,
        "inv_w2" => inv_w2, "up" => up, "inv_h2" => inv_h2, "env_radiance" => env_radiance,
        "seed" => seed, "sample" => sample, "offset" => offset, "count" => count,
        "max_bounces" => max_bounces, "integrator" => integrator, "n_lights" => n_lights,
        "n_emitters" => n_emitters, "emit_total" => emit_total, "ao_distance" => ao_distance,
        "fixed_offset" => fixed_offset, "crop_x0" => crop_x0, "crop_y0" => crop_y0,
        "crop_width" => crop_width, "aov_base" => aov_base, "placement_base" => placement_base,
        "n_placements" => n_placements, "env_x" => env_x, "env_width" => env_width,
        "env_y" => env_y, "env_height" => env_height, "env_z" => env_z,
        "env_texels" => env_texels, "env_cdf" => env_cdf, "has_env" => has_env,
        "tangent_base" => tangent_base, "pad2" => _pad2),
    );
    assert_eq!(size_of::<RenderParams>(), 208);
}

#[test]
fn shared_constants_read_back_as_the_rust_values() {
    let layout = &layouts()[0];
    for (kernel, src) in all_kernels(layout.as_ref(), &BufferParts::WHOLE) {
        let m = module(&src);
        // The render kernels also carry the renderer's own constants.
        let mut constants = shaders::shared_constants();
        if kernel.starts_with("render") {
            constants.extend(render_constants());
        }
        for (name, value) in constants {
            let (_, c) = (m.constants.iter())
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("{name} not in the {kernel} kernel"));
            let wgsl = &m.global_expressions[c.init];
            match (value, wgsl) {
                (Shared::U32(x), naga::Expression::Literal(naga::Literal::U32(w))) => {
                    assert_eq!(x, *w, "{name}")
                }
                (Shared::F32(x), naga::Expression::Literal(naga::Literal::F32(w))) => {
                    assert_eq!(x.to_bits(), w.to_bits(), "{name}: {x} vs {w}")
                }
                (v, e) => panic!("{name}: Rust {v:?}, WGSL {e:?}"),
            }
        }
    }
}

#[test]
fn bindings_are_the_rust_numbers() {
    use lancer::gpu::bindings;
    let expected = [
        ("node_words", bindings::NODE_WORDS),
        ("tri_words", bindings::TRI_WORDS),
        ("node_texels", bindings::NODE_TEXELS),
        ("tri_texels", bindings::TRI_TEXELS),
        ("rays", bindings::TRACE_RAYS),
        ("hits", bindings::TRACE_HITS),
        ("stats", bindings::TRACE_STATS),
        ("shade_words", bindings::RENDER_SHADES),
        ("shade_texels", bindings::RENDER_SHADE_TEXELS),
        ("accum", bindings::RENDER_ACCUM),
    ];
    let layout = &layouts()[0];
    let mut seen = 0;
    let kernels = all_kernels(layout.as_ref(), &BufferParts::WHOLE);
    let of_kind = |k: &str| kernels.iter().filter(|(n, _)| n.starts_with(k)).count();
    // dfs-sign has a subgroup form of both kernels.
    let (traces, renders) = (of_kind("trace"), of_kind("render"));
    assert_eq!((traces, renders), (2, 2));
    for (_, src) in &kernels {
        let m = module(src);
        for (_, g) in m.global_variables.iter() {
            let Some(b) = &g.binding else { continue };
            if let Some((_, want)) = expected.iter().find(|(n, _)| g.name.as_deref() == Some(n)) {
                assert_eq!(b.binding, *want, "{:?}", g.name);
                seen += 1;
            }
        }
    }
    // The four BVH bindings in every kernel, plus 3 in each trace and 3 in each render kernel.
    assert_eq!(seen, traces * (4 + 3) + renders * (4 + 3));
    // The driver's kernel: its acceleration structure and the trace bindings it shares.
    let src = shaders::driver_trace_source();
    let m = validated(&src, "driver trace");
    let driver: Vec<(String, u32)> = (m.global_variables.iter())
        .filter_map(|(_, g)| Some((g.name.clone()?, g.binding.as_ref()?.binding)))
        .collect();
    for want in [
        ("scene", bindings::DRIVER_SCENE),
        ("tri_words", bindings::TRI_WORDS),
        ("rays", bindings::TRACE_RAYS),
        ("hits", bindings::TRACE_HITS),
    ] {
        assert!(
            driver.contains(&(want.0.to_string(), want.1)),
            "{want:?} in {driver:?}"
        );
    }
}
