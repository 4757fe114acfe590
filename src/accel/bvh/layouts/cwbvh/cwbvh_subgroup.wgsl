// cwbvh, subgroup-coherent (TraversalMode::Subgroup): the lanes of a subgroup walk the cwbvh
// nodes (cwbvh_node.wgsl) together, one node a step at a subgroup-uniform index.
//
// A step loads one node, five lanes fetching its five words (one load instruction), and every
// live lane tests the eight children against its own ray (cwbvh_child_hits, with its own
// prune bound). The subgroup takes the union of the lanes' hit masks: the internal children
// any lane entered become the next group (one group stack for the subgroup, as per ray), and
// each triangle any lane hit is tested one a step, three lanes fetching its words, by the
// lanes whose own mask holds it. Children are ordered by one octant for the whole subgroup
// (its first valid lane's), so the masks line up. Each lane keeps its own best hit with the
// per-ray tests, tie rule and pruning, so closest hits equal the per-ray kernel's bit for
// bit (the closest hit under the tie rule does not depend on the visiting order). An any-hit
// lane stops at its first hit; the subgroup stops when every lane has.
//
// Why: lavapipe runs a SIMD group of rays for as long as its slowest lane and calls its
// texture-load function once per load instruction whatever the lanes' addresses; here a node
// is one load instead of five and a triangle one instead of three, and the lanes' walks
// never diverge.
//
// Work counted per lane (COUNT_STATS): nodes and triangles its subgroup loaded while the
// lane's ray was live (valid, and for any hit not yet answered), whether or not that ray
// entered them.

// Lanes a step reads by index (the five words of a node).
const CWBVH_SG_LANES: u32 = CWBVH_NODE_WORDS;

// Closest hit in [tmin, tmax], or with any_hit a hit; an invalid ray is a miss. Every lane
// of the subgroup calls it together (trace.wgsl).
fn traverse(r: Ray, any_hit: bool) -> Hit {
    var best = Hit(r.tmax, MISS, 0.0, 0.0);
    let valid = ray_is_valid(r);
    // This lane still wants nodes (with any_hit: until its first hit).
    var live = valid;
    if !subgroup_start(valid, CWBVH_SG_LANES) {
        return best;
    }
    let lane = subgroupExclusiveAdd(1u);
    let inv = safe_recip3(r.dir);
    let parallel = any(abs(inv) >= vec3<f32>(PARALLEL_INV));
    let w = watertight_setup(r.dir);
    // The first valid lane's slot order (some lane is valid, above): the smallest key, lane
    // in the high bits.
    let mine = cwbvh_octant_inv(r.dir);
    let oct_inv = subgroupMin(select(0xffffffffu, 16u * lane + mine, valid)) & 15u;
    var prune = prune_bound(best.t);
    group_count = 0u;
    // As per ray: x the first child node, y the internal children still to visit | imask.
    var group = vec2<u32>(0u, 1u << 31u);
    loop {
        let idx = cwbvh_take_child(group, oct_inv);
        // Lanes 0..4 fetch the node's words.
        let word = node_word(CWBVH_NODE_WORDS * idx + min(lane, CWBVH_NODE_WORDS - 1u));
        let node = cwbvh_node_from_words(subgroupBroadcast(word, 0u), subgroupBroadcast(word, 1u),
            subgroupBroadcast(word, 2u), subgroupBroadcast(word, 3u), subgroupBroadcast(word, 4u));
        if COUNT_STATS && live {
            n_nodes += 1u;
        }
        var hits = 0u;
        if live {
            hits = cwbvh_child_hits(node, r, inv, parallel, prune, oct_inv);
        }
        let any_hits = subgroupOr(hits);
        group = cwbvh_group(node, any_hits);
        var tris = any_hits & ~CWBVH_NODE_BITS;
        while tris != 0u {
            let t = firstTrailingBit(tris);
            tris &= tris - 1u;
            // Lanes 0..2 fetch the triangle's words.
            let tw = tri_word(3u * (node.tri_base + t) + min(lane, 2u));
            let tri = tri_from_words(subgroupBroadcast(tw, 0u), subgroupBroadcast(tw, 1u),
                subgroupBroadcast(tw, 2u));
            if COUNT_STATS && live {
                n_tris += 1u;
            }
            if live && ((hits >> t) & 1u) != 0u && test_tri(tri, r, w, &best, &prune) && any_hit {
                live = false;
            }
        }
        // Asked of every lane (any_hit may differ between lanes: the render kernel's path
        // and shadow rays); a closest-hit lane's valid ray stays live.
        if !subgroupAny(live) {
            traversal_end(bitcast<u32>(r.tmax));
            break;
        }
        group = cwbvh_next_group(group);
        if group.y == 0u {
            traversal_end(bitcast<u32>(r.tmax));
            break;
        }
    }
    return best;
}
