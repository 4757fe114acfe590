// Closest-hit / any-hit traversal of the flat BVH (trace::cpu::trace_ray on the GPU).
// Variants are override constants of this one source, never copies.

override ANY_HIT: bool = false;          // Query::Any: stop at the first hit
override COUNT_STATS: bool = false;      // write nodes visited / triangles tested per ray
override MOLLER_TRUMBORE: bool = false;  // TriangleTest::MollerTrumbore instead of watertight
override WORKGROUP_SIZE: u32 = 64u;

// gpu::trace::Params: this dispatch covers rays [offset, offset + count).
struct Params {
    offset: u32,
    count: u32,
}

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> tris: array<Tri>;
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
    let r = rays[ri];
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    var n_nodes = 0u;
    var n_tris = 0u;
    if ray_is_valid(r) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        var stack: array<u32, STACK_SIZE>;
        var sp = 0u;
        var idx = 0u;
        var done = false;
        loop {
            let node = nodes[idx];
            n_nodes += 1u;
            var descended = false;
            if slab_hit(node.lo, node.hi, r.origin, inv, r.tmin, best.t) {
                if (node.b & 3u) != LEAF_TAG {
                    var near = idx + 1u;
                    var far = node.a;
                    if r.dir[node.b & 3u] < 0.0 {
                        near = node.a;
                        far = idx + 1u;
                    }
                    stack[sp] = far;
                    sp += 1u;
                    idx = near;
                    descended = true;
                } else {
                    let end = node.a + (node.b >> 2u);
                    for (var i = node.a; i < end; i += 1u) {
                        let tri = tris[i];
                        n_tris += 1u;
                        var h: TriHit;
                        if MOLLER_TRUMBORE {
                            h = intersect_moller_trumbore(tri, r, r.tmin, best.t);
                        } else {
                            h = intersect_watertight(tri, r.origin, w, r.tmin, best.t);
                        }
                        if h.ok && beats(h.t, tri.prim, best.t, best.prim) {
                            best = Hit(h.t, tri.prim, h.u, h.v);
                            if ANY_HIT {
                                done = true;
                                break;
                            }
                        }
                    }
                }
            }
            if done {
                break;
            }
            if !descended {
                if sp == 0u {
                    break;
                }
                sp -= 1u;
                idx = stack[sp];
            }
        }
    }
    hits[ri] = best;
    if COUNT_STATS {
        stats[ri] = vec2<u32>(n_nodes, n_tris);
    }
}
