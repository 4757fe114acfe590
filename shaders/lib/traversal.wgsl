// What every layout's traversal reads and counts: the layout's two word arrays in the chosen
// BVH memory (gpu::BvhMemory), the shared leaf triangles (accel::LeafTri), and the work
// counters. A layout's WGSL defines `traverse(r: Ray, any_hit: bool) -> Hit` on top of it.

override COUNT_STATS: bool = false;  // count nodes visited / triangles tested

// Both arrays are read as 16-byte words. lavapipe compiles every storage-buffer load into a
// loop over the SIMD lanes, one loop per load instruction: vec4 loads instead of one per
// field are ~15% more rays/s there.
//
// The same words live either in storage buffers or, with BVH_TEXTURES, in read-only
// rgba32uint storage textures of TEXEL_ROW texels a row, which lavapipe loads with a gather
// (~18% more rays/s). Both pairs are declared; the unused pair is a placeholder. A buffer
// bigger than one storage binding is bound in parts: node_buffer_word and tri_buffer_word
// (generated for the parts there are, gpu::BufferParts) read part 0 here or the others.
override BVH_TEXTURES: bool = false;
@group(0) @binding(BINDING_NODE_WORDS) var<storage, read> node_words: array<vec4<u32>>;
@group(0) @binding(BINDING_TRI_WORDS) var<storage, read> tri_words: array<vec4<u32>>;
@group(0) @binding(BINDING_NODE_TEXELS) var node_texels: texture_storage_2d<rgba32uint, read>;
@group(0) @binding(BINDING_TRI_TEXELS) var tri_texels: texture_storage_2d<rgba32uint, read>;

// Two-level scenes (accel::instances): the bottom levels' arrays lie one after another in
// the node and triangle arrays, the top level's after them. The top level's walk sets the
// offsets of the bottom level it enters; a layout's traversal reads its own words through
// node_word and tri_word as always. Compiled out (INSTANCES false) in a one-level scene.
override INSTANCES: bool = false;
var<private> bottom_node_base: u32;  // in words
var<private> bottom_tri_base: u32;   // in words
// The prune bound of the last hit a leaf step took (hit_prune): the top level carries it on.
var<private> taken_prune: f32;
// The first triangle of the instance being walked (original indices over all instances).
var<private> bottom_prim_base: u32;

// Alpha masks (accel::HitMask): a hit the tie rule would take counts only where the kernel's
// alpha_keeps(prim, u, v) keeps it (a render kernel whose scene has masked materials), for
// closest-hit and any-hit alike. Kernels without materials keep every hit. Compiled out
// (ALPHA_MASK false) where no material is masked.
override ALPHA_MASK: bool = false;

// Whether the alpha mask keeps triangle `prim`'s hit h (`prim` as the leaf stores it).
fn alpha_passes(prim: u32, h: TriHit) -> bool {
    if !ALPHA_MASK {
        return true;
    }
    var p = prim;
    if INSTANCES {
        p += bottom_prim_base;
    }
    return alpha_keeps(p, h.u, h.v);
}

// Word i of the node array as a whole (the top level's reads).
fn array_node_word(i: u32) -> vec4<u32> {
    if BVH_TEXTURES {
        return textureLoad(node_texels, vec2<u32>(i % TEXEL_ROW, i / TEXEL_ROW));
    }
    return node_buffer_word(i);
}

fn node_word(i: u32) -> vec4<u32> {
    if INSTANCES {
        return array_node_word(i + bottom_node_base);
    }
    return array_node_word(i);
}

fn tri_word(i: u32) -> vec4<u32> {
    var j = i;
    if INSTANCES {
        j += bottom_tri_base;
    }
    if BVH_TEXTURES {
        return textureLoad(tri_texels, vec2<u32>(j % TEXEL_ROW, j / TEXEL_ROW));
    }
    return tri_buffer_word(j);
}

// accel::LeafTri: vertices, original triangle index in v0's w slot.
struct Tri {
    v0: vec3<f32>,
    prim: u32,
    v1: vec3<f32>,
    pad1: u32,
    v2: vec3<f32>,
    pad2: u32,
}

fn load_tri(i: u32) -> Tri {
    return tri_from_words(tri_word(3u * i), tri_word(3u * i + 1u), tri_word(3u * i + 2u));
}

// A Tri from its three words (for traversals that load the words some other way).
fn tri_from_words(a: vec4<u32>, b: vec4<u32>, c: vec4<u32>) -> Tri {
    return Tri(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w,
               bitcast<vec3<f32>>(c.xyz), c.w);
}

// One triangle of the leaf step: a hit that beats *best by the tie rule replaces it and
// moves *prune; returns whether it did.
fn test_tri(tri: Tri, r: Ray, w: Watertight, best: ptr<function, Hit>,
            prune: ptr<function, f32>) -> bool {
    let h = intersect_tri(tri.v0, tri.v1, tri.v2, r, w, r.tmin, (*best).t);
    if h.ok && beats(h.t, tri.prim, (*best).t, (*best).prim)
        && !rejects_near_hit(h, tri.v0, tri.v1, tri.v2, r, w) && alpha_passes(tri.prim, h) {
        *best = Hit(h.t, tri.prim, h.u, h.v);
        *prune = hit_prune(h);
        if INSTANCES {
            taken_prune = *prune;
        }
        return true;
    }
    return false;
}

// The leaf step of every layout's traversal (accel::leaf_tri::LeafRay::test_leaf, step for step):
// tests triangles first..first+count in order with test_tri. Returns true when an any-hit
// query is answered.
fn test_leaf(first: u32, count: u32, r: Ray, w: Watertight, any_hit: bool,
             best: ptr<function, Hit>, prune: ptr<function, f32>) -> bool {
    let end = first + count;
    for (var i = first; i < end; i += 1u) {
        let tri = load_tri(i);
        if COUNT_STATS {
            n_tris += 1u;
        }
        if test_tri(tri, r, w, best, prune) && any_hit {
            return true;
        }
    }
    return false;
}

// Work done by the last traverse() call (read when COUNT_STATS).
var<private> n_nodes: u32;
var<private> n_tris: u32;

// Set by traverse() when it ends by itself (its stack empty, or an any-hit answered). Left
// false when the driver cut it short: lavapipe up to Mesa 22 ends every loop of an
// invocation once 65,535 loop iterations have run in all, so a ray through ~50,000
// coincident triangles stops early. Callers mark such rays (gpu::INCOMPLETE) instead of
// returning a wrong hit. A traversal whose inner loops the driver may cut (a leaf's
// triangles, a pop, a node's slots) ends with traversal_end.
var<private> traversal_done: bool;

// Whether the driver has cut loops of this invocation short. lavapipe up to Mesa 22 counts
// the loop iterations of an invocation (all its loops, its SIMD lanes together, never reset)
// and, once 65,535 have run, ends every loop after the iteration it is in, each as if it had
// finished: the traversal loop, but also a leaf's triangle loop, a pop loop, the render
// kernel's own loops, where nothing in the loop's state need show it. From then on every
// loop stops after one iteration, so a loop that needs two shows it (with one iteration
// left before the cap it flags what was not cut: harmless). `start` is any value the
// compiler cannot know, so that the loop is not unrolled away (with a constant start it is:
// Mesa 22 then never reports a cut).
fn loops_were_cut(start: u32) -> bool {
    var n = start;
    loop {
        n += 1u;
        if n - start >= 2u {
            break;
        }
    }
    return n - start < 2u;
}

// Where a traversal ends by itself (its stack empty, or an any-hit answered): done, unless
// the driver has cut loops of this invocation short (loops_were_cut; `salt` any value of the
// ray). A cut inner loop ends as if it had finished, and the traversal can then reach its
// end with work left undone: the 8-wide traversals' pop loop, cut on an entry beyond the
// prune bound, reads as an empty stack; a leaf's loop as its last triangle tested; cwbvh's
// triangle loop as the node's last. Asked where the lane ends, not after the loop: a lane
// that ended before another lane's cut is done.
fn traversal_end(salt: u32) {
    traversal_done = !loops_were_cut(salt);
}

// The start every per-ray traversal (and subgroup_start) takes, with whether its ray is valid:
// resets the work counters and marks an invalid ray done (a miss). Returns `valid`.
fn traversal_start(valid: bool) -> bool {
    traversal_done = !valid;
    if COUNT_STATS {
        n_nodes = 0u;
        n_tris = 0u;
    }
    return valid;
}
