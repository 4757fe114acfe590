// The flat BVH and its traversal (trace::cpu::trace_ray), shared by every kernel that
// traces rays: the trace kernel (traverse.wgsl) and the renderer (render.wgsl).

override COUNT_STATS: bool = false;      // count nodes visited / triangles tested
override MOLLER_TRUMBORE: bool = false;  // TriangleTest::MollerTrumbore instead of watertight

// Node and Tri arrays, read as 16-byte words. lavapipe compiles every storage-buffer load
// into a loop over the SIMD lanes, one loop per load instruction: two vec4 loads per node
// instead of one per field (lo, a, hi, b) is ~15% more rays/s there. load_node/load_tri
// follow the offsets that tests/layout.rs checks.
//
// The same words live either in storage buffers or, with BVH_TEXTURES (gpu::BvhMemory), in
// read-only rgba32uint storage textures of TEXEL_ROW texels a row, which lavapipe loads with
// a gather (~18% more rays/s). Both pairs are declared; the unused pair is a placeholder.
override BVH_TEXTURES: bool = false;
const TEXEL_ROW: u32 = 4096u;  // gpu::TEXEL_ROW
@group(0) @binding(0) var<storage, read> node_words: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read> tri_words: array<vec4<u32>>;
@group(0) @binding(10) var node_texels: texture_storage_2d<rgba32uint, read>;
@group(0) @binding(11) var tri_texels: texture_storage_2d<rgba32uint, read>;

fn node_word(i: u32) -> vec4<u32> {
    if BVH_TEXTURES {
        return textureLoad(node_texels, vec2<u32>(i % TEXEL_ROW, i / TEXEL_ROW));
    }
    return node_words[i];
}

fn tri_word(i: u32) -> vec4<u32> {
    if BVH_TEXTURES {
        return textureLoad(tri_texels, vec2<u32>(i % TEXEL_ROW, i / TEXEL_ROW));
    }
    return tri_words[i];
}

fn load_node(i: u32) -> Node {
    let a = node_word(2u * i);
    let b = node_word(2u * i + 1u);
    return Node(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w);
}

fn load_tri(i: u32) -> Tri {
    let a = tri_word(3u * i);
    let b = tri_word(3u * i + 1u);
    let c = tri_word(3u * i + 2u);
    return Tri(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w,
               bitcast<vec3<f32>>(c.xyz), c.w);
}

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
            let node = load_node(idx);
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
                        let tri = load_tri(i);
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
