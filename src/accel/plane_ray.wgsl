// plane_ray: the WGSL twin of src/accel/plane_ray.rs, shared by the traversals that clip a
// ray's t-interval at axis-aligned planes (kdtree.wgsl, bih.wgsl). Every function names its
// Rust twin and does the same operations in the same order. PLANE_STACK_SIZE (the
// structure's deepest level) is generated in front (plane_ray::traversal_wgsl).

// The box the traversal clips the ray to first: the structure's bounds
// (plane_ray::root_box_overrides).
override PLANE_LO_X: f32 = 0.0;
override PLANE_LO_Y: f32 = 0.0;
override PLANE_LO_Z: f32 = 0.0;
override PLANE_HI_X: f32 = 0.0;
override PLANE_HI_Y: f32 = 0.0;
override PLANE_HI_Z: f32 = 0.0;

// widen_lo
fn widen_lo(t: f32) -> f32 {
    return -prune_bound(-t);
}

// widen_hi
fn widen_hi(t: f32) -> f32 {
    return prune_bound(t);
}

// finite
fn finite(t: f32) -> f32 {
    return clamp(t, -BIG, BIG);
}

// pow2_scales: 2^k
fn pow2(k: i32) -> f32 {
    return bitcast<f32>(u32(k + 127) << 23u);
}

// PlaneRay: a valid ray in the traversal's units, t' = t / 2^k along the direction scaled
// by 2^k (largest component in [1, 2)).
struct PlaneRay {
    o: vec3<f32>,
    inv: vec3<f32>,
    tmin: f32,
    tmax: f32,
    unscale: f32,
}

// PlaneRay::new
fn plane_ray(r: Ray) -> PlaneRay {
    let a = abs(r.dir);
    let e = i32((bitcast<u32>(max(max(a.x, a.y), a.z)) >> 23u) & 0xffu) - 127;
    let k = clamp(-e, -126, 126);
    let unscale = pow2(-k);
    let inv = safe_recip3(r.dir * pow2(k));
    return PlaneRay(r.origin, inv, finite(r.tmin * unscale), finite(min(r.tmax, BIG) * unscale),
                    unscale);
}

// PlaneRay::parallel
fn plane_parallel(pr: PlaneRay, k: u32) -> bool {
    return abs(pr.inv[k]) >= PARALLEL_INV;
}

// PlaneRay::scaled
fn plane_scaled(pr: PlaneRay, t: f32) -> f32 {
    return finite(t * pr.unscale);
}

// PlaneRay::root_interval: the ray's widened [near, far] interval in a box (x, y), z = 1
// when it is not empty and the ray meets the box.
fn plane_root_interval(pr: PlaneRay, lo: vec3<f32>, hi: vec3<f32>) -> vec3<f32> {
    var tn = pr.tmin;
    var tf = pr.tmax;
    for (var k = 0u; k < 3u; k += 1u) {
        let o = pr.o[k];
        let inv = pr.inv[k];
        if plane_parallel(pr, k) {
            if o < lo[k] || o > hi[k] {
                return vec3<f32>(tn, tf, 0.0);
            }
            continue;
        }
        let t0 = finite((lo[k] - o) * inv);
        let t1 = finite((hi[k] - o) * inv);
        let fwd = inv > 0.0;
        tn = max(tn, widen_lo(select(t1, t0, fwd)));
        tf = min(tf, widen_hi(select(t0, t1, fwd)));
    }
    return vec3<f32>(tn, tf, select(0.0, 1.0, tn <= tf));
}

// A pending far child and the ray's interval in it: the entries of the traversals' stacks,
// which they keep inline (an array and its length), as their twins do: a call to pop cost
// lavapipe 3-5 % of their rays/s, a stack type with its length inside it the CPU twin 8 %.
struct PlanePending {
    node: u32,
    lo: f32,
    hi: f32,
}
