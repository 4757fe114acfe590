// The renderer: one sample of one pixel per invocation, added to an accumulation buffer.
// render::integrator::CpuRenderer::sample operation for operation; the effects a scene
// does not call for are override constants set false, so their code is compiled out.

override SHADOWS: bool = true;
override SOFT_SHADOWS: bool = true;
override MIRROR: bool = true;
override REFRACTION: bool = true;
override INDIRECT: bool = true;
override TEXTURES: bool = true;
override AO: bool = true;
override SHADING_NORMALS: bool = true;
override ENVIRONMENT: bool = true;
override SPOT_LIGHTS: bool = true;
override NORMAL_MAPS: bool = true;
override MICROFACET: bool = true;
override TEXTURE_TRANSFORMS: bool = true;
override WORKGROUP_SIZE: u32 = 64u;
// AOVs (render::aov): sample 0 writes the first hit's depth, normal and albedo after the
// accumulator; false compiles that code out.
override AOVS: bool = false;

// PI_INV, KIND_*, INTEGRATOR_*, LIGHT_* and PRIMARY_TMAX come from the generated prelude.

// render::gpu::GpuShade: a triangle by original index, for shading.
struct Shade {
    v0: vec3<f32>,
    material: u32,
    v1: vec3<f32>,
    n0: u32,
    v2: vec3<f32>,
    n1: u32,
    uv0: vec2<f32>,
    uv1: vec2<f32>,
    uv2: vec2<f32>,
    n2: u32,
    tangent: u32,
}

fn shade_word(i: u32) -> vec4<u32> {
    if BVH_TEXTURES {
        return textureLoad(shade_texels, vec2<u32>(i % TEXEL_ROW, i / TEXEL_ROW));
    }
    return shade_buffer_word(i);
}

fn load_shade(i: u32) -> Shade {
    let a = shade_word(5u * i);
    let b = shade_word(5u * i + 1u);
    let c = shade_word(5u * i + 2u);
    let d = shade_word(5u * i + 3u);
    let e = shade_word(5u * i + 4u);
    return Shade(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w,
                 bitcast<vec3<f32>>(c.xyz), c.w, bitcast<vec2<f32>>(d.xy),
                 bitcast<vec2<f32>>(d.zw), bitcast<vec2<f32>>(e.xy), e.z, e.w);
}

// A scene with placements (INSTANCES, the two-level traversal): render::gpu::GpuPlacement,
// seven shading words each from params.placement_base — to_world (3 rows), to_object (3
// rows), (first_prim, shade_base, 0, 0). render::scene::Placements is the CPU's.
fn placement_word(i: u32, k: u32) -> vec4<u32> {
    return shade_word(params.placement_base + 7u * i + k);
}

// Placements::locate: the last placement whose first triangle is at most prim.
fn placement_of(prim: u32) -> u32 {
    var lo = 0u;
    var hi = params.n_placements;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if placement_word(mid, 6u).x <= prim {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// The placement of the last placed_shade, its object-space vertices' magnitudes, and its
// shading triangle's number.
var<private> placed: u32;
var<private> placed_vmax: vec3<f32>;
var<private> placed_index: u32;

// RenderScene::triangle: triangle number prim in world space, with its shading data.
fn placed_shade(prim: u32) -> Shade {
    if !INSTANCES {
        placed_index = prim;
        return load_shade(prim);
    }
    placed = placement_of(prim);
    let ids = placement_word(placed, 6u);
    placed_index = ids.y + prim - ids.x;
    var s = load_shade(placed_index);
    placed_vmax = max(max(abs(s.v0), abs(s.v1)), abs(s.v2));
    let w0 = bitcast<vec4<f32>>(placement_word(placed, 0u));
    let w1 = bitcast<vec4<f32>>(placement_word(placed, 1u));
    let w2 = bitcast<vec4<f32>>(placement_word(placed, 2u));
    s.v0 = affine_point(w0, w1, w2, s.v0);
    s.v1 = affine_point(w0, w1, w2, s.v1);
    s.v2 = affine_point(w0, w1, w2, s.v2);
    return s;
}

// RenderScene::point_error: a point's error bound `err` (point_error) plus the rounding of
// the last placed_shade's placement (Placements::error).
fn placed_error(p: vec3<f32>, err: vec3<f32>) -> vec3<f32> {
    if !INSTANCES {
        return err;
    }
    let w0 = abs(bitcast<vec4<f32>>(placement_word(placed, 0u)));
    let w1 = abs(bitcast<vec4<f32>>(placement_word(placed, 1u)));
    let w2 = abs(bitcast<vec4<f32>>(placement_word(placed, 2u)));
    let o0 = abs(bitcast<vec4<f32>>(placement_word(placed, 3u)));
    let o1 = abs(bitcast<vec4<f32>>(placement_word(placed, 4u)));
    let o2 = abs(bitcast<vec4<f32>>(placement_word(placed, 5u)));
    let images = affine_point(w0, w1, w2, placed_vmax);
    let back = affine_vector(w0, w1, w2, affine_point(o0, o1, o2, abs(p)));
    return err + (images + back) * TRANSFORM_ERROR;
}

// geometry::unpack_unit: a packed shading normal, not normalised.
fn unpack_normal(w: u32) -> vec3<f32> {
    let x = f32(bitcast<i32>(w << 16u) >> 16u) * SNORM16_SCALE;
    let y = f32(bitcast<i32>(w) >> 16u) * SNORM16_SCALE;
    let z = 1.0 - abs(x) - abs(y);
    if z < 0.0 {
        return vec3<f32>((1.0 - abs(y)) * select(-1.0, 1.0, x >= 0.0),
                         (1.0 - abs(x)) * select(-1.0, 1.0, y >= 0.0), z);
    }
    return vec3<f32>(x, y, z);
}

// RenderScene::shading_normal: the last placed_shade's corner normals interpolated, in
// world space (moved by the placement's inverse transpose), not normalised; zero where the
// triangle shades flat.
fn shading_normal(s: Shade, w: f32, u: f32, v: f32) -> vec3<f32> {
    if s.n0 == NO_NORMAL {
        return vec3<f32>(0.0);
    }
    let n = unpack_normal(s.n0) * w + unpack_normal(s.n1) * u + unpack_normal(s.n2) * v;
    if !INSTANCES {
        return n;
    }
    let o0 = bitcast<vec4<f32>>(placement_word(placed, 3u)).xyz;
    let o1 = bitcast<vec4<f32>>(placement_word(placed, 4u)).xyz;
    let o2 = bitcast<vec4<f32>>(placement_word(placed, 5u)).xyz;
    return o0 * n.x + o1 * n.y + o2 * n.z;
}

// render::gpu::GpuMaterial
struct Material {
    albedo: vec3<f32>,
    kind: u32,
    emission: vec3<f32>,
    ior: f32,
    tex_offset: u32,
    tex_width: u32,
    tex_height: u32,
    flags: u32,
    metallic: f32,
    roughness: f32,
    mr_offset: u32,
    emission_offset: u32,
    mr_width: u32,
    mr_height: u32,
    emission_width: u32,
    emission_height: u32,
    normal_offset: u32,
    normal_width: u32,
    normal_height: u32,
    normal_scale: f32,
    alpha: f32,
    alpha_cutoff: f32,
    occlusion_offset: u32,
    occlusion_width: u32,
    occlusion_height: u32,
    occlusion_strength: f32,
    uv_maps: u32,
    pad2: u32,
}

// render::gpu::GpuLight: kind 0 point (v = position, power = intensity),
// 1 directional (v = direction of travel, power = irradiance), 2 spot (a point light whose
// intensity falls off about `axis` by `scale` and `offset`).
struct Light {
    v: vec3<f32>,
    kind: u32,
    power: vec3<f32>,
    offset: f32,
    axis: vec3<f32>,
    scale: f32,
}

// Light::spot_falloff
fn spot_falloff(c: f32, scale: f32, offset: f32) -> f32 {
    let a = clamp(c * scale + offset, 0.0, 1.0);
    return a * a;
}

// render::gpu::RenderParams
struct Params {
    eye: vec3<f32>,
    width: u32,
    fwd: vec3<f32>,
    height: u32,
    right: vec3<f32>,
    inv_w2: f32,
    up: vec3<f32>,
    inv_h2: f32,
    env_radiance: vec3<f32>,
    seed: u32,
    sample: u32,
    offset: u32,
    count: u32,
    max_bounces: u32,
    integrator: u32,
    n_lights: u32,
    n_emitters: u32,
    emit_total: f32,
    ao_distance: f32,
    fixed_offset: f32,
    crop_x0: u32,
    crop_y0: u32,
    crop_width: u32,
    aov_base: u32,
    placement_base: u32,
    n_placements: u32,
    env_x: vec3<f32>,
    env_width: u32,
    env_y: vec3<f32>,
    env_height: u32,
    env_z: vec3<f32>,
    env_texels: u32,
    env_cdf: u32,
    has_env: u32,
    tangent_base: u32,
    pad2: u32,
}

// The shading triangles, five words each, in the BVH's memory (BVH_TEXTURES,
// lib/traversal.wgsl): a storage buffer, or a storage texture (which holds more than one
// storage binding may: lavapipe binds 128 MiB). The unused binding is a placeholder. A buffer
// bigger than one binding is bound in parts, read by shade_buffer_word (gpu::BufferParts).
@group(0) @binding(BINDING_RENDER_SHADES) var<storage, read> shade_words: array<vec4<u32>>;
@group(0) @binding(BINDING_RENDER_SHADE_TEXELS)
var shade_texels: texture_storage_2d<rgba32uint, read>;
@group(0) @binding(BINDING_RENDER_MATERIALS) var<storage, read> materials: array<Material>;
@group(0) @binding(BINDING_RENDER_LIGHTS) var<storage, read> lights: array<Light>;
// (original triangle index, running area sum as f32 bits)
@group(0) @binding(BINDING_RENDER_EMITTERS) var<storage, read> emitters: array<vec2<u32>>;
// The texels and the accumulator may be bound in parts (gpu::BufferParts): read them only
// through texel(i), accum_load(i) and accum_store(i, value), never indexed here.
@group(0) @binding(BINDING_RENDER_TEXELS) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(BINDING_RENDER_ACCUM) var<storage, read_write> accum: array<vec4<f32>>;
@group(0) @binding(BINDING_RENDER_PARAMS) var<uniform> params: Params;

// sampling::pcg
fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

var<private> rng_state: u32;

fn next_f32() -> f32 {
    rng_state = pcg(rng_state);
    return f32(rng_state >> 8u) * (1.0 / 16777216.0);
}

fn normalize3(v: vec3<f32>) -> vec3<f32> {
    let l = sqrt(dot3(v, v));
    return vec3<f32>(v.x / l, v.y / l, v.z / l);
}

// sampling::cosine_direction
fn cosine_direction(n: vec3<f32>) -> vec3<f32> {
    var x = 0.0;
    var y = 0.0;
    for (var i = 0; i < 16; i += 1) {
        let a = 2.0 * next_f32() - 1.0;
        let b = 2.0 * next_f32() - 1.0;
        if a * a + b * b <= 1.0 {
            x = a;
            y = b;
            break;
        }
    }
    let z = sqrt(max(1.0 - x * x - y * y, 0.0));
    let f = basis(n);
    return f.t * x + f.b * y + n * z;
}

// sampling::point_error: the error bound of v0·b0 + v1·b1 + v2·b2, per component.
fn point_error(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, b0: f32, b1: f32, b2: f32) -> vec3<f32> {
    return (abs(v0 * b0) + abs(v1 * b1) + abs(v2 * b2)) * POINT_ERROR;
}

fn next_away(x: f32, o: f32) -> f32 {
    // f32::next_up / next_down on the bits (−0.0 steps to the smallest positive or negative).
    let b = bitcast<u32>(x);
    var up = b + 1u;
    if x < 0.0 {
        up = b - 1u;
    } else if b == 0x80000000u {
        up = 1u;
    }
    var down = b + 1u;
    if x > 0.0 {
        down = b - 1u;
    } else if b == 0u {
        down = 0x80000001u;
    }
    if o > 0.0 {
        return bitcast<f32>(up);
    }
    if o < 0.0 {
        return bitcast<f32>(down);
    }
    return x;
}

// CpuRenderer::leave: sampling::offset_origin (pbrt-v4), a fixed epsilon, or none.
fn offset_origin(p: vec3<f32>, err: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if RAY_OFFSET == OFFSET_FIXED {
        return p + n * params.fixed_offset;
    }
    if RAY_OFFSET != OFFSET_ERROR_BOUND {
        return p;
    }
    let d = dot3(abs(n), err);
    let off = n * d;
    let po = p + off;
    return vec3<f32>(next_away(po.x, off.x), next_away(po.y, off.y), next_away(po.z, off.z));
}

// Samples in which the driver cut some loop short, a traversal's (see traversal_done) or the
// integrator's own (loops_were_cut, at the end of render): the host renders those pixels
// again on the CPU.
var<private> sample_incomplete: bool;

// texture::texture_taps: the four texels of a bilinear lookup at uv with wrap-around (indices
// into texels: top left, top right, bottom left, bottom right) and the weights between them.
struct Taps {
    i: vec4<u32>,
    f: vec2<f32>,
}

fn texture_taps(offset: u32, width: u32, height: u32, uv: vec2<f32>) -> Taps {
    let w = i32(width);
    let h = i32(height);
    let u = uv.x - floor(uv.x);
    let v = uv.y - floor(uv.y);
    let x = u * f32(w) - 0.5;
    let y = (1.0 - v) * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let ix0 = ((i32(x0) % w) + w) % w;
    let iy0 = ((i32(y0) % h) + h) % h;
    let ix1 = (ix0 + 1) % w;
    let iy1 = (iy0 + 1) % h;
    let at = vec4<i32>(iy0 * w + ix0, iy0 * w + ix1, iy1 * w + ix0, iy1 * w + ix1);
    return Taps(vec4<u32>(offset) + vec4<u32>(at), vec2<f32>(fx, fy));
}

// CpuRenderer::slot_uv: where `mat`'s texture in `slot` (UV_SLOT_*) is read at
// interpolated uv — moved by the slot's 2 × 3 map, two texels from mat.uv_maps + 2·slot
// (TEXTURE_TRANSFORMS; the upload writes the identity for a slot without one).
fn slot_uv(mat: Material, slot: u32, uv: vec2<f32>) -> vec2<f32> {
    if !TEXTURE_TRANSFORMS || (mat.flags & MAT_UV_TRANSFORMS) == 0u {
        return uv;
    }
    let a = texel(mat.uv_maps + 2u * slot);
    let b = texel(mat.uv_maps + 2u * slot + 1u);
    return vec2<f32>(a.x * uv.x + a.y * uv.y + a.z, b.x * uv.x + b.y * uv.y + b.z);
}

// The four texels around uv blended bilinearly: colour in .xyz, alpha in .w.
fn bilinear(offset: u32, width: u32, height: u32, uv: vec2<f32>) -> vec4<f32> {
    let t = texture_taps(offset, width, height, uv);
    let a = texel(t.i.x);
    let b = texel(t.i.y);
    let c = texel(t.i.z);
    let d = texel(t.i.w);
    let top = a + (b - a) * t.f.x;
    let bottom = c + (d - c) * t.f.x;
    return top + (bottom - top) * t.f.y;
}

// texture::sample_texture: the texture of `w` × `h` texels from `offset` at uv.
fn sample_texture(offset: u32, width: u32, height: u32, uv: vec2<f32>) -> vec3<f32> {
    return bilinear(offset, width, height, uv).xyz;
}

// texture::sample_alpha: the texture's alpha (its texels' w: 1 where the image has none).
fn sample_alpha(offset: u32, width: u32, height: u32, uv: vec2<f32>) -> f32 {
    return bilinear(offset, width, height, uv).w;
}

// render::AlphaMask::keeps, asked by traversal.wgsl's alpha_passes (ALPHA_MASK): whether
// triangle `prim`'s material keeps a hit at (u, v) (a mask: alpha ≥ cutoff; a blend:
// alpha above the hit's blend_threshold). Reads only the shade's material and
// texture coordinates, and leaves `placed` as it was.
fn alpha_keeps(prim: u32, u: f32, v: f32) -> bool {
    var i = prim;
    if INSTANCES {
        let ids = placement_word(placement_of(prim), 6u);
        i = ids.y + prim - ids.x;
    }
    let mat = materials[shade_word(5u * i).w];
    if (mat.flags & MAT_ALPHA_MASK) == 0u {
        return true;
    }
    var alpha = mat.alpha;
    if (mat.flags & MAT_TEXTURED) != 0u {
        let d = shade_word(5u * i + 3u);
        let e = shade_word(5u * i + 4u);
        let uv = bitcast<vec2<f32>>(d.xy) * (1.0 - u - v) + bitcast<vec2<f32>>(d.zw) * u
            + bitcast<vec2<f32>>(e.xy) * v;
        alpha *= sample_alpha(mat.tex_offset, mat.tex_width, mat.tex_height,
                              slot_uv(mat, UV_SLOT_BASE, uv));
    }
    if (mat.flags & MAT_ALPHA_BLEND) != 0u {
        return alpha > blend_threshold(prim, u, v);
    }
    return alpha >= mat.alpha_cutoff;
}

// render::blend_threshold: stochastic transparency's cutoff for a hit, uniform in [0, 1).
fn blend_threshold(prim: u32, u: f32, v: f32) -> f32 {
    let h = pcg(prim ^ pcg(bitcast<u32>(u) ^ pcg(bitcast<u32>(v))));
    return f32(h >> 8u) * (1.0 / 16777216.0);
}

// geometry::unpack_tangent: a packed tangent's direction, not normalised.
fn unpack_tangent(w: u32) -> vec3<f32> {
    let x = f32(bitcast<i32>(w << 17u) >> 17u) * SNORM15_SCALE;
    let y = f32(bitcast<i32>(w << 2u) >> 17u) * SNORM15_SCALE;
    let z = 1.0 - abs(x) - abs(y);
    if z < 0.0 {
        return vec3<f32>((1.0 - abs(y)) * select(-1.0, 1.0, x >= 0.0),
                         (1.0 - abs(x)) * select(-1.0, 1.0, y >= 0.0), z);
    }
    return vec3<f32>(x, y, z);
}

// tangents::interpolated: the last placed_shade's corner tangents (corner 0's in the
// shade, 1 and 2 from params.tangent_base) at weights (w, u, v), not normalised, in .xyz;
// its handedness (the corners' majority) in .w as 1 (flipped) or 0. Call only where the
// shade has a tangent (then so do its other corners).
fn interpolated_tangent(s: Shade, w: f32, u: f32, v: f32) -> vec4<f32> {
    let pair = shade_word(params.tangent_base + placed_index / 2u);
    let others = select(pair.xy, pair.zw, (placed_index & 1u) != 0u);
    let t = unpack_tangent(s.tangent) * w + unpack_tangent(others.x) * u
        + unpack_tangent(others.y) * v;
    let flips = u32((s.tangent & TANGENT_FLIPPED) != 0u) + u32((others.x & TANGENT_FLIPPED) != 0u)
        + u32((others.y & TANGENT_FLIPPED) != 0u);
    return vec4<f32>(t, select(0.0, 1.0, flips >= 2u));
}

// CpuRenderer::mapped_normal: the normal map's normal (not normalised) in .xyz of `m` and
// the unit normal of the frame it tilts in `front`, for the shading normal sn (zero: none)
// and the last placed_shade's tangent (RenderScene::tangent: moved by the placement; its
// handedness is the winding's); false where there is none.
var<private> mapped_front: vec3<f32>;
var<private> mapped_m: vec3<f32>;

fn mapped_normal(s: Shade, mat: Material, w: f32, u: f32, v: f32, sn: vec3<f32>) -> bool {
    if !NORMAL_MAPS || (mat.flags & MAT_NORMAL_MAP) == 0u || (s.tangent & TANGENT_PRESENT) == 0u {
        return false;
    }
    let tangent = interpolated_tangent(s, w, u, v);
    var t = tangent.xyz;
    var flipped = tangent.w != 0.0;
    if INSTANCES {
        let w0 = bitcast<vec4<f32>>(placement_word(placed, 0u));
        let w1 = bitcast<vec4<f32>>(placement_word(placed, 1u));
        let w2 = bitcast<vec4<f32>>(placement_word(placed, 2u));
        t = affine_vector(w0, w1, w2, t);
    }
    let wn = cross3(s.v1 - s.v0, s.v2 - s.v0);
    var n: vec3<f32>;
    if dot3(sn, sn) > 0.0 {
        n = normalize3(sn);
        flipped = flipped != (dot3(sn, wn) < 0.0);
    } else {
        n = normalize3(wn);
    }
    t = t - n * dot3(n, t);
    if !(dot3(t, t) > 0.0) {
        return false;
    }
    t = normalize3(t);
    let b = cross3(n, t) * select(1.0, -1.0, flipped);
    let uv = s.uv0 * w + s.uv1 * u + s.uv2 * v;
    let c = sample_texture(mat.normal_offset, mat.normal_width, mat.normal_height,
                           slot_uv(mat, UV_SLOT_NORMAL, uv)) * 2.0
        - vec3<f32>(1.0);
    mapped_m = t * (c.x * mat.normal_scale) + b * (c.y * mat.normal_scale) + n * c.z;
    mapped_front = n;
    return true;
}

// cpu::turned: a shading normal (zero: none) turned to n's side, or n.
fn turned(sn: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if !(dot3(sn, sn) > 0.0) {
        return n;
    }
    let ns = normalize3(sn);
    return select(ns, -ns, dot3(ns, n) < 0.0);
}

// CpuRenderer::shading_side: the shading normal, tilted by the normal map, turned to n's
// side as the untilted normal is, or the untilted one where the tilt leans below the
// surface; n where there is none.
fn shading_side(s: Shade, mat: Material, w: f32, u: f32, v: f32, n: vec3<f32>) -> vec3<f32> {
    if !SHADING_NORMALS {
        return n;
    }
    let sn = shading_normal(s, w, u, v);
    if mapped_normal(s, mat, w, u, v, sn) {
        let front = mapped_front;
        var m = mapped_m;
        if dot3(front, n) < 0.0 {
            m = -m;
        }
        if dot3(m, m) > 0.0 && dot3(m, n) > 0.0 {
            return normalize3(m);
        }
        return turned(front, n);
    }
    return turned(sn, n);
}

// cpu::keeps_side: d leaves on the side `toward` says of the geometric normal n.
fn keeps_side(d: vec3<f32>, n: vec3<f32>, toward: bool) -> bool {
    return !SHADING_NORMALS || (dot3(d, n) > 0.0) == toward;
}

// CpuRenderer::albedo
fn surface_albedo(mat: Material, s: Shade, w: f32, u: f32, v: f32) -> vec3<f32> {
    if TEXTURES && (mat.flags & MAT_TEXTURED) != 0u {
        let uv = s.uv0 * w + s.uv1 * u + s.uv2 * v;
        return sample_texture(mat.tex_offset, mat.tex_width, mat.tex_height,
                              slot_uv(mat, UV_SLOT_BASE, uv)) * mat.albedo;
    }
    return mat.albedo;
}

// CpuRenderer::bsdf
fn surface_bsdf(mat: Material, s: Shade, w: f32, u: f32, v: f32) -> Bsdf {
    let albedo = surface_albedo(mat, s, w, u, v);
    if !(MICROFACET && mat.kind == KIND_PRINCIPLED) {
        return Bsdf(albedo, 0.0, 1.0, false);
    }
    var metallic = mat.metallic;
    var roughness = mat.roughness;
    if TEXTURES && (mat.flags & MAT_METALLIC_ROUGHNESS) != 0u {
        let uv = s.uv0 * w + s.uv1 * u + s.uv2 * v;
        let mr = sample_texture(mat.mr_offset, mat.mr_width, mat.mr_height,
                                slot_uv(mat, UV_SLOT_METALLIC_ROUGHNESS, uv));
        roughness *= mr.y;
        metallic *= mr.z;
    }
    return principled(albedo, metallic, roughness);
}

// CpuRenderer::emission
fn surface_emission(mat: Material, s: Shade, w: f32, u: f32, v: f32) -> vec3<f32> {
    if TEXTURES && (mat.flags & MAT_EMISSION_TEXTURE) != 0u {
        let uv = s.uv0 * w + s.uv1 * u + s.uv2 * v;
        let t = sample_texture(mat.emission_offset, mat.emission_width, mat.emission_height,
                               slot_uv(mat, UV_SLOT_EMISSION, uv));
        return mat.emission * t;
    }
    return mat.emission;
}

// The tile pixel whose AOVs this invocation writes (sample 0 only).
var<private> aov_slot: u32;

// CpuRenderer::occlusion
fn surface_occlusion(mat: Material, s: Shade, w: f32, u: f32, v: f32) -> f32 {
    if TEXTURES && (mat.flags & MAT_OCCLUSION) != 0u {
        let uv = s.uv0 * w + s.uv1 * u + s.uv2 * v;
        let t = sample_texture(mat.occlusion_offset, mat.occlusion_width, mat.occlusion_height,
                               slot_uv(mat, UV_SLOT_OCCLUSION, uv));
        return 1.0 + mat.occlusion_strength * (t.x - 1.0);
    }
    return 1.0;
}

// CpuRenderer::first_hit, written after the accumulator as two vec4s: (depth, normal) and
// (albedo, occlusion); a miss writes depth −1 (the host reads it as +∞: WGSL has no
// runtime ∞).
fn write_aovs(depth: f32, n: vec3<f32>, albedo: vec3<f32>, occlusion: f32) {
    if AOVS && params.sample == 0u {
        accum_store(params.aov_base + 2u * aov_slot, vec4<f32>(depth, n));
        accum_store(params.aov_base + 2u * aov_slot + 1u, vec4<f32>(albedo, occlusion));
    }
}

// The integrator is resumable, so that every lane calls trace_ray() at the same time (a
// subgroup traversal walks with all the lanes of its subgroup): it runs CpuRenderer::sample
// up to the next ray that function traces, leaves that ray in `query` and where to go on in
// `step`, and the step functions below go on from there with the ray's hit (sample_alone
// and sample_together call them). Each lane does the CPU's operations in the CPU's order,
// so the sample is the same bit for bit.
const STEP_PATH: u32 = 0u;     // query: this bounce's path ray (closest hit)
const STEP_AO: u32 = 1u;       // query: the ambient-occlusion ray
const STEP_LIGHT: u32 = 2u;    // query: the shadow ray to lights[light_i]
const STEP_EMITTER: u32 = 3u;  // query: the shadow ray to the point sampled on an emitter
const STEP_DONE: u32 = 4u;     // the sample is finished
// Steps with no ray in flight: where to go on after a ray's hit.
const STEP_LIGHTS: u32 = 5u;   // next: the lights from lights[light_i] on
const STEP_EMITTER_SAMPLE: u32 = 6u;  // next: the emitter sample
const STEP_END_DIRECT: u32 = 7u;      // next: the bounce after direct()
const STEP_ENV: u32 = 8u;             // query: the shadow ray toward the environment's sample
const STEP_ENV_SAMPLE: u32 = 9u;      // next: the environment's sample

var<private> step: u32;
var<private> query: Ray;
// CpuRenderer::sample's path state.
var<private> rad: vec3<f32>;
var<private> beta: vec3<f32>;
var<private> bounce: u32;
// The density the last diffuse or principled bounce drew the path ray's direction with
// (0: a camera ray or a specular bounce).
var<private> bounce_pdf: f32;
// CpuRenderer::direct's state at a diffuse or principled hit: the point, the normals, the
// surface and the direction toward the viewer, the shadow rays' origin, the light summed
// so far, and what the light of the shadow ray in flight adds if nothing blocks it.
var<private> at_p: vec3<f32>;
var<private> at_n: vec3<f32>;  // the shading normal
var<private> at_ng: vec3<f32>; // the geometric normal
var<private> at_bsdf: Bsdf;
var<private> at_wo: vec3<f32>;
var<private> at_o: vec3<f32>;
var<private> light_sum: vec3<f32>;
var<private> light_i: u32;
var<private> pending: vec3<f32>;

// CpuRenderer::camera_ray and the start of CpuRenderer::sample.
fn start_sample(x: u32, y: u32) {
    let pixel = y * params.width + x;
    rng_state = pcg(params.seed ^ pcg(pixel ^ pcg(params.sample)));
    let jx = next_f32();
    let jy = next_f32();
    // CameraFrame::ray
    let sx = (f32(x) + jx) * params.inv_w2 - 1.0;
    let sy = 1.0 - (f32(y) + jy) * params.inv_h2;
    rad = vec3<f32>(0.0);
    beta = vec3<f32>(1.0);
    bounce = 0u;
    bounce_pdf = 0.0;
    query = Ray(params.eye, 0.0, normalize3(params.fwd + params.right * sx + params.up * sy), PRIMARY_TMAX);
    step = STEP_PATH;
}

// The next bounce's path ray (sample's loop never passes max_bounces here: its callers
// stop at the last bounce).
fn next_bounce(r: Ray) {
    bounce += 1u;
    query = r;
    step = STEP_PATH;
}

// CpuRenderer::sample's bounce after the path ray's hit.
fn path_hit(hit: Hit) {
    let ray = query;
    if hit.prim == MISS {
        if bounce == 0u {
            write_aovs(-1.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
        }
        if ENVIRONMENT && params.has_env != 0u {
            var w = 1.0;
            if bounce_pdf > 0.0 {
                w = power_heuristic(bounce_pdf, env_pdf(ray.dir));
            }
            rad += beta * env_eval(ray.dir) * w;
        }
        step = STEP_DONE;
        return;
    }
    let s = placed_shade(hit.prim);
    let mat = materials[s.material];
    let w = 1.0 - hit.u - hit.v;
    let p = s.v0 * w + s.v1 * hit.u + s.v2 * hit.v;
    let p_err = placed_error(p, point_error(s.v0, s.v1, s.v2, w, hit.u, hit.v));
    let ng = normalize3(cross3(s.v1 - s.v0, s.v2 - s.v0));
    let front = dot3(ng, ray.dir) < 0.0;
    let n = select(-ng, ng, front);
    let ns = shading_side(s, mat, w, hit.u, hit.v, n);
    if AOVS && bounce == 0u {
        write_aovs(hit.t, ns, surface_albedo(mat, s, w, hit.u, hit.v),
                   surface_occlusion(mat, s, w, hit.u, hit.v));
    }
    if mat.kind == KIND_EMISSIVE {
        if front || (mat.flags & MAT_TWO_SIDED) != 0u {
            // Multiple importance sampling with the light sample of the last hit.
            var w = 1.0;
            if SOFT_SHADOWS && params.n_emitters > 0u && bounce_pdf > 0.0 {
                let cl = abs(dot3(n, ray.dir)) / sqrt(dot3(ray.dir, ray.dir));
                let d2 = hit.t * hit.t * dot3(ray.dir, ray.dir);
                w = power_heuristic(bounce_pdf, d2 / (cl * params.emit_total));
            }
            rad += beta * mat.emission * w;
        }
        step = STEP_DONE;
        return;
    }
    if AO && params.integrator == INTEGRATOR_AO {
        let d = cosine_direction(ns);
        if !keeps_side(d, n, true) {
            step = STEP_DONE;
            return;
        }
        query = Ray(offset_origin(p, p_err, n), 0.0, d, params.ao_distance);
        step = STEP_AO;
        return;
    }
    let last = bounce == params.max_bounces;
    let mirror = MIRROR && mat.kind == KIND_MIRROR;
    let glass = REFRACTION && mat.kind == KIND_GLASS;
    let d = ray.dir;
    let reflected = d - ns * (2.0 * dot3(d, ns));
    if (mirror || glass) && last {
        step = STEP_DONE;
        return;
    }
    if mirror {
        if !keeps_side(reflected, n, true) {
            step = STEP_DONE;
            return;
        }
        beta *= mat.albedo;
        bounce_pdf = 0.0;
        next_bounce(Ray(offset_origin(p, p_err, n), 0.0, reflected, PRIMARY_TMAX));
        return;
    }
    if glass {
        let cos_i = -dot3(d, ns);
        let eta = select(mat.ior, 1.0 / mat.ior, front);
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        var r0 = (1.0 - mat.ior) / (1.0 + mat.ior);
        r0 = r0 * r0;
        let m = 1.0 - cos_i;
        let fresnel = r0 + (1.0 - r0) * (m * m * m * m * m);
        let u = next_f32();
        beta *= mat.albedo;
        bounce_pdf = 0.0;
        if sin2_t >= 1.0 || u < fresnel {
            if !keeps_side(reflected, n, true) {
                step = STEP_DONE;
                return;
            }
            next_bounce(Ray(offset_origin(p, p_err, n), 0.0, reflected, PRIMARY_TMAX));
        } else {
            let cos_t = sqrt(1.0 - sin2_t);
            let t = d * eta + ns * (eta * cos_i - cos_t);
            if !keeps_side(t, n, false) {
                step = STEP_DONE;
                return;
            }
            next_bounce(Ray(offset_origin(p, p_err, -n), 0.0, t, PRIMARY_TMAX));
        }
        return;
    }
    // Diffuse or principled: CpuRenderer::direct, from its first light.
    let bsdf = surface_bsdf(mat, s, w, hit.u, hit.v);
    let wo = -d;
    var nb = ns;
    if bsdf.principled {
        if front || (mat.flags & MAT_TWO_SIDED) != 0u {
            rad += beta * surface_emission(mat, s, w, hit.u, hit.v);
        }
        // A view below the shading normal sees the geometric one.
        if dot3(ns, wo) <= 0.0 {
            nb = n;
        }
    }
    at_p = p;
    at_n = nb;
    at_ng = n;
    at_bsdf = bsdf;
    at_wo = wo;
    at_o = offset_origin(p, p_err, n);
    light_sum = vec3<f32>(0.0);
    light_i = 0u;
    step = STEP_LIGHTS;
}

// CpuRenderer::direct's loop over the lights, from lights[light_i] to its next shadow ray.
fn light_rays() {
    let p = at_p;
    let n = at_n;
    let o = at_o;
    for (; light_i < params.n_lights; light_i += 1u) {
        let l = lights[light_i];
        if l.kind == LIGHT_SPOT {
            if !SPOT_LIGHTS {
                continue;
            }
            let d = l.v - p;
            let d2 = dot3(d, d);
            let wi = d / sqrt(d2);
            let c = dot3(n, wi);
            let falloff = spot_falloff(-dot3(l.axis, wi), l.scale, l.offset);
            if c > 0.0 && falloff > 0.0 && keeps_side(d, at_ng, true) {
                pending = l.power * bsdf_eval(at_bsdf, n, at_wo, wi).xyz * (falloff / d2);
                if SHADOWS {
                    query = Ray(o, 0.0, l.v - o, 1.0);
                    step = STEP_LIGHT;
                    return;
                }
                light_sum += pending;
            }
        } else if l.kind == LIGHT_POINT {
            let d = l.v - p;
            let d2 = dot3(d, d);
            let wi = d / sqrt(d2);
            let c = dot3(n, wi);
            if c > 0.0 && keeps_side(d, at_ng, true) {
                pending = l.power * bsdf_eval(at_bsdf, n, at_wo, wi).xyz / d2;
                if SHADOWS {
                    query = Ray(o, 0.0, l.v - o, 1.0);
                    step = STEP_LIGHT;
                    return;
                }
                light_sum += pending;
            }
        } else {
            let c = -dot3(n, l.v);
            if c > 0.0 && keeps_side(-l.v, at_ng, true) {
                pending = l.power * bsdf_eval(at_bsdf, n, at_wo, -l.v).xyz;
                if SHADOWS {
                    query = Ray(o, 0.0, -l.v, PRIMARY_TMAX);
                    step = STEP_LIGHT;
                    return;
                }
                light_sum += pending;
            }
        }
    }
    step = STEP_EMITTER_SAMPLE;
}

// CpuRenderer::direct's emitter sample, up to its shadow ray.
fn emitter_ray() {
    if SOFT_SHADOWS && params.n_emitters > 0u {
        let p = at_p;
        let n = at_n;
        let target_area = next_f32() * params.emit_total;
        var lo = 0u;
        var hi = params.n_emitters - 1u;
        while lo < hi {
            let mid = (lo + hi) / 2u;
            if bitcast<f32>(emitters[mid].y) > target_area {
                hi = mid;
            } else {
                lo = mid + 1u;
            }
        }
        let s = placed_shade(emitters[lo].x);
        let su = sqrt(next_f32());
        let b0 = 1.0 - su;
        let b1 = next_f32() * su;
        let b2 = 1.0 - b0 - b1;
        let q = s.v0 * b0 + s.v1 * b1 + s.v2 * b2;
        let q_err = placed_error(q, point_error(s.v0, s.v1, s.v2, b0, b1, b2));
        let nl = normalize3(cross3(s.v1 - s.v0, s.v2 - s.v0));
        let d = q - p;
        let d2 = dot3(d, d);
        let wi = d / sqrt(d2);
        let cs = dot3(n, wi);
        let lm = materials[s.material];
        // One-sided lights emit from their front (the winding's normal) only.
        var cl = -dot3(nl, wi);
        if (lm.flags & MAT_TWO_SIDED) != 0u {
            cl = abs(dot3(nl, wi));
        }
        if cs > 0.0 && cl > 0.0 && keeps_side(d, at_ng, true) {
            let toward = select(nl, -nl, dot3(nl, d) > 0.0);
            let qt = offset_origin(q, q_err, toward);
            let e = bsdf_eval(at_bsdf, n, at_wo, wi);
            var w = 1.0;
            if path_continues() {
                w = power_heuristic(d2 / (cl * params.emit_total), e.w);
            }
            pending = lm.emission * e.xyz * (cl / d2 * params.emit_total * w);
            if SHADOWS {
                query = Ray(at_o, 0.0, qt - at_o, 1.0);
                step = STEP_EMITTER;
                return;
            }
            light_sum += pending;
        }
    }
    step = STEP_ENV_SAMPLE;
}

// cpu::power_heuristic
fn power_heuristic(a: f32, b: f32) -> f32 {
    if a >= b {
        let r = b / a;
        return 1.0 / (1.0 + r * r);
    }
    let r = a / b;
    return r * r / (1.0 + r * r);
}

// CpuRenderer::direct's environment sample, up to its shadow ray.
fn env_ray() {
    if ENVIRONMENT && params.has_env != 0u {
        let u1 = next_f32();
        let u2 = next_f32();
        let e = env_sample(u1, u2);
        if e.w > 0.0 {
            let d = e.xyz;
            let c = dot3(at_n, d);
            if c > 0.0 && keeps_side(d, at_ng, true) {
                let f = bsdf_eval(at_bsdf, at_n, at_wo, d);
                var w = 1.0;
                if path_continues() {
                    w = power_heuristic(e.w, f.w);
                }
                pending = env_eval(d) * f.xyz * (w / e.w);
                if SHADOWS {
                    query = Ray(at_o, 0.0, d, PRIMARY_TMAX);
                    step = STEP_ENV;
                    return;
                }
                light_sum += pending;
            }
        }
    }
    step = STEP_END_DIRECT;
}

// CpuRenderer::sample's `bounces`: a bounce sampled from the BSDF follows this hit.
fn path_continues() -> bool {
    return INDIRECT && params.integrator == INTEGRATOR_PATH && bounce != params.max_bounces;
}

// CpuRenderer::sample's diffuse or principled bounce after direct().
fn end_direct() {
    rad += beta * light_sum;
    if !path_continues() {
        step = STEP_DONE;
        return;
    }
    let b = bsdf_sample(at_bsdf, at_n, at_wo);
    if !(b.pdf > 0.0) || !keeps_side(b.dir, at_ng, true) {
        step = STEP_DONE;
        return;
    }
    beta *= b.weight;
    bounce_pdf = b.pdf;
    // at_o is the CPU's second leave(p, p_err, n): the same origin.
    next_bounce(Ray(at_o, 0.0, b.dir, PRIMARY_TMAX));
}

// What the hit of the ray in `query` does, by the step that traced it.
fn ao_hit(hit: Hit) {
    if hit.prim == MISS {
        rad += beta;
    }
    step = STEP_DONE;
}

fn light_hit(hit: Hit) {
    if hit.prim == MISS {
        light_sum += pending;
    }
    light_i += 1u;
    step = STEP_LIGHTS;
}

fn emitter_hit(hit: Hit) {
    if hit.prim == MISS {
        light_sum += pending;
    }
    step = STEP_ENV_SAMPLE;
}

fn env_hit(hit: Hit) {
    if hit.prim == MISS {
        light_sum += pending;
    }
    step = STEP_END_DIRECT;
}

// Traces `query`, noting a traversal the driver cut short.
fn trace_query(any_hit: bool) -> Hit {
    let hit = trace_ray(query, any_hit);
    sample_incomplete = sample_incomplete || !traversal_done;
    return hit;
}

// Each lane on its own: CpuRenderer::sample's loops, each ray traced where the CPU traces
// it. (lavapipe runs every branch that any of its SIMD lanes takes, so this costs less
// than going round all the steps once a ray.)
fn sample_alone() {
    loop {
        if step == STEP_DONE {
            break;
        }
        // The path ray, or the AO ray after it.
        let hit = trace_query(step == STEP_AO);
        if step == STEP_AO {
            ao_hit(hit);
            break;
        }
        path_hit(hit);
        if step != STEP_LIGHTS {
            continue;
        }
        loop {
            light_rays();
            if step != STEP_LIGHT {
                break;
            }
            light_hit(trace_query(true));
        }
        emitter_ray();
        if step == STEP_EMITTER {
            emitter_hit(trace_query(true));
        }
        env_ray();
        if step == STEP_ENV {
            env_hit(trace_query(true));
        }
        end_direct();
    }
}

// The lanes that traverse together (lanes_any) trace one ray each a round, until none has
// one left; a finished lane traverses an invalid ray (a miss at once). A step's code runs
// only in rounds where some lane is at it, and each function is inlined once.
fn sample_together() {
    loop {
        let has_ray = step != STEP_DONE;
        if !lanes_any(has_ray) {
            break;
        }
        var r = Ray(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);  // zero direction: invalid
        if has_ray {
            r = query;
        }
        let hit = trace_ray(r, step != STEP_PATH);
        sample_incomplete = sample_incomplete || (has_ray && !traversal_done);
        let traced = step;
        if lanes_any(traced == STEP_PATH) && traced == STEP_PATH {
            path_hit(hit);
        }
        if lanes_any(traced == STEP_AO) && traced == STEP_AO {
            ao_hit(hit);
        }
        if lanes_any(traced == STEP_LIGHT) && traced == STEP_LIGHT {
            light_hit(hit);
        }
        if lanes_any(traced == STEP_EMITTER) && traced == STEP_EMITTER {
            emitter_hit(hit);
        }
        if lanes_any(traced == STEP_ENV) && traced == STEP_ENV {
            env_hit(hit);
        }
        if lanes_any(step == STEP_LIGHTS) && step == STEP_LIGHTS {
            light_rays();
        }
        if lanes_any(step == STEP_EMITTER_SAMPLE) && step == STEP_EMITTER_SAMPLE {
            emitter_ray();
        }
        if lanes_any(step == STEP_ENV_SAMPLE) && step == STEP_ENV_SAMPLE {
            env_ray();
        }
        if lanes_any(step == STEP_END_DIRECT) && step == STEP_END_DIRECT {
            end_direct();
        }
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Invocations past the last pixel go along with no ray, so that a subgroup traversal
    // keeps all its lanes.
    let live = gid.x < params.count;
    // The accumulator holds the crop's pixels; the random numbers are the full image's.
    let pixel = params.offset + gid.x;
    aov_slot = pixel;
    sample_incomplete = false;
    step = STEP_DONE;
    if live {
        start_sample(params.crop_x0 + pixel % params.crop_width, params.crop_y0 + pixel / params.crop_width);
    }
    if LANES_TOGETHER {
        sample_together();
    } else {
        sample_alone();
    }
    // A driver's cut can end any loop of the sample as if it had finished, not only a
    // traversal's: the sample's own (its next bounce never traced), the lights', the
    // rejection sampler's; none of them shows it in the sample's state, so the sample asks
    // whether this invocation's loops were cut at all (or it stopped short of its end).
    if step != STEP_DONE || loops_were_cut(pixel) {
        sample_incomplete = true;
    }
    if live {
        // w counts the samples of this pixel that a driver cut short.
        accum_store(pixel, accum_load(pixel) + vec4<f32>(rad, select(0.0, 1.0, sample_incomplete)));
    }
}
