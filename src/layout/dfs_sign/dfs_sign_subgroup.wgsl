// dfs-sign, subgroup-coherent (TraversalMode::Subgroup): the lanes of a subgroup walk the
// dfs-sign nodes (dfs_node.wgsl) together. The subgroup visits a node when any live lane's
// ray hits its box, descends first into the child the majority of those lanes' signs on the
// split axis name, and shares one stack spread over the lanes' registers. Nodes and
// triangles are loaded cooperatively (each lane fetches a different word, then the words
// are passed round with subgroup shuffles); lavapipe turns every load instruction into a
// loop over the lanes, so one load of 8 words costs what one load of 1 word does. Each lane
// keeps its own best hit with the per-ray tests, tie rule and pruning, so closest hits equal
// the per-ray kernel's bit for bit (the closest hit under the tie rule does not depend on
// the visiting order); an any-hit lane stops counting once it has a hit.
//
// Work counted per lane (COUNT_STATS): the nodes and triangles its subgroup loaded while
// the lane's ray was live (valid, and for any hit not yet answered), whether or not that
// ray entered them: the union traversal each ray waits through.

// Stack entries per lane: entry e lives in lane e % lanes, slot e / lanes.
const DFS_SG_SLOTS: u32 = (STACK_SIZE + SUBGROUP_MIN_LANES - 1u) / SUBGROUP_MIN_LANES;
// Triangles one cooperative load fetches (3 words each).
const DFS_SG_TRIS: u32 = SUBGROUP_MIN_LANES / 3u;

// The lanes are exactly 0..lanes-1 (so a lane's rank among the active lanes is its id, the
// index subgroupShuffle takes) and at least SUBGROUP_MIN_LANES of them. Called by every lane
// of the subgroup.
fn dfs_sg_lanes_ok(lanes: u32) -> bool {
    let ballot = subgroupBallot(true);
    let first = vec4<u32>(0u, 32u, 64u, 96u);
    let bits = min(max(vec4<u32>(lanes), first) - first, vec4<u32>(32u));
    let low = (vec4<u32>(1u) << (bits & vec4<u32>(31u))) - vec4<u32>(1u);
    let want = select(low, vec4<u32>(0xffffffffu), bits == vec4<u32>(32u));
    return all(ballot == want) && lanes >= SUBGROUP_MIN_LANES;
}

// Closest hit in [tmin, tmax], or with any_hit a hit; an invalid ray is a miss. Every lane
// of the subgroup calls it (trace.wgsl).
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    let valid = ray_is_valid(r);
    // This lane still wants nodes (with any_hit: until its first hit).
    var live = valid;
    traversal_done = !valid;
    if COUNT_STATS {
        n_nodes = 0u;
        n_tris = 0u;
    }
    let lanes = subgroupAdd(1u);
    let lane = subgroupExclusiveAdd(1u);
    if !dfs_sg_lanes_ok(lanes) {
        // Not lanes this stack can spread over: leave done false, the host traces again.
        traversal_done = false;
        return best;
    }
    if !subgroupAny(valid) {
        return best;
    }
    let inv = safe_recip3(r.dir);
    let w = watertight_setup(r.dir);
    // Boxes are cut against the best t plus a few ulps (prune_bound), as per ray.
    var prune = prune_bound(best.t);
    var slots: array<u32, DFS_SG_SLOTS>;
    var sp = 0u;
    var idx = 0u;
    loop {
        // Even lanes fetch the node's first word, odd lanes its second.
        let word = node_word(2u * idx + (lane & 1u));
        let node = dfs_node_from_words(subgroupBroadcast(word, 0u), subgroupBroadcast(word, 1u));
        if COUNT_STATS && live {
            n_nodes += 1u;
        }
        let hit = live && slab_hit(node.lo, node.hi, r.origin, inv, r.tmin, prune);
        var descended = false;
        if subgroupAny(hit) {
            if (node.b & 3u) != DFS_LEAF_TAG {
                let axis = node.b & 3u;
                let neg = subgroupAdd(select(0u, 1u, hit && r.dir[axis] < 0.0));
                let entering = subgroupAdd(select(0u, 1u, hit));
                var near = idx + 1u;
                var far = node.a;
                if 2u * neg > entering {
                    near = node.a;
                    far = idx + 1u;
                }
                if lane == sp % lanes {
                    slots[sp / lanes] = far;
                }
                sp += 1u;
                idx = near;
                descended = true;
            } else {
                let count = node.b >> 2u;
                let end = node.a + count;
                let last_word = 3u * end - 1u;
                var testing = hit;  // this lane's ray entered the leaf and is still looking
                var seen = 0u;
                for (var i = node.a; i < end; i += DFS_SG_TRIS) {
                    // Lane l fetches word l of the next DFS_SG_TRIS triangles.
                    let tw = tri_word(min(3u * i + lane, last_word));
                    for (var j = 0u; j < DFS_SG_TRIS; j += 1u) {
                        if i + j < end {
                            let k = 3u * j;
                            let tri = tri_from_words(subgroupShuffle(tw, k),
                                subgroupShuffle(tw, k + 1u), subgroupShuffle(tw, k + 2u));
                            seen += 1u;
                            if COUNT_STATS && live {
                                n_tris += 1u;
                            }
                            if testing {
                                let h = intersect_tri(tri.v0, tri.v1, tri.v2, r, w, r.tmin, best.t);
                                if h.ok && beats(h.t, tri.prim, best.t, best.prim)
                                    && !(REJECT_NEAR_HITS && maybe_behind_origin(h)) {
                                    best = Hit(h.t, tri.prim, h.u, h.v);
                                    prune = hit_prune(h);
                                    if any_hit {
                                        testing = false;
                                        live = false;
                                    }
                                }
                            }
                        }
                    }
                }
                if seen != count {
                    // The driver cut a loop short (traversal_done stays false).
                    break;
                }
                if any_hit && !subgroupAny(live) {
                    traversal_done = true;
                    break;
                }
            }
        }
        if !descended {
            if sp == 0u {
                traversal_done = true;
                break;
            }
            sp -= 1u;
            idx = subgroupShuffle(slots[sp / lanes], sp % lanes);
        }
    }
    return best;
}
