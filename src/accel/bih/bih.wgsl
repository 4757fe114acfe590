// bih: the bounding interval hierarchy's own arrays (src/accel/bih): 16-byte nodes one to a
// word, the leaves' triangles one LeafTri each. Front to back with a stack of pending far
// children and the ray's interval in each. The CPU twin is Bih::walk in traverse.rs, step
// for step: same operations in the same order, so hits and statistics agree bit for bit.
// BIH_LEAF_TAG, BIH_LINK_SHIFT and PLANE_STACK_SIZE (MAX_BIH_DEPTH) are generated in front
// from their Rust definitions (gpu.rs), followed by plane_ray.wgsl (the root box Bih::bounds
// in its overrides, the ray, the stack's entries).

// bih::BihNode. Inner: clip = [left child's maximum, right child's minimum],
// link = right child << BIH_LINK_SHIFT | axis (the left child is the next node), count = 0.
// Leaf: link = first triangle << BIH_LINK_SHIFT | BIH_LEAF_TAG, count = its triangles.
struct BihNode {
    clip: vec2<f32>,
    link: u32,
    count: u32,
}

fn bih_load_node(i: u32) -> BihNode {
    let w = node_word(i);
    return BihNode(bitcast<vec2<f32>>(w.xy), w.z, w.w);
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
    // An empty tree is a single empty leaf (Layout::validate: the only one).
    let root = bih_load_node(0u);
    if !ray_is_valid(r) || ((root.link & 3u) == BIH_LEAF_TAG && root.count == 0u) {
        return best;
    }
    let pr = plane_ray(r);
    let box_lo = vec3<f32>(PLANE_LO_X, PLANE_LO_Y, PLANE_LO_Z);
    let box_hi = vec3<f32>(PLANE_HI_X, PLANE_HI_Y, PLANE_HI_Z);
    let root_interval = plane_root_interval(pr, box_lo, box_hi);
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
    var hit_prune = min(r.tmax, BIG);
    var prune = plane_scaled(pr, hit_prune);
    var stack: array<PlanePending, PLANE_STACK_SIZE>;
    var sp = 0u;
    var idx = 0u;
    loop {
        let node = bih_load_node(idx);
        if COUNT_STATS {
            n_nodes += 1u;
        }
        if (node.link & 3u) != BIH_LEAF_TAG {
            let k = node.link & 3u;
            let o = pr.o[k];
            let inv = pr.inv[k];
            let positive = inv > 0.0;
            let right = node.link >> BIH_LINK_SHIFT;
            let near = select(right, idx + 1u, positive);
            let far = select(idx + 1u, right, positive);
            let near_plane = select(node.clip.y, node.clip.x, positive);
            let far_plane = select(node.clip.x, node.clip.y, positive);
            var visit_near: bool;
            var visit_far: bool;
            var near_hi = hi;
            var far_lo = lo;
            if plane_parallel(pr, k) {
                // The origin's side decides; the interval is unchanged.
                visit_near = select(o >= near_plane, o <= near_plane, positive);
                visit_far = select(o <= far_plane, o >= far_plane, positive);
            } else {
                let t_near = finite((near_plane - o) * inv);
                let t_far = finite((far_plane - o) * inv);
                visit_near = t_near >= lo;
                visit_far = t_far <= hi;
                near_hi = min(hi, widen_hi(t_near));
                far_lo = max(lo, widen_lo(t_far));
            }
            visit_far = visit_far && far_lo <= prune;
            if visit_near {
                if visit_far {
                    stack[sp] = PlanePending(far, far_lo, hi);
                    sp += 1u;
                }
                idx = near;
                hi = near_hi;
                continue;
            }
            if visit_far {
                idx = far;
                lo = far_lo;
                continue;
            }
        } else {
            let first = node.link >> BIH_LINK_SHIFT;
            if test_leaf(first, node.count, r, w, any_hit, &best, &hit_prune) {
                traversal_end(bitcast<u32>(r.tmax));
                return best;
            }
            prune = plane_scaled(pr, hit_prune);
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
