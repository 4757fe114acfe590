// The flat BVH and its traversal (trace::cpu::trace_ray), shared by every kernel that
// traces rays: the trace kernel (traverse.wgsl) and the renderer (render.wgsl).

override COUNT_STATS: bool = false;      // count nodes visited / triangles tested
override MOLLER_TRUMBORE: bool = false;  // TriangleTest::MollerTrumbore instead of watertight

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> tris: array<Tri>;

// Work done by the last traverse() call (read when COUNT_STATS).
var<private> n_nodes: u32;
var<private> n_tris: u32;

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if COUNT_STATS {
        n_nodes = 0u;
        n_tris = 0u;
    }
    if ray_is_valid(r) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        var stack: array<u32, STACK_SIZE>;
        var sp = 0u;
        var idx = 0u;
        loop {
            let node = nodes[idx];
            if COUNT_STATS {
                n_nodes += 1u;
            }
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
                        if COUNT_STATS {
                            n_tris += 1u;
                        }
                        var h: TriHit;
                        if MOLLER_TRUMBORE {
                            h = intersect_moller_trumbore(tri, r, r.tmin, best.t);
                        } else {
                            h = intersect_watertight(tri, r.origin, w, r.tmin, best.t);
                        }
                        if h.ok && beats(h.t, tri.prim, best.t, best.prim) {
                            best = Hit(h.t, tri.prim, h.u, h.v);
                            if any_hit {
                                // Empty the stack: the pop below ends the traversal.
                                sp = 0u;
                                break;
                            }
                        }
                    }
                }
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
    return best;
}
