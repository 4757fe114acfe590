// Closest-hit / any-hit trace kernel: one ray per invocation through trace_ray(): the form's
// traverse() (its per-ray traversal, or its subgroup traversal:
// gpu::shaders::trace_subgroup_source), or a two-level form's walk of its top level.
// Variants are override constants of this one source, never copies.

override ANY_HIT: bool = false;          // Query::Any: stop at the first hit
override WORKGROUP_SIZE: u32 = 64u;

// gpu::trace::TraceParams: this dispatch covers rays [offset, offset + count).
struct Params {
    offset: u32,
    count: u32,
}

// Rays and hits as 16-byte words (a Ray is two, a Hit one): lavapipe turns each storage
// access into a loop over the lanes, and a struct's load or store into one such loop per
// field (four for a Ray, four for a Hit). Three loops a ray instead of eight; on this
// project's machine the gain was within the noise of six paired runs (bunny, Mesa 25).
@group(0) @binding(BINDING_TRACE_RAYS) var<storage, read> rays: array<vec4<f32>>;
@group(0) @binding(BINDING_TRACE_HITS) var<storage, read_write> hits: array<vec4<u32>>;
@group(0) @binding(BINDING_TRACE_STATS) var<storage, read_write> stats: array<vec2<u32>>;
@group(0) @binding(BINDING_TRACE_PARAMS) var<uniform> params: Params;

@compute @workgroup_size(WORKGROUP_SIZE)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Every invocation calls trace_ray(), those past the last ray with an invalid one (a
    // miss at once), so a subgroup traversal (Layout::subgroup_wgsl) keeps all its lanes.
    let live = gid.x < params.count;
    let ri = params.offset + gid.x;
    var r = Ray(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);  // zero direction: invalid
    if live {
        let a = rays[2u * ri];
        let b = rays[2u * ri + 1u];
        r = Ray(a.xyz, a.w, b.xyz, b.w);
    }
    var h = trace_ray(r, ANY_HIT);
    if !live {
        return;
    }
    if !traversal_done {
        h.prim = INCOMPLETE;  // cut short by the driver: the host traces it again
    }
    hits[ri] = vec4<u32>(bitcast<u32>(h.t), h.prim, bitcast<u32>(h.u), bitcast<u32>(h.v));
    if COUNT_STATS {
        stats[ri] = vec2<u32>(n_nodes, n_tris);
    }
}
