// dfs-sign, subgroup-coherent (TraversalMode::Subgroup): the lanes of a subgroup walk the
// dfs-sign nodes (dfs_node.wgsl) together, one subgroup-uniform step at a time.
//
// A step expands one inner node: four lanes fetch the four words of its two children (one
// load instruction), every lane tests both boxes against its own ray, and one vote decides
// for the subgroup which children it enters and in which order (the majority of those lanes'
// rays that meet the second child's centre first). A hit inner child becomes the next node
// (the far one is pushed on a stack of inner nodes); a hit leaf joins one of two leaf slots,
// whose triangles are tested one per step alongside the expansions, three lanes fetching
// its words. A leaf with no free slot stalls the step (its children are tested again on the
// next). Each lane keeps its own best hit with the per-ray tests, tie rule and pruning
// (prune_bound / hit_prune), so closest hits equal the per-ray kernel's bit for bit: the
// closest hit under the tie rule does not depend on the visiting order. An any-hit lane stops
// at its first hit; the subgroup stops when every lane has. Lanes may differ in any_hit.
//
// Why this shape: lavapipe (Mesa 22.3) runs both sides of every branch and turns each load
// instruction into a loop over the lanes, so a step costs all of its code every time; a step
// that tests two boxes and a triangle with two loads does in ~12 steps what the per-ray
// kernel does in ~20 (bunny, primary rays).
//
// Work counted per lane (COUNT_STATS): node records and triangles its subgroup loaded and
// tested while the lane's ray was live (valid, and for any hit not yet answered), whether
// or not that ray entered them: the union traversal each ray waits through.

const DFS_SG_NONE: u32 = 0xffffffffu;
// Lanes a step reads by index (the four words of two nodes).
const DFS_SG_LANES: u32 = 4u;

// Closest hit in [tmin, tmax], or with any_hit a hit; an invalid ray is a miss. Every lane
// of the subgroup calls it together (trace.wgsl).
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    let valid = ray_is_valid(r);
    // This lane still wants nodes (with any_hit: until its first hit).
    var live = valid;
    if !subgroup_start(valid, DFS_SG_LANES) {
        return best;
    }
    let lane = subgroupExclusiveAdd(1u);
    let inv = safe_recip3(r.dir);
    let w = watertight_setup(r.dir);
    // Boxes are cut against the best t plus a few ulps (prune_bound), as per ray.
    var prune = prune_bound(best.t);
    let root = dfs_load_node(0u);
    if COUNT_STATS && live {
        n_nodes += 1u;
    }
    let root_hit = live && slab_hit(root.lo, root.hi, r.origin, inv, r.tmin, prune);
    // The inner node to expand next (its index and second child), or DFS_SG_NONE.
    var cur = DFS_SG_NONE;
    var cur_a = 0u;
    // Leaf slots: triangles [t0, e0) for the lanes with in0, then [t1, e1) for in1 (the
    // second is used only while the first is).
    var t0 = 0u;
    var e0 = 0u;
    var in0 = false;
    var t1 = 0u;
    var e1 = 0u;
    var in1 = false;
    if subgroupAny(root_hit) {
        if (root.b & 3u) == DFS_LEAF_TAG {
            t0 = root.a;
            e0 = root.a + (root.b >> 2u);
            in0 = root_hit;
        } else {
            cur = 0u;
            cur_a = root.a;
        }
    }
    // Inner nodes still to expand (index, second child): at most one per level of the path
    // to `cur`, as per ray.
    var stack_i: array<u32, STACK_SIZE>;
    var stack_a: array<u32, STACK_SIZE>;
    var sp = 0u;
    loop {
        // One triangle of the first leaf slot: lanes 0..2 fetch its words.
        if t0 < e0 {
            let tw = tri_word(min(3u * t0 + lane, 3u * e0 - 1u));
            let tri = tri_from_words(subgroupBroadcast(tw, 0u), subgroupBroadcast(tw, 1u),
                subgroupBroadcast(tw, 2u));
            if COUNT_STATS && live {
                n_tris += 1u;
            }
            // The shared leaf step's triangle test (traversal.wgsl's test_tri).
            if in0 && test_tri(tri, r, w, &best, &prune) && any_hit {
                live = false;
                in0 = false;
                in1 = false;
            }
            t0 += 1u;
            if t0 >= e0 {
                t0 = t1;
                e0 = e1;
                in0 = in1;
                t1 = 0u;
                e1 = 0u;
            }
            // Asked of every lane (any_hit may differ between lanes: the render kernel's
            // path and shadow rays); a closest-hit lane's valid ray stays live.
            if !subgroupAny(live) {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
        // Expand `cur`: lanes 0..3 fetch the words of its children cur + 1 and cur_a.
        if cur != DFS_SG_NONE {
            let first = cur + 1u;
            let q = lane & 3u;
            let word = node_word(select(2u * cur_a + q - 2u, 2u * first + q, q < 2u));
            let n0 = dfs_node_from_words(subgroupBroadcast(word, 0u), subgroupBroadcast(word, 1u));
            let n1 = dfs_node_from_words(subgroupBroadcast(word, 2u), subgroupBroadcast(word, 3u));
            if COUNT_STATS && live {
                n_nodes += 2u;
            }
            let h0 = live && slab_hit(n0.lo, n0.hi, r.origin, inv, r.tmin, prune);
            let h1 = live && slab_hit(n1.lo, n1.hi, r.origin, inv, r.tmin, prune);
            // One vote: lanes entering each child (bytes 0, 1), and of the lanes entering
            // either, those meeting the second child's centre first (byte 2) and all (byte 3);
            // a subgroup has at most 128 lanes, so each count fits its byte.
            let second = dot3((n1.lo + n1.hi) - (n0.lo + n0.hi), r.dir) < 0.0;
            let either = h0 || h1;
            let votes = subgroupAdd(select(0u, 1u, h0) + select(0u, 0x100u, h1)
                + select(0u, 0x10000u, either && second) + select(0u, 0x1000000u, either));
            var near_i = first;
            var near = n0;
            var near_hit = h0;
            var near_any = (votes & 0xffu) != 0u;
            var far_i = cur_a;
            var far = n1;
            var far_hit = h1;
            var far_any = (votes & 0xff00u) != 0u;
            if 2u * ((votes >> 16u) & 0xffu) > votes >> 24u {
                near_i = cur_a;
                near = n1;
                near_hit = h1;
                near_any = (votes & 0xff00u) != 0u;
                far_i = first;
                far = n0;
                far_hit = h0;
                far_any = (votes & 0xffu) != 0u;
            }
            let near_leaf = near_any && (near.b & 3u) == DFS_LEAF_TAG;
            let far_leaf = far_any && (far.b & 3u) == DFS_LEAF_TAG;
            let free = select(0u, 1u, t0 >= e0) + select(0u, 1u, t1 >= e1);
            if select(0u, 1u, near_leaf) + select(0u, 1u, far_leaf) <= free {
                if near_leaf {
                    if t0 >= e0 {
                        t0 = near.a;
                        e0 = near.a + (near.b >> 2u);
                        in0 = near_hit;
                    } else {
                        t1 = near.a;
                        e1 = near.a + (near.b >> 2u);
                        in1 = near_hit;
                    }
                }
                if far_leaf {
                    if t0 >= e0 {
                        t0 = far.a;
                        e0 = far.a + (far.b >> 2u);
                        in0 = far_hit;
                    } else {
                        t1 = far.a;
                        e1 = far.a + (far.b >> 2u);
                        in1 = far_hit;
                    }
                }
                let near_inner = near_any && !near_leaf;
                let far_inner = far_any && !far_leaf;
                cur = DFS_SG_NONE;
                if near_inner {
                    cur = near_i;
                    cur_a = near.a;
                }
                if far_inner {
                    if near_inner {
                        stack_i[sp] = far_i;
                        stack_a[sp] = far.a;
                        sp += 1u;
                    } else {
                        cur = far_i;
                        cur_a = far.a;
                    }
                }
            }
        }
        if cur == DFS_SG_NONE {
            if sp > 0u {
                sp -= 1u;
                cur = stack_i[sp];
                cur_a = stack_a[sp];
            } else if t0 >= e0 {
                traversal_end(bitcast<u32>(r.tmax));
                break;
            }
        }
    }
    return best;
}
