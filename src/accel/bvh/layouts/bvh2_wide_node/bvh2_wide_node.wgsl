// bvh2-wide-node (Aila & Laine 2009): 64-byte records holding both children's boxes and
// references; both boxes tested per visit, the hit children visited nearest first, the far
// one pushed. The CPU twin is twin.rs, step for step. BVH2_WIDE_LEAF_TAG,
// BVH2_WIDE_COUNT_SHIFT and BVH2_WIDE_RECORD_WORDS come from mod.rs.

// One record: child 0's box and reference (a0, b0), then child 1's. A reference is a leaf
// when b & BVH2_WIDE_LEAF_TAG: a = first tri, b >> BVH2_WIDE_COUNT_SHIFT = count; otherwise
// a = the child's record. Record 0 is the header: the root's box and reference in slot 0.
struct Bvh2WideNodeRecord {
    lo0: vec3<f32>,
    a0: u32,
    hi0: vec3<f32>,
    b0: u32,
    lo1: vec3<f32>,
    a1: u32,
    hi1: vec3<f32>,
    b1: u32,
}

fn bvh2_wide_load(i: u32) -> Bvh2WideNodeRecord {
    let base = BVH2_WIDE_RECORD_WORDS * i;
    let a = node_word(base);
    let b = node_word(base + 1u);
    let c = node_word(base + 2u);
    let d = node_word(base + 3u);
    return Bvh2WideNodeRecord(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w,
                              bitcast<vec3<f32>>(c.xyz), c.w, bitcast<vec3<f32>>(d.xyz), d.w);
}

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        // The root box, once, from the header's slot 0 (its first two words).
        let h0 = node_word(0u);
        let h1 = node_word(1u);
        if COUNT_STATS {
            n_nodes += 1u;
        }
        if !slab_hit(bitcast<vec3<f32>>(h0.xyz), bitcast<vec3<f32>>(h1.xyz), r.origin, inv, r.tmin, prune) {
            traversal_end(bitcast<u32>(r.tmax));
        } else {
            // Stack entries are references; at most one per level (mod.rs: the stack bound).
            var stack: array<vec2<u32>, STACK_SIZE>;
            var sp = 0u;
            var cur = vec2<u32>(h0.w, h1.w);
            loop {
                var next = false;
                if (cur.y & BVH2_WIDE_LEAF_TAG) == BVH2_WIDE_LEAF_TAG {
                    if test_leaf(cur.x, cur.y >> BVH2_WIDE_COUNT_SHIFT, r, w, any_hit, &best, &prune) {
                        // Answered: empty the stack, the pop below ends the traversal.
                        sp = 0u;
                    }
                } else {
                    let node = bvh2_wide_load(cur.x);
                    if COUNT_STATS {
                        n_nodes += 1u;
                    }
                    let i0 = slab_interval(node.lo0, node.hi0, r.origin, inv, r.tmin, prune);
                    let i1 = slab_interval(node.lo1, node.hi1, r.origin, inv, r.tmin, prune);
                    let hit0 = i0.x <= i0.y;
                    let hit1 = i1.x <= i1.y;
                    let c0 = vec2<u32>(node.a0, node.b0);
                    let c1 = vec2<u32>(node.a1, node.b1);
                    if hit0 && hit1 {
                        // Nearer entry first; equal entries: child 0 first.
                        var near = c0;
                        var far = c1;
                        if i1.x < i0.x {
                            near = c1;
                            far = c0;
                        }
                        stack[sp] = far;
                        sp += 1u;
                        cur = near;
                        next = true;
                    } else if hit0 {
                        cur = c0;
                        next = true;
                    } else if hit1 {
                        cur = c1;
                        next = true;
                    }
                }
                if !next {
                    if sp == 0u {
                        traversal_end(bitcast<u32>(r.tmax));
                        break;
                    }
                    sp -= 1u;
                    cur = stack[sp];
                }
            }
        }
    }
    return best;
}
