// kdtree: the SAH kd-tree's own arrays (src/accel/kdtree): 8-byte nodes two to a 16-byte word,
// the leaves' triangles one LeafTri per reference. Front to back with a stack of pending far
// children and the ray's interval in each. The CPU twin is KdTree::walk in traverse.rs, step
// for step: same operations in the same order, so hits and statistics agree bit for bit.
// KD_LEAF_TAG, KD_BELOW_EMPTY, KD_ABOVE_EMPTY, KD_ABOVE_SHIFT, KD_COUNT_SHIFT, KD_MAILBOX and
// PLANE_STACK_SIZE (MAX_KD_DEPTH) are generated in front from their Rust definitions (gpu.rs),
// followed by plane_ray.wgsl (the root cell KdTree::bounds in its overrides, the ray, the
// stack's entries).

// The mailbox is two vec4<u32> (no loop: lavapipe caps the loop iterations of a ray).
const_assert KD_MAILBOX == 8u;

// kdtree::Node. Inner: a = the split position's bits, b = above child << KD_ABOVE_SHIFT |
// KD_ABOVE_EMPTY | KD_BELOW_EMPTY | axis (the child below is the next node).
// Leaf: a = first triangle, b = count << KD_COUNT_SHIFT | KD_LEAF_TAG.
struct KdNode {
    a: u32,
    b: u32,
}

// Node i: the low or high half of word i / 2.
fn kd_load_node(i: u32) -> KdNode {
    let w = node_word(i >> 1u);
    let h = select(w.xy, w.zw, (i & 1u) != 0u);
    return KdNode(h.x, h.y);
}

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    traversal_done = true;
    if COUNT_STATS {
        n_nodes = 0u;
        n_tris = 0u;
    }
    // An empty tree is a single empty leaf (count 0: its tagged word is the tag).
    if !ray_is_valid(r) || kd_load_node(0u).b == KD_LEAF_TAG {
        return best;
    }
    // Distances t' = t / 2^k along the direction scaled by 2^k (largest component in [1, 2)).
    let pr = plane_ray(r);
    // [lo, hi]: the ray's widened interval in the current cell.
    let cell_lo = vec3<f32>(PLANE_LO_X, PLANE_LO_Y, PLANE_LO_Z);
    let cell_hi = vec3<f32>(PLANE_HI_X, PLANE_HI_Y, PLANE_HI_Z);
    let root_interval = plane_root_interval(pr, cell_lo, cell_hi);
    if root_interval.z == 0.0 {
        if COUNT_STATS {
            n_nodes = 1u;
        }
        return best;
    }
    traversal_done = false;
    var lo = root_interval.x;
    var hi = root_interval.y;
    let w = watertight_setup(r.dir);
    var prune = pr.tmax;
    var stack: array<PlanePending, PLANE_STACK_SIZE>;
    var sp = 0u;
    var idx = 0u;
    var mail_lo = vec4<u32>(MISS);
    var mail_hi = vec4<u32>(MISS);
    var slot = 0u;
    loop {
        let node = kd_load_node(idx);
        if COUNT_STATS {
            n_nodes += 1u;
        }
        if (node.b & 3u) != KD_LEAF_TAG {
            let ax = node.b & 3u;
            let s = bitcast<f32>(node.a);
            let below = idx + 1u;
            let above = node.b >> KD_ABOVE_SHIFT;
            let below_empty = (node.b & KD_BELOW_EMPTY) != 0u;
            let above_empty = (node.b & KD_ABOVE_EMPTY) != 0u;
            let o = pr.o[ax];
            let inv = pr.inv[ax];
            let fwd = inv > 0.0;
            let near = select(above, below, fwd);
            let far = select(below, above, fwd);
            let near_empty = select(above_empty, below_empty, fwd);
            let far_empty = select(below_empty, above_empty, fwd);
            // Parallel to the split axis: the origin's side decides, the interval stays.
            var reach_near: bool;
            var reach_far: bool;
            var dl = lo;
            var dh = hi;
            if plane_parallel(pr, ax) {
                let on_below = o <= s;
                let on_above = o >= s;
                reach_near = select(on_above, on_below, fwd);
                reach_far = select(on_below, on_above, fwd);
            } else {
                let d = finite((s - o) * inv);
                reach_near = d >= lo;
                reach_far = d <= hi;
                dl = widen_lo(d);
                dh = widen_hi(d);
            }
            let visit_near = reach_near && !near_empty;
            let visit_far = reach_far && !far_empty;
            if visit_near {
                if visit_far {
                    stack[sp] = PlanePending(far, select(lo, dl, dl > lo), hi);
                    sp += 1u;
                    if dh < hi {
                        hi = dh;
                    }
                }
                idx = near;
                continue;
            }
            if visit_far {
                if dl > lo {
                    lo = dl;
                }
                idx = far;
                continue;
            }
        } else {
            let end = node.a + (node.b >> KD_COUNT_SHIFT);
            var any_found = false;
            for (var i = node.a; i < end; i += 1u) {
                let tri = load_tri(i);
                let p = vec4<u32>(tri.prim);
                if any(mail_lo == p) || any(mail_hi == p) {
                    continue;
                }
                if slot < 4u {
                    mail_lo[slot] = tri.prim;
                } else {
                    mail_hi[slot - 4u] = tri.prim;
                }
                slot = (slot + 1u) % KD_MAILBOX;
                if COUNT_STATS {
                    n_tris += 1u;
                }
                let h = intersect_tri(tri.v0, tri.v1, tri.v2, r, w, r.tmin, best.t);
                if h.ok && beats(h.t, tri.prim, best.t, best.prim)
                    && !rejects_near_hit(h, tri.v0, tri.v1, tri.v2, r, w)
                    && alpha_passes(tri.prim, h) {
                    best = Hit(h.t, tri.prim, h.u, h.v);
                    if any_hit {
                        any_found = true;
                        break;
                    }
                    prune = plane_scaled(pr, hit_prune(h));
                }
            }
            if any_found {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
        // Next: the nearest pending node whose entry is not beyond the best hit.
        var popped = false;
        loop {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            let next = stack[sp];
            if next.lo <= prune {
                idx = next.node;
                lo = next.lo;
                hi = next.hi;
                popped = true;
                break;
            }
        }
        if !popped {
            traversal_end(bitcast<u32>(r.tmax));
            break;
        }
    }
    return best;
}
