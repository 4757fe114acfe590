// bvh4 and bvh8: W-wide nodes (W = WIDE_WIDTH), the used slots' boxes tested with the
// shared slab_interval, hit children visited nearest first, leaves through the shared
// test_leaf. The CPU twin is twin.rs, step for step. WIDE_INNER, WIDE_WIDTH, WIDE_GROUPS
// (W / 4), WIDE_STACK_SIZE, WIDE_NODE_WORDS and WIDE_SLOT_BITS come from mod.rs.

// WideNode: slot k's box is (lo_x, lo_y, lo_z)-(hi_x, hi_y, hi_z) at [k / 4][k % 4].
// kind: WIDE_INNER (child = node index), 0 (unused slot) or a leaf's triangle count
// (child = first triangle).
struct WideNode {
    lo_x: array<vec4<f32>, WIDE_GROUPS>,
    lo_y: array<vec4<f32>, WIDE_GROUPS>,
    lo_z: array<vec4<f32>, WIDE_GROUPS>,
    hi_x: array<vec4<f32>, WIDE_GROUPS>,
    hi_y: array<vec4<f32>, WIDE_GROUPS>,
    hi_z: array<vec4<f32>, WIDE_GROUPS>,
    child: array<vec4<u32>, WIDE_GROUPS>,
    kind: array<vec4<u32>, WIDE_GROUPS>,
}

fn wide_load_node(i: u32) -> WideNode {
    let b = WIDE_NODE_WORDS * i;
    var n: WideNode;
    for (var g = 0u; g < WIDE_GROUPS; g += 1u) {
        n.lo_x[g] = bitcast<vec4<f32>>(node_word(b + g));
        n.lo_y[g] = bitcast<vec4<f32>>(node_word(b + WIDE_GROUPS + g));
        n.lo_z[g] = bitcast<vec4<f32>>(node_word(b + 2u * WIDE_GROUPS + g));
        n.hi_x[g] = bitcast<vec4<f32>>(node_word(b + 3u * WIDE_GROUPS + g));
        n.hi_y[g] = bitcast<vec4<f32>>(node_word(b + 4u * WIDE_GROUPS + g));
        n.hi_z[g] = bitcast<vec4<f32>>(node_word(b + 5u * WIDE_GROUPS + g));
        n.child[g] = node_word(b + 6u * WIDE_GROUPS + g);
        n.kind[g] = node_word(b + 7u * WIDE_GROUPS + g);
    }
    return n;
}

// A pushed child: its node and slot (node << WIDE_SLOT_BITS | slot), the entry distance of
// its box.
struct WideEntry {
    slot: u32,
    enter: f32,
}

// The traversal stack: per invocation, not per traverse() call (WGSL zeroes a function's
// variables at every call); W − 1 entries for each level of this tree (mod.rs, `depth`).
var<private> wide_stack: array<WideEntry, WIDE_STACK_SIZE>;

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
        var kind = WIDE_INNER;
        let slots = vec4<u32>(0u, 1u, 2u, 3u);
        loop {
            var descended = false;
            if kind == WIDE_INNER {
                let index = child;
                let node = wide_load_node(index);
                if COUNT_STATS {
                    n_nodes += 1u;
                }
                // Used slots whose boxes the ray enters before the prune bound.
                var bits = 0u;
                var enter: array<vec4<f32>, WIDE_GROUPS>;
                for (var g = 0u; g < WIDE_GROUPS; g += 1u) {
                    var e = vec4<f32>(0.0);
                    for (var l = 0u; l < 4u; l += 1u) {
                        if node.kind[g][l] != 0u {
                            let lo = vec3<f32>(node.lo_x[g][l], node.lo_y[g][l], node.lo_z[g][l]);
                            let hi = vec3<f32>(node.hi_x[g][l], node.hi_y[g][l], node.hi_z[g][l]);
                            let i = slab_interval(lo, hi, r.origin, inv, r.tmin, prune);
                            e[l] = i.x;
                            bits |= select(0u, 1u << (4u * g + l), i.x <= i.y);
                        }
                    }
                    enter[g] = e;
                }
                if bits != 0u {
                    descended = true;
                    let n = countOneBits(bits);
                    if n == 1u {
                        let k = firstTrailingBit(bits);
                        child = node.child[k >> 2u][k & 3u];
                        kind = node.kind[k >> 2u][k & 3u];
                    } else {
                        // rank[k]: hit children before slot k by (entry distance, slot).
                        var rank: array<vec4<u32>, WIDE_GROUPS>;
                        for (var gj = 0u; gj < WIDE_GROUPS; gj += 1u) {
                            let ejs = enter[gj];
                            for (var lj = 0u; lj < 4u; lj += 1u) {
                                let j = 4u * gj + lj;
                                if ((bits >> j) & 1u) != 0u {
                                    let ej = vec4<f32>(ejs[lj]);
                                    for (var g = 0u; g < WIDE_GROUPS; g += 1u) {
                                        let e = enter[g];
                                        let earlier = vec4<u32>(j) < slots + vec4<u32>(4u * g);
                                        let before = (ej < e) | ((ej == e) & earlier);
                                        rank[g] += select(vec4<u32>(0u), vec4<u32>(1u), before);
                                    }
                                }
                            }
                        }
                        // The nearest is visited next; the others pushed farthest first.
                        for (var g = 0u; g < WIDE_GROUPS; g += 1u) {
                            let rg = rank[g];
                            let eg = enter[g];
                            for (var l = 0u; l < 4u; l += 1u) {
                                let k = 4u * g + l;
                                if ((bits >> k) & 1u) != 0u {
                                    if rg[l] == 0u {
                                        child = node.child[g][l];
                                        kind = node.kind[g][l];
                                    } else {
                                        let e = WideEntry((index << WIDE_SLOT_BITS) | k, eg[l]);
                                        wide_stack[sp + n - 1u - rg[l]] = e;
                                    }
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
                    let e = wide_stack[sp];
                    if e.enter <= prune {
                        // The child and kind words of the pushed slot's node.
                        let at = WIDE_NODE_WORDS * (e.slot >> WIDE_SLOT_BITS);
                        let k = e.slot & ((1u << WIDE_SLOT_BITS) - 1u);
                        let word = at + (k >> 2u);
                        child = node_word(word + 6u * WIDE_GROUPS)[k & 3u];
                        kind = node_word(word + 7u * WIDE_GROUPS)[k & 3u];
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
