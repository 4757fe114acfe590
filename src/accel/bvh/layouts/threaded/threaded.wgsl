// threaded: eight copies of the dfs-sign tree in dfs_node.wgsl's 32-byte nodes, one per
// ray octant, each in the order dfs-sign visits it for that octant's rays; an inner node's
// `a` is its skip index (the node after its subtree). No stack: a hit inner node or any leaf
// goes on to the next node, a missed inner node to its skip index. The CPU twin is twin.rs,
// step for step (mod.rs: octant()).
//
// The loop is split in two (Aila & Laine's while-while): a lane walks nodes until it enters a
// leaf or ends, and once every lane has, the lanes holding a leaf test it together. Each
// lane's own sequence of steps is the single loop's, so hits and work are the twin's; but a
// SIMD driver runs the triangle test once for all the lanes at a leaf instead of once per
// lane that meets one. On this project's machine: 1.1-1.2x the rays/s of the single loop on
// Mesa 25 lavapipe, 1.8x on Mesa 22 (which runs both sides of every branch).

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if traversal_start(ray_is_valid(r)) {
        let inv = safe_recip3(r.dir);
        let w = watertight_setup(r.dir);
        // Boxes are cut against the best t plus a few ulps (prune_bound, as the twin does).
        var prune = prune_bound(best.t);
        // A copy's length: copy 0's root skips to the end of copy 0 (a leaf root: 1 node).
        let root = dfs_load_node(0u);
        var n = 1u;
        if (root.b & 3u) != DFS_LEAF_TAG {
            n = root.a;
        }
        let octant = select(0u, 1u, r.dir.x < 0.0) | select(0u, 2u, r.dir.y < 0.0)
            | select(0u, 4u, r.dir.z < 0.0);
        var idx = octant * n;
        let end = idx + n;
        // While-while (Aila & Laine 2009): each lane walks until it enters a leaf or ends,
        // then the lanes with a leaf test it together.
        loop {
            var has_leaf = false;
            var first = 0u;
            var count = 0u;
            loop {
                if idx >= end {
                    break;
                }
                let node = dfs_load_node(idx);
                if COUNT_STATS {
                    n_nodes += 1u;
                }
                let leaf = (node.b & 3u) == DFS_LEAF_TAG;
                var next = idx + 1u;
                if slab_hit(node.lo, node.hi, r.origin, inv, r.tmin, prune) {
                    if leaf {
                        has_leaf = true;
                        first = node.a;
                        count = node.b >> 2u;
                    }
                } else if !leaf {
                    // Never backwards (validate() ensures it; this keeps a corrupt array
                    // from looping).
                    next = max(node.a, idx + 1u);
                }
                idx = next;
                if has_leaf {
                    break;
                }
            }
            if has_leaf && test_leaf(first, count, r, w, any_hit, &best, &prune) {
                // Answered: the traversal ends.
                idx = end;
            }
            if idx >= end {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
    }
    return best;
}
