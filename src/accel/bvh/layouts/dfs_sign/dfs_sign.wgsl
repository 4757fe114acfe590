// dfs-sign: 32-byte nodes in depth-first order (dfs_node.wgsl), near child by the ray's sign
// on the split axis. The CPU twin is twin.rs, step for step.

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        var stack: array<u32, STACK_SIZE>;
        var sp = 0u;
        var idx = 0u;
        loop {
            let node = dfs_load_node(idx);
            if COUNT_STATS {
                n_nodes += 1u;
            }
            var descended = false;
            if slab_hit(node.lo, node.hi, r.origin, inv, r.tmin, prune) {
                if (node.b & 3u) != DFS_LEAF_TAG {
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
                } else if test_leaf(node.a, node.b >> 2u, r, w, any_hit, &best, &prune) {
                    // Answered: empty the stack, the pop below ends the traversal.
                    sp = 0u;
                }
            }
            if !descended {
                if sp == 0u {
                    traversal_end(bitcast<u32>(r.tmax));
                    break;
                }
                sp -= 1u;
                idx = stack[sp];
            }
        }
    }
    return best;
}
