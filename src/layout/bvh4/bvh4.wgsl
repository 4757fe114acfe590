// bvh4: 4-wide nodes, the used slots' boxes tested with the shared slab_interval, hit
// children visited nearest first, leaves through the shared test_leaf. The CPU twin is
// twin.rs, step for step. BVH4_INNER, BVH4_STACK_SIZE, BVH4_NODE_WORDS and BVH4_SLOT_BITS
// come from mod.rs.

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
    let b = BVH4_NODE_WORDS * i;
    return Bvh4Node(
        bitcast<vec4<f32>>(node_word(b)), bitcast<vec4<f32>>(node_word(b + 1u)),
        bitcast<vec4<f32>>(node_word(b + 2u)), bitcast<vec4<f32>>(node_word(b + 3u)),
        bitcast<vec4<f32>>(node_word(b + 4u)), bitcast<vec4<f32>>(node_word(b + 5u)),
        node_word(b + 6u), node_word(b + 7u));
}

// A pushed child: its node and slot (node << BVH4_SLOT_BITS | slot), the entry distance of
// its box.
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
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        var sp = 0u;
        var child = 0u;
        var kind = BVH4_INNER;
        let slots = vec4<u32>(0u, 1u, 2u, 3u);
        loop {
            var descended = false;
            if kind == BVH4_INNER {
                let index = child;
                let node = bvh4_load_node(index);
                if COUNT_STATS {
                    n_nodes += 1u;
                }
                // Used slots whose boxes the ray enters before the prune bound.
                var bits = 0u;
                var enter = vec4<f32>(0.0);
                for (var k = 0u; k < 4u; k += 1u) {
                    if node.kind[k] != 0u {
                        let lo = vec3<f32>(node.lo_x[k], node.lo_y[k], node.lo_z[k]);
                        let hi = vec3<f32>(node.hi_x[k], node.hi_y[k], node.hi_z[k]);
                        let i = slab_interval(lo, hi, r.origin, inv, r.tmin, prune);
                        enter[k] = i.x;
                        bits |= select(0u, 1u << k, i.x <= i.y);
                    }
                }
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
                            if ((bits >> j) & 1u) != 0u {
                                let ej = vec4<f32>(enter[j]);
                                let before = (ej < enter) | ((ej == enter) & (vec4<u32>(j) < slots));
                                rank += select(vec4<u32>(0u), vec4<u32>(1u), before);
                            }
                        }
                        // The nearest is visited next; the others pushed farthest first.
                        for (var k = 0u; k < 4u; k += 1u) {
                            if ((bits >> k) & 1u) != 0u {
                                if rank[k] == 0u {
                                    child = node.child[k];
                                    kind = node.kind[k];
                                } else {
                                    let e = Bvh4Entry((index << BVH4_SLOT_BITS) | k, enter[k]);
                                    bvh4_stack[sp + n - 1u - rank[k]] = e;
                                }
                            }
                        }
                        sp += n - 1u;
                    }
                }
            } else if test_leaf(child, kind, r, w, any_hit, &best, &prune) {
                // Answered: empty the stack, so the pop below ends the traversal.
                sp = 0u;
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
                        let at = BVH4_NODE_WORDS * (e.slot >> BVH4_SLOT_BITS);
                        let k = e.slot & ((1u << BVH4_SLOT_BITS) - 1u);
                        child = node_word(at + 6u)[k];
                        kind = node_word(at + 7u)[k];
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
