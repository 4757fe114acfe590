// Closest-hit / any-hit trace kernel: one ray per invocation through traverse() (bvh.wgsl).
// Variants are override constants of this one source, never copies.

override ANY_HIT: bool = false;          // Query::Any: stop at the first hit
override WORKGROUP_SIZE: u32 = 64u;

// gpu::trace::Params: this dispatch covers rays [offset, offset + count).
struct Params {
    offset: u32,
    count: u32,
}

@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> hits: array<Hit>;
@group(0) @binding(4) var<storage, read_write> stats: array<vec2<u32>>;
@group(0) @binding(5) var<uniform> params: Params;

@compute @workgroup_size(WORKGROUP_SIZE)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.count {
        return;
    }
    let ri = params.offset + gid.x;
    hits[ri] = traverse(rays[ri], ANY_HIT);
    if COUNT_STATS {
        stats[ri] = vec2<u32>(n_nodes, n_tris);
    }
}
