// dfs-distance: the dfs nodes (dfs_node.wgsl) visited nearest child first by entry distance;
// the farther hit child is pushed with its entry distance and culled on the pop once the best
// hit is closer. The CPU twin is twin.rs, step for step.

// Node i, counted as one node load.
fn dfs_distance_load(i: u32) -> DfsNode {
    if COUNT_STATS {
        n_nodes += 1u;
    }
    return dfs_load_node(i);
}

// Closest hit in [tmin, tmax], or with any_hit the first hit met in traversal order.
// An invalid ray (NaN, zero direction, empty interval) is a miss.
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    if !traversal_start(ray_is_valid(r)) {
        return best;
    }
    let inv = safe_recip3(r.dir);
    let w = watertight_setup(r.dir);
    var prune = prune_bound(best.t);
    var node = dfs_distance_load(0u);
    let root = slab_interval(node.lo, node.hi, r.origin, inv, r.tmin, prune);
    if !(root.x <= root.y) {
        traversal_end(bitcast<u32>(r.tmax));
        return best;
    }
    var stack_node: array<u32, STACK_SIZE>;
    var stack_enter: array<f32, STACK_SIZE>;
    var sp = 0u;
    var node_index = 0u;
    loop {
        var descended = false;
        if (node.b & 3u) != DFS_LEAF_TAG {
            // The first child follows its parent: its index travels with the node.
            let a = node_index + 1u;
            let b = node.a;
            let na = dfs_distance_load(a);
            let nb = dfs_distance_load(b);
            let ia = slab_interval(na.lo, na.hi, r.origin, inv, r.tmin, prune);
            let ib = slab_interval(nb.lo, nb.hi, r.origin, inv, r.tmin, prune);
            let hit_a = ia.x <= ia.y;
            let hit_b = ib.x <= ib.y;
            if hit_a && hit_b {
                // Equal entries: the first child first.
                var far = b;
                var far_enter = ib.x;
                node_index = a;
                node = na;
                if ib.x < ia.x {
                    far = a;
                    far_enter = ia.x;
                    node_index = b;
                    node = nb;
                }
                stack_node[sp] = far;
                stack_enter[sp] = far_enter;
                sp += 1u;
                descended = true;
            } else if hit_a {
                node_index = a;
                node = na;
                descended = true;
            } else if hit_b {
                node_index = b;
                node = nb;
                descended = true;
            }
        } else if test_leaf(node.a, node.b >> 2u, r, w, any_hit, &best, &prune) {
            traversal_end(bitcast<u32>(r.tmax));
            break;
        }
        if !descended {
            // Pop the next child whose box the ray enters before the best hit (with slack).
            var found = false;
            while sp > 0u {
                sp -= 1u;
                if stack_enter[sp] <= prune {
                    node_index = stack_node[sp];
                    node = dfs_distance_load(node_index);
                    found = true;
                    break;
                }
            }
            if !found {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
    }
    return best;
}
