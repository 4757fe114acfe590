// cwbvh's node, child test and stack of node groups, shared by its per-ray traversal
// (cwbvh.wgsl) and its subgroup traversal (cwbvh_subgroup.wgsl). CWBVH_TRI_BITS,
// CWBVH_COUNT_SHIFT, CWBVH_WIDTH, CWBVH_NODE_WORDS (words of a node), CWBVH_STACK_REGISTERS
// and CWBVH_SPILL_SIZE come from mod.rs.

// CwbvhNode, 80 bytes (mod.rs CwNode). e_imask: step exponents x, y, z and imask, one byte
// each, low byte first. child_meta, q_lo, q_hi: one byte per slot, slots 0-3 in .x, 4-7 in .y;
// q_lo[axis] / q_hi[axis] are the children's low / high planes on that axis.
struct CwbvhNode {
    p: vec3<f32>,
    e_imask: u32,
    child_base: u32,
    tri_base: u32,
    child_meta: vec2<u32>,
    q_lo: array<vec2<u32>, 3>,
    q_hi: array<vec2<u32>, 3>,
}

// A node from its five words.
fn cwbvh_node_from_words(a: vec4<u32>, b: vec4<u32>, c: vec4<u32>, d: vec4<u32>,
                         e: vec4<u32>) -> CwbvhNode {
    return CwbvhNode(bitcast<vec3<f32>>(a.xyz), a.w, b.x, b.y, b.zw,
                     array<vec2<u32>, 3>(c.xy, c.zw, d.xy), array<vec2<u32>, 3>(d.zw, e.xy, e.zw));
}

fn cwbvh_load_node(i: u32) -> CwbvhNode {
    let at = CWBVH_NODE_WORDS * i;
    return cwbvh_node_from_words(node_word(at), node_word(at + 1u), node_word(at + 2u),
                                 node_word(at + 3u), node_word(at + 4u));
}

// The hit mask of the node's children whose dequantised boxes the ray enters before `prune`
// (twin: RayBox::child_hits): an internal child in slot s at bit CWBVH_TRI_BITS + (s ^ oct_inv),
// a leaf's triangles at their offsets from tri_base. A ray parallel to an axis (`parallel`)
// takes the shared slab test with its parallel-axis rule; the others the same verdict from
// each axis's planes in the order the ray meets them (slab_hit_ordered: the planes are
// swapped once a node by the ray's signs, not compared per child). On this project's machine
// that gave ~1.1x rays/s on shadow and primary rays on Mesa 25 lavapipe, whose SIMD lanes
// skip a branch none of them takes (Mesa 22 runs both sides: 0.8x there).
fn cwbvh_child_hits(n: CwbvhNode, r: Ray, inv: vec3<f32>, parallel: bool, prune: f32,
                    oct_inv: u32) -> u32 {
    let ex = vec3<u32>(n.e_imask, n.e_imask >> 8u, n.e_imask >> 16u) & vec3<u32>(0xffu);
    let scale = bitcast<vec3<f32>>(ex << vec3<u32>(23u));
    let imask = n.e_imask >> 24u;
    let index_mask = (1u << CWBVH_COUNT_SHIFT) - 1u;
    // Per axis, the quantised planes met first (`a`) and last (`b`); low and high ones for a
    // parallel ray.
    let swap = (inv < vec3<f32>(0.0)) & vec3<bool>(!parallel);
    let qa = array<vec2<u32>, 3>(select(n.q_lo[0], n.q_hi[0], swap.x),
        select(n.q_lo[1], n.q_hi[1], swap.y), select(n.q_lo[2], n.q_hi[2], swap.z));
    let qb = array<vec2<u32>, 3>(select(n.q_hi[0], n.q_lo[0], swap.x),
        select(n.q_hi[1], n.q_lo[1], swap.y), select(n.q_hi[2], n.q_lo[2], swap.z));
    var hits = 0u;
    for (var h = 0u; h < 2u; h += 1u) {
        let hi_half = h == 1u;
        let child_meta = select(n.child_meta.x, n.child_meta.y, hi_half);
        let a4 = select(vec3<u32>(qa[0].x, qa[1].x, qa[2].x),
                        vec3<u32>(qa[0].y, qa[1].y, qa[2].y), hi_half);
        let b4 = select(vec3<u32>(qb[0].x, qb[1].x, qb[2].x),
                        vec3<u32>(qb[0].y, qb[1].y, qb[2].y), hi_half);
        for (var b = 0u; b < 4u; b += 1u) {
            let sh = 8u * b;
            let m = (child_meta >> sh) & 0xffu;
            // An unused slot (m = 0) adds no bit, so no branch skips it: 1.05-1.07x rays/s on
            // Mesa 25 lavapipe on this project's machine (0.95x on Mesa 22).
            // quantise::dequantise: p + q * scale (exact product, so contraction-proof).
            let qpa = vec3<f32>((a4 >> vec3<u32>(sh)) & vec3<u32>(0xffu));
            let qpb = vec3<f32>((b4 >> vec3<u32>(sh)) & vec3<u32>(0xffu));
            let pa = n.p + qpa * scale;
            let pb = n.p + qpb * scale;
            var hit = false;
            if parallel {
                hit = slab_hit(pa, pb, r.origin, inv, r.tmin, prune);
            } else {
                hit = slab_hit_ordered(pa, pb, r.origin, inv, r.tmin, prune);
            }
            let inner = (imask >> (4u * h + b)) & 1u;
            let bits = (m >> CWBVH_COUNT_SHIFT) << ((m & index_mask) ^ (oct_inv * inner));
            hits |= select(0u, bits, hit);
        }
    }
    return hits;
}

// The stack of node groups, at most one per level of this tree. Its top four entries live
// in variables (CWBVH_STACK_REGISTERS: group_top0-3), the rest in an array of
// CWBVH_SPILL_SIZE (the tree's depth - 4, mod.rs spill_size): on lavapipe a store to or a load from a private array at a per-lane index is
// a loop over the lanes, each a read-modify-write with a branch, while shifting four
// variables is a few blends. An 8-wide tree is shallow and a group holds up to eight
// children, so the array is seldom reached: on this project's machine (Mesa 25 lavapipe)
// that gave 1.1-1.2x rays/s on bounce and random rays and ~1.05x on primary ones. The
// binary layouts push at every inner node, far deeper than four, and measured 0.84-0.93x
// with it (not kept there).
var<private> group_top0: vec2<u32>;
var<private> group_top1: vec2<u32>;
var<private> group_top2: vec2<u32>;
var<private> group_top3: vec2<u32>;
var<private> group_rest: array<vec2<u32>, CWBVH_SPILL_SIZE>;
var<private> group_count: u32;

fn group_push(g: vec2<u32>) {
    // The oldest of the four moves to the array. A loop, not an `if`: lavapipe skips a loop
    // no lane enters, but runs a short `if` for every lane (the masked-off lanes' stores too).
    var spill = group_count >= CWBVH_STACK_REGISTERS;
    while spill {
        group_rest[group_count - CWBVH_STACK_REGISTERS] = group_top3;
        spill = false;
    }
    group_top3 = group_top2;
    group_top2 = group_top1;
    group_top1 = group_top0;
    group_top0 = g;
    group_count += 1u;
}

// The hit mask's bits that name internal children (the others name triangles).
const CWBVH_NODE_BITS: u32 = ~((1u << CWBVH_TRI_BITS) - 1u);

// The group a node leaves for its hit mask `hits`: its internal children still to visit (from
// child_base), with its imask.
fn cwbvh_group(node: CwbvhNode, hits: u32) -> vec2<u32> {
    return vec2<u32>(node.child_base, (hits & CWBVH_NODE_BITS) | (node.e_imask >> 24u));
}

// The group the next node comes from: `group` while it holds an internal child, else the
// stack's top; vec2(0) (no child) when the stack is empty too and the traversal is over.
fn cwbvh_next_group(group: vec2<u32>) -> vec2<u32> {
    if (group.y & CWBVH_NODE_BITS) != 0u {
        return group;
    }
    if group_count == 0u {
        return vec2<u32>(0u);
    }
    return group_pop();
}

// The slot order of a ray along `dir` (twin: the octant's xor): CWBVH_WIDTH - 1 xor the
// direction's sign bits, so the highest hit bit is the nearest child.
fn cwbvh_octant_inv(dir: vec3<f32>) -> u32 {
    let octant = select(0u, 1u, dir.x < 0.0) | select(0u, 2u, dir.y < 0.0)
        | select(0u, 4u, dir.z < 0.0);
    return (CWBVH_WIDTH - 1u) ^ octant;
}

// Takes the next internal child of `group` (its highest bit: the nearest in the slot order
// `oct_inv`), pushes the rest of the group if any internal child is left, and returns the
// child's node index. `group` (x: first child node, y: hit internal children | imask) holds
// at least one internal child.
fn cwbvh_take_child(group: vec2<u32>, oct_inv: u32) -> u32 {
    let bit = firstLeadingBit(group.y);
    let rest = vec2<u32>(group.x, group.y & ~(1u << bit));
    if (rest.y & CWBVH_NODE_BITS) != 0u {
        group_push(rest);
    }
    let slot = (bit - CWBVH_TRI_BITS) ^ oct_inv;
    return group.x + countOneBits(rest.y & ((1u << slot) - 1u));
}

// The top group, removed; the stack must not be empty.
fn group_pop() -> vec2<u32> {
    let g = group_top0;
    group_top0 = group_top1;
    group_top1 = group_top2;
    group_top2 = group_top3;
    group_count -= 1u;
    var fill = group_count >= CWBVH_STACK_REGISTERS;
    while fill {
        group_top3 = group_rest[group_count - CWBVH_STACK_REGISTERS];
        fill = false;
    }
    return g;
}

