// bvh4: 4-wide nodes, the four child boxes tested at once, hit children visited nearest
// first. The CPU twin is twin.rs (slab test: slab4.rs), step for step. BVH4_INNER and
// BVH4_STACK_SIZE come from mod.rs's INNER and STACK_SIZE.

// Bvh4Node: slot k's box is (lo_x[k], lo_y[k], lo_z[k])-(hi_x[k], hi_y[k], hi_z[k]).
// kind[k]: BVH4_INNER (child[k] = node index), 0 (unused slot) or a leaf's triangle count
// (child[k] = first triangle).
struct Bvh4Node {
    lo_x: vec4<f32>,
    lo_y: vec4<f32>,
    lo_z: vec4<f32>,
    hi_x: vec4<f32>,
    hi_y: vec4<f32>,
    hi_z: vec4<f32>,
    child: vec4<u32>,
    kind: vec4<u32>,
}

fn bvh4_load_node(i: u32) -> Bvh4Node {
    let b = 8u * i;
    return Bvh4Node(
        bitcast<vec4<f32>>(node_word(b)), bitcast<vec4<f32>>(node_word(b + 1u)),
        bitcast<vec4<f32>>(node_word(b + 2u)), bitcast<vec4<f32>>(node_word(b + 3u)),
        bitcast<vec4<f32>>(node_word(b + 4u)), bitcast<vec4<f32>>(node_word(b + 5u)),
        node_word(b + 6u), node_word(b + 7u));
}

// One axis of slab_hit for four boxes: near and far distances, lane k for box k.
struct Bvh4Span {
    tn: vec4<f32>,
    tf: vec4<f32>,
}

fn bvh4_axis(lo: vec4<f32>, hi: vec4<f32>, o: f32, inv: f32) -> Bvh4Span {
    let ov = vec4<f32>(o);
    let t0 = (lo - ov) * inv;
    let t1 = (hi - ov) * inv;
    let parallel = abs(inv) >= PARALLEL_INV;
    let inside = (lo <= ov) & (ov <= hi);
    let big = select(vec4<f32>(-BIG), vec4<f32>(BIG), inside);
    let widen = select(1.0, FAR_WIDEN, ROBUST_SLAB);
    return Bvh4Span(select(min(t0, t1), -big, parallel), select(max(t0, t1) * widen, big, parallel));
}

// The four boxes against the ray: lane k does common.wgsl's slab_hit on box k, the same
// operations in the same order (twin: slab4.rs's slab_hit4).
struct Bvh4Slab {
    hit: vec4<bool>,
    enter: vec4<f32>,
}

fn bvh4_slab(n: Bvh4Node, origin: vec3<f32>, inv_dir: vec3<f32>, tmin: f32, tmax: f32) -> Bvh4Slab {
    let x = bvh4_axis(n.lo_x, n.hi_x, origin.x, inv_dir.x);
    let y = bvh4_axis(n.lo_y, n.hi_y, origin.y, inv_dir.y);
    let z = bvh4_axis(n.lo_z, n.hi_z, origin.z, inv_dir.z);
    let enter = max(max(max(x.tn, y.tn), z.tn), vec4<f32>(tmin));
    let exit = min(min(min(x.tf, y.tf), z.tf), vec4<f32>(tmax));
    return Bvh4Slab(enter <= exit, enter);
}

// A pushed child: its node and slot (node << 2 | slot), the entry distance of its box.
struct Bvh4Entry {
    slot: u32,
    enter: f32,
}

// The traversal stack: per invocation, not per traverse() call (WGSL zeroes a function's
// variables at every call).
var<private> bvh4_stack: array<Bvh4Entry, BVH4_STACK_SIZE>;

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    traversal_done = !ray_is_valid(r);
    if COUNT_STATS {
        n_nodes = 0u;
        n_tris = 0u;
    }
    if ray_is_valid(r) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        var sp = 0u;
        var child = 0u;
        var kind = BVH4_INNER;
        loop {
            var descended = false;
            if kind == BVH4_INNER {
                let index = child;
                let node = bvh4_load_node(index);
                if COUNT_STATS {
                    n_nodes += 1u;
                }
                let s = bvh4_slab(node, r.origin, inv, r.tmin, prune);
                let hit = s.hit & (node.kind != vec4<u32>(0u));
                let bits = dot(select(vec4<u32>(0u), vec4<u32>(1u, 2u, 4u, 8u), hit), vec4<u32>(1u));
                if bits != 0u {
                    descended = true;
                    let n = countOneBits(bits);
                    if n == 1u {
                        let k = firstTrailingBit(bits);
                        child = node.child[k];
                        kind = node.kind[k];
                    } else {
                        // rank[k]: hit children before slot k by (entry distance, slot).
                        var rank = vec4<u32>(0u);
                        for (var j = 0u; j < 4u; j += 1u) {
                            let ej = vec4<f32>(s.enter[j]);
                            let before = (ej < s.enter) | ((ej == s.enter) & (vec4<u32>(j) < vec4<u32>(0u, 1u, 2u, 3u)));
                            rank += select(vec4<u32>(0u), vec4<u32>(1u), before & vec4<bool>(hit[j]));
                        }
                        // The nearest is visited next; the others pushed farthest first.
                        for (var k = 0u; k < 4u; k += 1u) {
                            if hit[k] {
                                if rank[k] == 0u {
                                    child = node.child[k];
                                    kind = node.kind[k];
                                } else {
                                    bvh4_stack[sp + n - 1u - rank[k]] = Bvh4Entry(index << 2u | k, s.enter[k]);
                                }
                            }
                        }
                        sp += n - 1u;
                    }
                }
            } else {
                let end = child + kind;
                for (var i = child; i < end; i += 1u) {
                    let tri = load_tri(i);
                    if COUNT_STATS {
                        n_tris += 1u;
                    }
                    let h = intersect_tri(tri.v0, tri.v1, tri.v2, r, w, r.tmin, best.t);
                    if h.ok && beats(h.t, tri.prim, best.t, best.prim)
                        && !(REJECT_NEAR_HITS && maybe_behind_origin(h)) {
                        best = Hit(h.t, tri.prim, h.u, h.v);
                        prune = hit_prune(h);
                        if any_hit {
                            // Empty the stack: the pop below ends the traversal.
                            sp = 0u;
                            break;
                        }
                    }
                }
            }
            if !descended {
                // The nearest entry whose box is still entered before the prune bound (the
                // slab test again with the new bound: only its tmax changed).
                var popped = false;
                loop {
                    if sp == 0u {
                        break;
                    }
                    sp -= 1u;
                    let e = bvh4_stack[sp];
                    if e.enter <= prune {
                        // The child and kind words of the pushed slot's node.
                        let at = 8u * (e.slot >> 2u);
                        child = node_word(at + 6u)[e.slot & 3u];
                        kind = node_word(at + 7u)[e.slot & 3u];
                        popped = true;
                        break;
                    }
                }
                if !popped {
                    traversal_done = true;
                    break;
                }
            }
        }
    }
    return best;
}
