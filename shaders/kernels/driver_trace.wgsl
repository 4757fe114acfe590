// The driver's own traversal (gpu::driver): one ray per invocation through a Vulkan ray
// query on the driver's acceleration structure, built from the layout's leaf triangles in
// leaf order. A reference row and an independent oracle, not one of lancer's kernels: its t
// is the driver's arithmetic, so it agrees with lancer up to the oracle's tolerance.
// The module starts with `enable wgpu_ray_query;` (gpu::shaders::driver_trace_source).

override ANY_HIT: bool = false;  // Query::Any: stop at the first hit
override WORKGROUP_SIZE: u32 = 64u;

// gpu::trace::TraceParams: this dispatch covers rays [offset, offset + count).
struct Params {
    offset: u32,
    count: u32,
}

@group(0) @binding(BINDING_DRIVER_SCENE) var scene: acceleration_structure;
// accel::LeafTri words: the driver's primitive i is leaf triangle i, whose original index
// is the w slot of its first word.
@group(0) @binding(BINDING_TRI_WORDS) var<storage, read> tri_words: array<vec4<u32>>;
@group(0) @binding(BINDING_TRACE_RAYS) var<storage, read> rays: array<Ray>;
@group(0) @binding(BINDING_TRACE_HITS) var<storage, read_write> hits: array<Hit>;
@group(0) @binding(BINDING_TRACE_PARAMS) var<uniform> params: Params;

@compute @workgroup_size(WORKGROUP_SIZE)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.count {
        return;
    }
    let ri = params.offset + gid.x;
    let r = rays[ri];
    var h = Hit(r.tmax, MISS, 0.0, 0.0);
    // Invalid rays are misses, as in every lancer kernel; the driver also wants tmin >= 0.
    if ray_is_valid(r) && r.tmin >= 0.0 {
        var flags = RAY_FLAG_FORCE_OPAQUE;
        if ANY_HIT {
            flags |= RAY_FLAG_TERMINATE_ON_FIRST_HIT;
        }
        var rq: ray_query;
        rayQueryInitialize(&rq, scene, RayDesc(flags, 0xffu, r.tmin, r.tmax, r.origin, r.dir));
        // Opaque geometry only: the driver commits every hit itself.
        while rayQueryProceed(&rq) {
        }
        let x = rayQueryGetCommittedIntersection(&rq);
        if x.kind == RAY_QUERY_INTERSECTION_TRIANGLE {
            h = Hit(x.t, tri_words[3u * x.primitive_index].w, x.barycentrics.x,
                    x.barycentrics.y);
        }
    }
    hits[ri] = h;
}
