// bvh4 and bvh8: W-wide nodes (W = WIDE_WIDTH, 4 or 8), the used slots' boxes tested with
// the shared slab_interval, hit children visited nearest first, leaves through the shared
// test_leaf. The CPU twin is twin.rs, step for step. WIDE_INNER, WIDE_WIDTH, WIDE_GROUPS
// (W / 4), WIDE_STACK_SIZE, WIDE_NODE_WORDS and WIDE_SLOT_BITS come from mod.rs.
//
// A node is 2·W words of four slots each: the planes lo_x, lo_y, lo_z, hi_x, hi_y, hi_z,
// then child and kind, each WIDE_GROUPS words long. kind: WIDE_INNER (child = node index),
// 0 (unused slot) or a leaf's triangle count (child = first triangle). A node's slots are
// held in WideGroups of four, never in an array: lavapipe keeps an array indexed by a loop
// variable in memory, element by element and lane by lane (with the node, the entries and
// the ranks in arrays, Mesa 22 ran bvh8's bunny primary rays at 0.61 Mrays/s, 5.78 now).

// Four slots of a node: their entry distances, which of them the ray enters (bits 0–3),
// their children and kinds.
struct WideGroup {
    enter: vec4<f32>,
    bits: u32,
    child: vec4<u32>,
    kind: vec4<u32>,
}

// Slots 4g..4g+3 of the node at word `at`, tested against the ray (used slots whose boxes
// it enters before `prune`).
fn wide_group(at: u32, g: u32, r: Ray, inv: vec3<f32>, prune: f32) -> WideGroup {
    let lo_x = bitcast<vec4<f32>>(node_word(at + g));
    let lo_y = bitcast<vec4<f32>>(node_word(at + WIDE_GROUPS + g));
    let lo_z = bitcast<vec4<f32>>(node_word(at + 2u * WIDE_GROUPS + g));
    let hi_x = bitcast<vec4<f32>>(node_word(at + 3u * WIDE_GROUPS + g));
    let hi_y = bitcast<vec4<f32>>(node_word(at + 4u * WIDE_GROUPS + g));
    let hi_z = bitcast<vec4<f32>>(node_word(at + 5u * WIDE_GROUPS + g));
    var q = WideGroup(vec4<f32>(0.0), 0u, node_word(at + 6u * WIDE_GROUPS + g),
        node_word(at + 7u * WIDE_GROUPS + g));
    for (var l = 0u; l < 4u; l += 1u) {
        if q.kind[l] != 0u {
            let lo = vec3<f32>(lo_x[l], lo_y[l], lo_z[l]);
            let hi = vec3<f32>(hi_x[l], hi_y[l], hi_z[l]);
            let i = slab_interval(lo, hi, r.origin, inv, r.tmin, prune);
            q.enter[l] = i.x;
            q.bits |= select(0u, 1u << l, i.x <= i.y);
        }
    }
    return q;
}

// How many entered slots of `bits` (entry distances e0 for slots 0–3, e1 for 4–7) come
// before each slot of group `g` (slots 4g..4g+3, entry distances `e`) by (entry distance,
// slot).
fn wide_ranks(bits: u32, e0: vec4<f32>, e1: vec4<f32>, g: u32, e: vec4<f32>) -> vec4<u32> {
    var rank = vec4<u32>(0u);
    let slots = vec4<u32>(0u, 1u, 2u, 3u) + vec4<u32>(4u * g);
    for (var j = 0u; j < WIDE_WIDTH; j += 1u) {
        if ((bits >> j) & 1u) != 0u {
            let ej = vec4<f32>(select(e1[j & 3u], e0[j & 3u], j < 4u));
            let before = (ej < e) | ((ej == e) & (vec4<u32>(j) < slots));
            rank += select(vec4<u32>(0u), vec4<u32>(1u), before);
        }
    }
    return rank;
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
        loop {
            var descended = false;
            if kind == WIDE_INNER {
                let index = child;
                let at = WIDE_NODE_WORDS * index;
                if COUNT_STATS {
                    n_nodes += 1u;
                }
                // Used slots whose boxes the ray enters before the prune bound.
                let q0 = wide_group(at, 0u, r, inv, prune);
                var q1 = WideGroup(vec4<f32>(0.0), 0u, vec4<u32>(0u), vec4<u32>(0u));
                if WIDE_GROUPS > 1u {
                    q1 = wide_group(at, 1u, r, inv, prune);
                }
                let bits = q0.bits | (q1.bits << 4u);
                if bits != 0u {
                    descended = true;
                    let n = countOneBits(bits);
                    if n == 1u {
                        let k = firstTrailingBit(bits);
                        let l = k & 3u;
                        child = select(q1.child[l], q0.child[l], k < 4u);
                        kind = select(q1.kind[l], q0.kind[l], k < 4u);
                    } else {
                        // rank: hit children before a slot by (entry distance, slot).
                        let rank0 = wide_ranks(bits, q0.enter, q1.enter, 0u, q0.enter);
                        var rank1 = vec4<u32>(0u);
                        if WIDE_GROUPS > 1u {
                            rank1 = wide_ranks(bits, q0.enter, q1.enter, 1u, q1.enter);
                        }
                        // The nearest is visited next; the others pushed farthest first.
                        for (var k = 0u; k < WIDE_WIDTH; k += 1u) {
                            if ((bits >> k) & 1u) != 0u {
                                let l = k & 3u;
                                let low = k < 4u;
                                let rk = select(rank1[l], rank0[l], low);
                                if rk == 0u {
                                    child = select(q1.child[l], q0.child[l], low);
                                    kind = select(q1.kind[l], q0.kind[l], low);
                                } else {
                                    let ek = select(q1.enter[l], q0.enter[l], low);
                                    let e = WideEntry((index << WIDE_SLOT_BITS) | k, ek);
                                    wide_stack[sp + n - 1u - rk] = e;
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
                    // The stack is empty, or the driver cut this loop (traversal_end).
                    traversal_end(bitcast<u32>(r.tmax));
                    break;
                }
            }
        }
    }
    return best;
}
