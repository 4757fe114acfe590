// cwbvh: the compressed 8-wide BVH of Ylitie, Karras & Laine 2017, octant-ordered traversal
// with a stack of node groups (cwbvh_node.wgsl's group_push), one ray per invocation. The CPU
// twin is twin.rs, step for step.

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        let parallel = any(abs(inv) >= vec3<f32>(PARALLEL_INV));
        let w = watertight_setup(r.dir);
        let oct_inv = cwbvh_octant_inv(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        group_count = 0u;
        // x: first child node; y: hit internal children (high byte) | imask. At the top of
        // the loop it always holds a node: first the root, alone in the top bit.
        var group = vec2<u32>(0u, 1u << 31u);
        loop {
            let node = cwbvh_load_node(cwbvh_take_child(group, oct_inv));
            if COUNT_STATS {
                n_nodes += 1u;
            }
            let hits = cwbvh_child_hits(node, r, inv, parallel, prune, oct_inv);
            group = cwbvh_group(node, hits);
            var tri_hits = hits & ~CWBVH_NODE_BITS;
            var stop = false;
            while tri_hits != 0u {
                let b = firstTrailingBit(tri_hits);
                tri_hits &= tri_hits - 1u;
                let tri = load_tri(node.tri_base + b);
                if COUNT_STATS {
                    n_tris += 1u;
                }
                // test_tri (traversal.wgsl), written out: calling it here, with pointers to
                // best and prune, measured 0.93x shadow rays/s on Mesa 25 lavapipe (7 rounds).
                let h = intersect_tri(tri.v0, tri.v1, tri.v2, r, w, r.tmin, best.t);
                if h.ok && beats(h.t, tri.prim, best.t, best.prim)
                    && !rejects_near_hit(h, tri.v0, tri.v1, tri.v2, r, w)
                    && alpha_passes(tri.prim, h) {
                    best = Hit(h.t, tri.prim, h.u, h.v);
                    prune = hit_prune(h);
                    if INSTANCES {
                        taken_prune = prune;
                    }
                    if any_hit {
                        stop = true;
                        break;
                    }
                }
            }
            if stop {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
            group = cwbvh_next_group(group);
            if group.y == 0u {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
    }
    return best;
}
