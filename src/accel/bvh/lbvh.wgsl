// LBVH on the GPU: the kernels of `gpu::build_lbvh`, in the order it runs them. Their CPU
// twin is `accel/bvh/lbvh.rs`; both make the same radix tree. The constants (CODE_BITS,
// LEAF_BIT, RADIX_BITS, SORT_TILE, …) are generated in front of this file from Rust.

struct Params {
    // Primitives.
    n: u32,
    // Sort tiles of SORT_TILE primitives.
    tiles: u32,
    // The sort pass's digit: bits shift .. shift + RADIX_BITS of the code.
    shift: u32,
    // The SAH's leaf rule (BuildOptions).
    max_leaf: u32,
    t_cube: f32,
    t_obj: f32,
    // The flatten's pass: the inner nodes of one height, at by_height[first .. first + count].
    first: u32,
    count: u32,
    // Always 0, unknown to the compiler (see `rounded`).
    zero: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// The storage arrays are declared in front of this file with their accessors (NAME_at,
// NAME_set; NAME_load, NAME_store, NAME_max, NAME_add for atomics), each bound in as many parts as
// its size needs (gpu::parted_array); `gpu::lbvh_build::ARRAYS` says what each holds.

const WORKGROUP: u32 = 64u;
const NO_NODE: u32 = 0xffffffffu;
const RADIX: u32 = 1u << RADIX_BITS;
const SCAN_THREADS: u32 = 256u;

// A float as a u32 in the same order (-0 below +0; never NaN here).
fn ordered(f: f32) -> u32 {
    let b = bitcast<u32>(f);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

fn unordered(u: u32) -> f32 {
    return bitcast<f32>(select(~u, u & 0x7fffffffu, (u & 0x80000000u) != 0u));
}

// The thread's index over a dispatch that may be two-dimensional (beyond the per-dimension
// workgroup limit).
fn thread_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * WORKGROUP;
}

fn vertex(a: u32, i: u32) -> vec3<f32> {
    let k = 3u * i;
    if a == 0u {
        return vec3<f32>(v0_at(k), v0_at(k + 1u), v0_at(k + 2u));
    }
    if a == 1u {
        return vec3<f32>(v1_at(k), v1_at(k + 1u), v1_at(k + 2u));
    }
    return vec3<f32>(v2_at(k), v2_at(k + 1u), v2_at(k + 2u));
}

struct Box {
    lo: vec3<f32>,
    hi: vec3<f32>,
}

fn triangle_box(i: u32) -> Box {
    let a = vertex(0u, i);
    let b = vertex(1u, i);
    let c = vertex(2u, i);
    return Box(min(min(a, b), c), max(max(a, b), c));
}

fn ordered3(f: vec3<f32>) -> vec3<u32> {
    return vec3<u32>(ordered(f.x), ordered(f.y), ordered(f.z));
}

var<workgroup> reduce_lo: array<vec3<u32>, WORKGROUP>;
var<workgroup> reduce_hi: array<vec3<u32>, WORKGROUP>;

// 1. Bounds of the doubled centroids: each thread folds every threads-th triangle (at most
//    BOUNDS_GROUPS workgroups, one dimension: few barriers and atomics), each workgroup
//    reduces its threads', then raises the global words once.
@compute @workgroup_size(WORKGROUP)
fn bounds(@builtin(global_invocation_id) gid: vec3<u32>,
          @builtin(num_workgroups) groups: vec3<u32>,
          @builtin(local_invocation_index) t: u32) {
    let threads = groups.x * WORKGROUP;
    var lo = vec3<u32>(0u);
    var hi = vec3<u32>(0u);
    for (var i = gid.x; i < params.n; i += threads) {
        let b = triangle_box(i);
        let c2 = ordered3(b.lo + b.hi);
        lo = max(lo, ~c2);
        hi = max(hi, c2);
    }
    reduce_lo[t] = lo;
    reduce_hi[t] = hi;
    workgroupBarrier();
    for (var half = WORKGROUP / 2u; half > 0u; half /= 2u) {
        if t < half {
            reduce_lo[t] = max(reduce_lo[t], reduce_lo[t + half]);
            reduce_hi[t] = max(reduce_hi[t], reduce_hi[t + half]);
        }
        workgroupBarrier();
    }
    if t == 0u {
        for (var a = 0u; a < 3u; a++) {
            centre_bounds_max(a, reduce_lo[0][a]);
            centre_bounds_max(a + 3u, reduce_hi[0][a]);
        }
    }
}

fn spread(v: u32) -> u32 {
    var x = v & 0x3ffu;
    x = (x | (x << 16u)) & 0x030000ffu;
    x = (x | (x << 8u)) & 0x0300f00fu;
    x = (x | (x << 4u)) & 0x030c30c3u;
    x = (x | (x << 2u)) & 0x09249249u;
    return x;
}

fn pow2(k: i32) -> f32 {
    return bitcast<f32>(u32(k + 127) << 23u);
}

// 2. Morton codes (`Quantiser` in lbvh.rs, operation for operation).
@compute @workgroup_size(WORKGROUP)
fn codes(@builtin(global_invocation_id) gid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_index(gid, groups);
    if i >= params.n {
        return;
    }
    var lo: vec3<f32>;
    var hi: vec3<f32>;
    for (var a = 0u; a < 3u; a++) {
        lo[a] = unordered(~centre_bounds_load(a));
        hi[a] = unordered(centre_bounds_load(a + 3u));
    }
    let e = hi - lo;
    let side = max(e.x, max(e.y, e.z));
    let field = (bitcast<u32>(side) >> 23u) & 0xffu;
    var s1 = 0.0;
    var s2 = 0.0;
    if field != 0u {
        let k = i32(CODE_BITS) - 1 - (i32(field) - 127);
        s1 = pow2(k >> 1u);
        s2 = pow2(k - (k >> 1u));
    }
    let b = triangle_box(i);
    let c2 = b.lo + b.hi;
    var code = 0u;
    for (var a = 0u; a < 3u; a++) {
        let q = ((c2[a] - lo[a]) * s1) * s2;
        code |= spread(min(u32(q), (1u << CODE_BITS) - 1u)) << a;
    }
    pairs_out_set(i, vec2<u32>(code, i));
}

// 3. One pass of the stable radix sort (RADIX_BITS a pass, SORT_PASSES passes from the low
//    digit): each thread counts its tile's digits, one workgroup turns the counts into
//    where each tile's digits go, each thread moves its tile's pairs there in order.
@compute @workgroup_size(WORKGROUP)
fn histogram(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
    let tile = thread_index(gid, groups);
    if tile >= params.tiles {
        return;
    }
    var count: array<u32, RADIX>;
    let end = min(params.n, (tile + 1u) * SORT_TILE);
    for (var e = tile * SORT_TILE; e < end; e++) {
        count[(pairs_in_at(e).x >> params.shift) & (RADIX - 1u)] += 1u;
    }
    for (var d = 0u; d < RADIX; d++) {
        table_set(d * params.tiles + tile, count[d]);
    }
}

var<workgroup> partial: array<u32, SCAN_THREADS>;

@compute @workgroup_size(SCAN_THREADS)
fn scan(@builtin(local_invocation_index) t: u32) {
    let m = RADIX * params.tiles;
    let chunk = (m + SCAN_THREADS - 1u) / SCAN_THREADS;
    let first = min(t * chunk, m);
    let last = min(first + chunk, m);
    var sum = 0u;
    for (var k = first; k < last; k++) {
        sum += table_at(k);
    }
    partial[t] = sum;
    workgroupBarrier();
    for (var step = 1u; step < SCAN_THREADS; step *= 2u) {
        let before = select(0u, partial[max(t, step) - step], t >= step);
        workgroupBarrier();
        partial[t] += before;
        workgroupBarrier();
    }
    var run = partial[t] - sum;
    for (var k = first; k < last; k++) {
        let c = table_at(k);
        table_set(k, run);
        run += c;
    }
}

@compute @workgroup_size(WORKGROUP)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>,
           @builtin(num_workgroups) groups: vec3<u32>) {
    let tile = thread_index(gid, groups);
    if tile >= params.tiles {
        return;
    }
    var at: array<u32, RADIX>;
    for (var d = 0u; d < RADIX; d++) {
        at[d] = table_at(d * params.tiles + tile);
    }
    let end = min(params.n, (tile + 1u) * SORT_TILE);
    for (var e = tile * SORT_TILE; e < end; e++) {
        let p = pairs_in_at(e);
        let d = (p.x >> params.shift) & (RADIX - 1u);
        pairs_out_set(at[d], p);
        at[d] += 1u;
    }
}

// Common prefix length of the keys (code, place) at places i and j; -1 outside.
fn delta(i: i32, j: i32) -> i32 {
    if j < 0 || j >= i32(params.n) {
        return -1;
    }
    let a = pairs_in_at(u32(i)).x;
    let b = pairs_in_at(u32(j)).x;
    if a != b {
        return i32(countLeadingZeros(a ^ b));
    }
    return 32 + i32(countLeadingZeros(u32(i ^ j)));
}

// 4. The radix tree (Karras 2012; `node_kids` in lbvh.rs): every inner node on its own.
@compute @workgroup_size(WORKGROUP)
fn hierarchy(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
    let node = thread_index(gid, groups);
    if node + 1u >= params.n {
        return;
    }
    let i = i32(node);
    let d = select(-1, 1, delta(i, i + 1) > delta(i, i - 1));
    let dmin = delta(i, i - d);
    var lmax = 2;
    while delta(i, i + lmax * d) > dmin {
        lmax *= 2;
    }
    var l = 0;
    for (var t = lmax / 2; t >= 1; t /= 2) {
        if delta(i, i + (l + t) * d) > dmin {
            l += t;
        }
    }
    let j = i + l * d;
    let dnode = delta(i, j);
    var s = 0;
    var div = 2;
    loop {
        let t = (l + div - 1) / div;
        if delta(i, i + (s + t) * d) > dnode {
            s += t;
        }
        if t == 1 {
            break;
        }
        div *= 2;
    }
    let split = i + s * d + min(d, 0);
    var pair: vec2<u32>;
    let ends = vec2<i32>(min(i, j), max(i, j));
    for (var side = 0; side < 2; side++) {
        let place = split + side;
        if place == ends[side] {
            pair[side] = LEAF_BIT | u32(place);
            parents_set(params.n - 1u + pairs_in_at(u32(place)).y, node);
        } else {
            pair[side] = u32(place);
            parents_set(u32(place), node);
        }
    }
    kids_set(node, pair);
}

// 5. Boxes and heights (a node of two leaves: 1): each primitive raises its box and its
//    distance into its ancestors' words, going up while it raised any. The first to raise a
//    word to its final value goes on, so every node ends with its subtree's bounds and
//    height, whatever the order (each word's raises are atomic).
@compute @workgroup_size(WORKGROUP)
fn boxes(@builtin(global_invocation_id) gid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let p = thread_index(gid, groups);
    if p >= params.n || params.n < 2u {
        return;
    }
    let b = triangle_box(p);
    var words: array<u32, 6>;
    for (var a = 0u; a < 3u; a++) {
        words[a] = ~ordered(b.lo[a]);
        words[a + 3u] = ordered(b.hi[a]);
    }
    var node = parents_at(params.n - 1u + p);
    var h = 1u;
    loop {
        // Every word is raised, whatever the ones before did.
        var raised = node_height_max(node, h) < h;
        for (var k = 0u; k < 6u; k++) {
            let old = node_boxes_max(6u * node + k, words[k]);
            raised = raised || old < words[k];
        }
        if !raised || node == 0u {
            break;
        }
        node = parents_at(node);
        h += 1u;
    }
}

// 6. The flatten into dfs-sign, as `cluster_tree::to_node` then `DfsSign::flatten` make it
//    on the CPU, one height of inner nodes a pass, up then down. First each place's box.
@compute @workgroup_size(WORKGROUP)
fn leaf_boxes(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let s = thread_index(gid, groups);
    if s >= params.n {
        return;
    }
    let b = triangle_box(pairs_in_at(s).y);
    for (var a = 0u; a < 3u; a++) {
        place_boxes_set(6u * s + a, b.lo[a]);
        place_boxes_set(6u * s + 3u + a, b.hi[a]);
    }
}

// The inner nodes of each height (a radix tree over distinct 62-bit keys is at most 62
// levels deep: heights stay below HEIGHT_LIMIT).
@compute @workgroup_size(WORKGROUP)
fn count_heights(@builtin(global_invocation_id) gid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_index(gid, groups);
    if i + 1u < params.n {
        cursor_add(min(node_height_load(i), HEIGHT_LIMIT - 1u), 1u);
    }
}

// The inner nodes grouped by height (the cursor set to each height's first place); the
// order within a height is any: each node's work depends on its own data only.
@compute @workgroup_size(WORKGROUP)
fn by_heights(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_index(gid, groups);
    if i + 1u < params.n {
        by_height_set(cursor_add(min(node_height_load(i), HEIGHT_LIMIT - 1u), 1u), i);
    }
}

// The inner node of this pass's height that thread `t` takes (NO_NODE: none).
fn pass_node(t: u32) -> u32 {
    if t >= params.count {
        return NO_NODE;
    }
    return by_height_at(params.first + t);
}

fn node_box(i: u32) -> Box {
    var b: Box;
    for (var a = 0u; a < 3u; a++) {
        b.lo[a] = unordered(~node_boxes_load(6u * i + a));
        b.hi[a] = unordered(node_boxes_load(6u * i + 3u + a));
    }
    return b;
}

fn place_box(s: u32) -> Box {
    var b: Box;
    for (var a = 0u; a < 3u; a++) {
        b.lo[a] = place_boxes_at(6u * s + a);
        b.hi[a] = place_boxes_at(6u * s + 3u + a);
    }
    return b;
}

// A product rounded to f32 before it is added, as on the CPU. Without SPIR-V's NoContraction
// (which WGSL cannot ask for; on Vulkan lancer adds it itself, gpu::exact_spirv, but not on
// other backends) a driver may fuse a * b + c into one fma, rounding once where the CPU
// rounds twice (lavapipe does: one ulp turned an exact SAH tie at 10M triangles); passing
// the product through an integer operation the compiler cannot see through keeps it a
// product of its own.
fn rounded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) ^ params.zero);
}

// Aabb::area.
fn area(b: Box) -> f32 {
    if any(b.lo > b.hi) {
        return 0.0;
    }
    let e = b.hi - b.lo;
    return 2.0 * (rounded(e.x * e.y) + rounded(e.y * e.z) + rounded(e.z * e.x));
}

// tree::children_order: the axis where the centres lie farthest apart, and whether the
// second child is the low side there.
fn children_order(a: Box, b: Box) -> vec2<u32> {
    let ca = (a.lo + a.hi) * 0.5;
    let cb = (b.lo + b.hi) * 0.5;
    let gap = abs(cb - ca);
    var axis = 2u;
    if gap.x >= gap.y && gap.x >= gap.z {
        axis = 0u;
    } else if gap.y >= gap.z {
        axis = 1u;
    }
    return vec2<u32>(axis, select(0u, 1u, cb[axis] < ca[axis]));
}

// A child's (primitives, nodes, cost times area) and box (an inner child's was filled in
// an earlier pass: its height is lower).
struct Summary {
    count: u32,
    nodes: u32,
    cost: f32,
    b: Box,
}

fn summary(k: u32) -> Summary {
    if (k & LEAF_BIT) != 0u {
        let b = place_box(k & ~LEAF_BIT);
        return Summary(1u, 1u, rounded(params.t_obj * area(b)), b);
    }
    let f = info_at(k);
    return Summary(f.x, f.y, bitcast<f32>(f.z), node_box(k));
}

//    Bottom-up, one height a pass: the SAH's leaves (`convert` in cluster_tree.rs).
@compute @workgroup_size(WORKGROUP)
fn costs(@builtin(global_invocation_id) gid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let i = pass_node(thread_index(gid, groups));
    if i == NO_NODE {
        return;
    }
    let k = kids_at(i);
    let a = summary(k.x);
    let b = summary(k.y);
    let order = children_order(a.b, b.b);
    var l = a;
    var r = b;
    if order.y == 1u {
        l = b;
        r = a;
    }
    let own = area(node_box(i));
    let count = l.count + r.count;
    let split = rounded(2.0 * params.t_cube * own) + l.cost + r.cost;
    let as_leaf = f32(count) * params.t_obj * own;
    let leaf = count <= params.max_leaf && as_leaf <= split;
    let nodes = select(1u + l.nodes + r.nodes, 1u, leaf);
    let cost = select(split, as_leaf, leaf);
    let flags = order.x | (order.y << 2u) | (select(0u, 1u, leaf) << 3u);
    info_set(i, vec4<u32>(count, nodes, bitcast<u32>(cost), flags));
}

// An inner node's children, low side first: (first, second).
fn ordered_kids(i: u32) -> vec2<u32> {
    let k = kids_at(i);
    if ((info_at(i).w >> 2u) & 1u) == 1u {
        return k.yx;
    }
    return k;
}

fn count_and_nodes(k: u32) -> vec2<u32> {
    if (k & LEAF_BIT) != 0u {
        return vec2<u32>(1u, 1u);
    }
    return info_at(k).xy;
}

//    Top-down, one height a pass from the root's: each node's dfs-sign index and first
//    place in leaf order handed to its children (the root's are zero).
@compute @workgroup_size(WORKGROUP)
fn places(@builtin(global_invocation_id) gid: vec3<u32>,
          @builtin(num_workgroups) groups: vec3<u32>) {
    let i = pass_node(thread_index(gid, groups));
    if i == NO_NODE {
        return;
    }
    let me = down_at(i);
    let hidden = me.z != 0u || ((info_at(i).w >> 3u) & 1u) == 1u;
    let k = ordered_kids(i);
    let first = count_and_nodes(k.x);
    let index = vec2<u32>(me.x + 1u, me.x + 1u + first.y);
    let start = vec2<u32>(me.y, me.y + first.x);
    for (var side = 0u; side < 2u; side++) {
        let c = k[side];
        if (c & LEAF_BIT) != 0u {
            place_down_set(c & ~LEAF_BIT, vec2<u32>(start[side], select(index[side], NO_NODE, hidden)));
        } else {
            down_set(c, vec4<u32>(index[side], start[side], select(0u, 1u, hidden), 0u));
        }
    }
}

fn write_node(at: u32, b: Box, a: u32, tag: u32) {
    let w = 8u * at;
    for (var k = 0u; k < 3u; k++) {
        out_nodes_set(w + k, bitcast<u32>(b.lo[k]));
        out_nodes_set(w + 4u + k, bitcast<u32>(b.hi[k]));
    }
    out_nodes_set(w + 3u, a);
    out_nodes_set(w + 7u, tag);
}

//    The inner nodes' records: an inner node (its second child, its axis) or a leaf made of
//    its subtree (its first place, its count).
@compute @workgroup_size(WORKGROUP)
fn emit_nodes(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_index(gid, groups);
    if i + 1u >= params.n {
        return;
    }
    let me = down_at(i);
    if me.z != 0u {
        return;
    }
    let f = info_at(i);
    if ((f.w >> 3u) & 1u) == 1u {
        write_node(me.x, node_box(i), me.y, (f.x << 2u) | DFS_LEAF_TAG);
    } else {
        let first = count_and_nodes(ordered_kids(i).x);
        write_node(me.x, node_box(i), me.x + 1u + first.y, f.w & 3u);
    }
}

//    The leaves of one primitive.
@compute @workgroup_size(WORKGROUP)
fn emit_leaves(@builtin(global_invocation_id) gid: vec3<u32>,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let s = thread_index(gid, groups);
    if s >= params.n {
        return;
    }
    let d = place_down_at(s);
    if d.y != NO_NODE {
        write_node(d.y, place_box(s), d.x, (1u << 2u) | DFS_LEAF_TAG);
    }
}

//    The triangles in leaf order (`LeafTri`: each vertex, the mesh index in the first's w).
@compute @workgroup_size(WORKGROUP)
fn emit_tris(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
    let s = thread_index(gid, groups);
    if s >= params.n {
        return;
    }
    let p = pairs_in_at(s).y;
    let w = 12u * place_down_at(s).x;
    for (var v = 0u; v < 3u; v++) {
        let x = vertex(v, p);
        for (var k = 0u; k < 3u; k++) {
            out_tris_set(w + 4u * v + k, bitcast<u32>(x[k]));
        }
        out_tris_set(w + 4u * v + 3u, 0u);
    }
    out_tris_set(w + 3u, ids_at(p));
}
