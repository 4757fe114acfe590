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
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// The triangles' vertices, three floats each: v0[3i..3i+3] is triangle i's first.
@group(0) @binding(1) var<storage, read> v0: array<f32>;
@group(0) @binding(2) var<storage, read> v1: array<f32>;
@group(0) @binding(3) var<storage, read> v2: array<f32>;
// Bounds of the doubled centroids, ordered-encoded: [0..3) the low corner's complement,
// [3..6) the high corner (both only ever raised, from zero).
@group(0) @binding(4) var<storage, read_write> centre_bounds: array<atomic<u32>, 6>;
// (code, primitive) pairs: a sort pass reads one array and writes the other.
@group(0) @binding(5) var<storage, read> pairs_in: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> pairs_out: array<vec2<u32>>;
// Digit counts of every tile, digit-major, then their exclusive prefix sums.
@group(0) @binding(7) var<storage, read_write> table: array<u32>;
// Children of each inner node (LEAF_BIT | place for a leaf).
@group(0) @binding(8) var<storage, read_write> kids: array<vec2<u32>>;
// Parent of inner node i at i, of primitive p at n - 1 + p.
@group(0) @binding(9) var<storage, read_write> parents: array<u32>;
// Inner node boxes, ordered-encoded as in centre_bounds, six words a node.
@group(0) @binding(10) var<storage, read_write> node_boxes: array<atomic<u32>>;

const WORKGROUP: u32 = 64u;
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
        return vec3<f32>(v0[k], v0[k + 1u], v0[k + 2u]);
    }
    if a == 1u {
        return vec3<f32>(v1[k], v1[k + 1u], v1[k + 2u]);
    }
    return vec3<f32>(v2[k], v2[k + 1u], v2[k + 2u]);
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

var<workgroup> reduce: array<array<u32, 6>, WORKGROUP>;

// 1. Bounds of the doubled centroids: each workgroup reduces its own, then raises the
//    global words once.
@compute @workgroup_size(WORKGROUP)
fn bounds(@builtin(global_invocation_id) gid: vec3<u32>,
          @builtin(num_workgroups) groups: vec3<u32>,
          @builtin(local_invocation_index) t: u32) {
    let i = thread_index(gid, groups);
    var mine = array<u32, 6>(0u, 0u, 0u, 0u, 0u, 0u);
    if i < params.n {
        let b = triangle_box(i);
        let c2 = b.lo + b.hi;
        for (var a = 0u; a < 3u; a++) {
            mine[a] = ~ordered(c2[a]);
            mine[a + 3u] = ordered(c2[a]);
        }
    }
    reduce[t] = mine;
    workgroupBarrier();
    for (var half = WORKGROUP / 2u; half > 0u; half /= 2u) {
        if t < half {
            for (var k = 0u; k < 6u; k++) {
                reduce[t][k] = max(reduce[t][k], reduce[t + half][k]);
            }
        }
        workgroupBarrier();
    }
    if t == 0u {
        for (var k = 0u; k < 6u; k++) {
            atomicMax(&centre_bounds[k], reduce[0][k]);
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
        lo[a] = unordered(~atomicLoad(&centre_bounds[a]));
        hi[a] = unordered(atomicLoad(&centre_bounds[a + 3u]));
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
    pairs_out[i] = vec2<u32>(code, i);
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
        count[(pairs_in[e].x >> params.shift) & (RADIX - 1u)] += 1u;
    }
    for (var d = 0u; d < RADIX; d++) {
        table[d * params.tiles + tile] = count[d];
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
        sum += table[k];
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
        let c = table[k];
        table[k] = run;
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
        at[d] = table[d * params.tiles + tile];
    }
    let end = min(params.n, (tile + 1u) * SORT_TILE);
    for (var e = tile * SORT_TILE; e < end; e++) {
        let p = pairs_in[e];
        let d = (p.x >> params.shift) & (RADIX - 1u);
        pairs_out[at[d]] = p;
        at[d] += 1u;
    }
}

// Common prefix length of the keys (code, place) at places i and j; -1 outside.
fn delta(i: i32, j: i32) -> i32 {
    if j < 0 || j >= i32(params.n) {
        return -1;
    }
    let a = pairs_in[u32(i)].x;
    let b = pairs_in[u32(j)].x;
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
            parents[params.n - 1u + pairs_in[u32(place)].y] = node;
        } else {
            pair[side] = u32(place);
            parents[u32(place)] = node;
        }
    }
    kids[node] = pair;
}

// 5. Boxes: each primitive raises its box into its ancestors' words, going up while it
//    raised any. The first to raise a word to its final value goes on, so every node ends
//    with its subtree's bounds, whatever the order (each word's raises are atomic).
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
    var node = parents[params.n - 1u + p];
    loop {
        var raised = false;
        for (var k = 0u; k < 6u; k++) {
            // Every word is raised, whatever the ones before did.
            let old = atomicMax(&node_boxes[6u * node + k], words[k]);
            raised = raised || old < words[k];
        }
        if !raised || node == 0u {
            break;
        }
        node = parents[node];
    }
}
