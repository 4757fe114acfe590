// The top level over instances (accel::instances), walked as dfs-sign walks its nodes: the
// far child stacked, the near one by the ray's sign on the split axis. At an instance the ray
// moves into object space and the bottom level's traverse() continues the trace in its own
// arrays (bottom_node_base, bottom_tri_base). The CPU twin is two_level.rs
// (TwoLevel::intersect), step for step. TOP_LEAF_TAG is generated from the Rust LEAF_TAG.

override TOP_NODE_BASE: u32 = 0u;   // first word of the top level's dfs nodes
override TOP_ENTRY_BASE: u32 = 0u;  // first word of its entries (top_level.rs TopEntry)

// The kernels' trace: closest hit in [tmin, tmax] over every instance, or with any_hit the
// first hit met. Work counters and traversal_done cover both levels.
fn trace_ray(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    var nodes = 0u;
    var tris = 0u;
    var done = true;
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        var prune = prune_bound(best.t);
        var stack: array<u32, STACK_SIZE>;
        var sp = 0u;
        var idx = 0u;
        loop {
            // Inner nodes until a hit leaf or the end of the walk, the next node popped
            // first: the lanes of a SIMD group then enter their instances together, rather
            // than one lane's bottom-level traversal waiting for another's inner steps. The
            // nodes are visited in the order of a one-loop walk (the twin's).
            var entered = false;
            var k = 0u;  // the hit leaf's instance (a leaf holds one: top_level.rs)
            var finished = false;
            loop {
                let na = array_node_word(TOP_NODE_BASE + 2u * idx);
                let nb = array_node_word(TOP_NODE_BASE + 2u * idx + 1u);
                nodes += 1u;
                if slab_hit(bitcast<vec3<f32>>(na.xyz), bitcast<vec3<f32>>(nb.xyz), r.origin,
                            inv, r.tmin, prune) {
                    if (nb.w & 3u) != TOP_LEAF_TAG {
                        var near = idx + 1u;
                        var far = na.w;
                        if r.dir[nb.w & 3u] < 0.0 {
                            near = na.w;
                            far = idx + 1u;
                        }
                        stack[sp] = far;
                        sp += 1u;
                        idx = near;
                        continue;
                    }
                    entered = true;
                    k = na.w;
                }
                if sp == 0u {
                    finished = true;
                } else {
                    sp -= 1u;
                    idx = stack[sp];
                }
                if entered || finished {
                    break;
                }
            }
            // One instance, not a loop over a leaf's: on lavapipe the bottom level's
            // traversal nested one loop deeper ran ~15% slower.
            if entered {
                let e = TOP_ENTRY_BASE + 4u * k;
                let m0 = bitcast<vec4<f32>>(array_node_word(e));
                let m1 = bitcast<vec4<f32>>(array_node_word(e + 1u));
                let m2 = bitcast<vec4<f32>>(array_node_word(e + 2u));
                let ids = array_node_word(e + 3u);  // first_prim, mesh, node_base, tri_base
                bottom_node_base = ids.z;
                bottom_prim_base = ids.x;
                bottom_tri_base = ids.w;
                var local = Ray(affine_point(m0, m1, m2, r.origin), r.tmin,
                                affine_vector(m0, m1, m2, r.dir), r.tmax);
                if best.prim != MISS {
                    local.tmax = prune;
                }
                let h = traverse(local, any_hit);
                nodes += n_nodes;
                tris += n_tris;
                done = done && traversal_done;
                let prim = ids.x + h.prim;
                if h.prim != MISS && beats(h.t, prim, best.t, best.prim) {
                    best = Hit(h.t, prim, h.u, h.v);
                    prune = taken_prune;
                    finished = finished || any_hit;  // answered
                }
            }
            if finished {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
    }
    if COUNT_STATS {
        n_nodes = nodes;
        n_tris = tris;
    }
    traversal_done = traversal_done && done;
    return best;
}
