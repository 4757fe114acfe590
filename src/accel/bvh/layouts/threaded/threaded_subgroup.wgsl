// threaded, subgroup-coherent (TraversalMode::Subgroup): the lanes of a subgroup walk one
// copy of the tree together, one node a step at a subgroup-uniform index: two lanes fetch
// its two words (one load instruction), every live lane tests the box against its own ray,
// and the subgroup enters the node (the next node) when any lane hits it, else jumps to its
// skip index. A leaf entered by any lane has its triangles tested one a step, three lanes
// fetching each triangle's words; only the lanes that hit its box test them. Each lane keeps
// its own best hit with the per-ray tests, tie rule and pruning, so closest hits equal the
// per-ray kernel's bit for bit (the closest hit under the tie rule does not depend on the
// visiting order, so any copy serves every lane: the subgroup walks the copy of its first
// live lane's octant). An any-hit lane stops at its first hit; the subgroup stops when
// every lane has.
//
// Work counted per lane (COUNT_STATS): nodes and triangles its subgroup loaded and tested
// while the lane's ray was live, whether or not that ray entered them.

// Lanes a step reads by index (the three words of a triangle).
const THREADED_SG_LANES: u32 = 3u;

// Closest hit in [tmin, tmax], or with any_hit a hit; an invalid ray is a miss. Every lane
// of the subgroup calls it together (trace.wgsl).
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    let valid = ray_is_valid(r);
    // This lane still wants nodes (with any_hit: until its first hit).
    var live = valid;
    if !subgroup_start(valid, THREADED_SG_LANES) {
        return best;
    }
    let lane = subgroupExclusiveAdd(1u);
    let inv = safe_recip3(r.dir);
    let w = watertight_setup(r.dir);
    var prune = prune_bound(best.t);
    let root = dfs_load_node(0u);
    var n = 1u;
    if (root.b & 3u) != DFS_LEAF_TAG {
        n = root.a;
    }
    let mine = select(0u, 1u, r.dir.x < 0.0) | select(0u, 2u, r.dir.y < 0.0)
        | select(0u, 4u, r.dir.z < 0.0);
    // The first valid lane's octant (some lane is valid, above): the smallest key, lane in
    // the high bits.
    let octant = subgroupMin(select(0xffffffffu, 16u * lane + mine, valid)) & 15u;
    var idx = octant * n;
    let end = idx + n;
    loop {
        if idx >= end {
            traversal_end(bitcast<u32>(r.tmax));
            break;
        }
        let word = node_word(2u * idx + (lane & 1u));
        let node = dfs_node_from_words(subgroupBroadcast(word, 0u), subgroupBroadcast(word, 1u));
        if COUNT_STATS && live {
            n_nodes += 1u;
        }
        let hit = live && slab_hit(node.lo, node.hi, r.origin, inv, r.tmin, prune);
        let leaf = (node.b & 3u) == DFS_LEAF_TAG;
        if subgroupAny(hit) {
            if leaf {
                let first = node.a;
                let last = node.a + (node.b >> 2u);
                var in_leaf = hit;
                for (var t = first; t < last; t += 1u) {
                    let tw = tri_word(min(3u * t + lane, 3u * last - 1u));
                    let tri = tri_from_words(subgroupBroadcast(tw, 0u), subgroupBroadcast(tw, 1u),
                        subgroupBroadcast(tw, 2u));
                    if COUNT_STATS && live {
                        n_tris += 1u;
                    }
                    if in_leaf && test_tri(tri, r, w, &best, &prune) && any_hit {
                        live = false;
                        in_leaf = false;
                    }
                }
                if !subgroupAny(live) {
                    traversal_end(bitcast<u32>(r.tmax));
                    break;
                }
            }
            idx += 1u;
        } else if leaf {
            idx += 1u;
        } else {
            // Never backwards (as per ray).
            idx = max(node.a, idx + 1u);
        }
    }
    return best;
}

