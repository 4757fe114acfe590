// Types and tests shared by every lancer kernel. Each struct mirrors a #[repr(C)] Rust type;
// tests/layout.rs checks offsets and sizes with naga. Each function mirrors a Rust one,
// same operations in the same order (named in the comment), so CPU and GPU agree bit for bit.

// geometry::Ray
struct Ray {
    origin: vec3<f32>,
    tmin: f32,
    dir: vec3<f32>,
    tmax: f32,
}

// geometry::Hit
struct Hit {
    t: f32,
    prim: u32,
    u: f32,
    v: f32,
}

// Constants shared with Rust (MISS, STACK_SIZE, RECIP_FLOOR, FAR_WIDEN, PARALLEL_INV, BIG,
// ...) come from the prelude gpu::shaders generates from the Rust definitions.

// geometry::Robustness, as override constants (Robustness::overrides).
override MOLLER_TRUMBORE: bool = false;  // TriangleTest::MollerTrumbore instead of watertight
override ROBUST_SLAB: bool = true;       // SlabTest::Robust: far plane widened by FAR_WIDEN
override RAY_OFFSET: u32 = 0u;           // RayOffset::code (render kernel)
override REJECT_NEAR_HITS: bool = true;  // Robustness::rejects_near_hits

// glam's Vec3::dot and Vec3::cross, operation for operation. WGSL's dot() and cross() are
// the driver's own: a hardware driver computes them with fused multiply-adds, whatever the
// NoContraction on every other operation (gpu::exact_spirv), so no kernel calls them.
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

// Finite test on bits: NaN/Inf comparisons are not reliable in WGSL.
fn is_finite_bits(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) < 0x7f800000u;
}

// Ray::is_valid
fn ray_is_valid(r: Ray) -> bool {
    let o = bitcast<vec3<u32>>(r.origin) & vec3<u32>(0x7fffffffu);
    let near = o <= vec3<u32>(bitcast<u32>(MAX_ORIGIN));
    let fin = near.x && near.y && near.z
        && is_finite_bits(r.dir.x) && is_finite_bits(r.dir.y) && is_finite_bits(r.dir.z)
        && is_finite_bits(r.tmin);
    let tmax_ok = (bitcast<u32>(r.tmax) & 0x7fffffffu) <= 0x7f800000u;
    let d = bitcast<vec3<u32>>(r.dir) & vec3<u32>(0x7fffffffu);
    let long_enough = max(d.x, max(d.y, d.z)) >= bitcast<u32>(MIN_DIR);
    return fin && tmax_ok && long_enough && r.tmin <= r.tmax;
}

// safe_recip: ±1/max(|d|, RECIP_FLOOR), sign of d kept (−0.0 included, by its sign bit).
fn safe_recip(d: f32) -> f32 {
    var m = d;
    if abs(d) < RECIP_FLOOR {
        m = select(RECIP_FLOOR, -RECIP_FLOOR, (bitcast<u32>(d) & 0x80000000u) != 0u);
    }
    return 1.0 / m;
}

fn safe_recip3(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(safe_recip(d.x), safe_recip(d.y), safe_recip(d.z));
}

// Aabb::slab_interval with Robustness::far_widen (an axis the ray is parallel to bounds nothing
// if the origin is in its slab): [enter, exit] of the ray in the box, hit when enter <= exit.
fn slab_interval(lo: vec3<f32>, hi: vec3<f32>, origin: vec3<f32>, inv_dir: vec3<f32>, tmin: f32, tmax: f32) -> vec2<f32> {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let parallel = abs(inv_dir) >= vec3<f32>(PARALLEL_INV);
    let inside = (lo <= origin) & (origin <= hi);
    let big = select(vec3<f32>(-BIG), vec3<f32>(BIG), inside);
    let tn = select(min(t0, t1), -big, parallel);
    let widen = select(1.0, FAR_WIDEN, ROBUST_SLAB);
    // Outwards whatever t_far's sign (Aabb::slab_hit).
    let far = max(t0, t1);
    let tf = select(max(far * widen, far * (2.0 - widen)), big, parallel);
    let enter = max(max(max(tn.x, tn.y), tn.z), tmin);
    let exit = min(min(min(tf.x, tf.y), tf.z), tmax);
    return vec2<f32>(enter, exit);
}

// Aabb::slab_hit
fn slab_hit(lo: vec3<f32>, hi: vec3<f32>, origin: vec3<f32>, inv_dir: vec3<f32>, tmin: f32, tmax: f32) -> bool {
    let i = slab_interval(lo, hi, origin, inv_dir, tmin, tmax);
    return i.x <= i.y;
}

// slab_hit for a ray with no axis it is parallel to, given each axis's planes in the order the
// ray meets them (`near` the low plane where the direction is positive, the high one where it
// is negative): the same verdict with fewer operations (CPU: geometry::SlabRay4). Rounding
// keeps the order of the two planes' distances, so `near` gives slab_interval's min and `far`
// its max; the widening never decreases, so widening the least exit equals the least widened
// exit.
fn slab_hit_ordered(near: vec3<f32>, far: vec3<f32>, origin: vec3<f32>, inv_dir: vec3<f32>, tmin: f32, tmax: f32) -> bool {
    let tn = (near - origin) * inv_dir;
    let tf = (far - origin) * inv_dir;
    let widen = select(1.0, FAR_WIDEN, ROBUST_SLAB);
    let least = min_not_nan(min_not_nan(tf.x, tf.y), tf.z);
    let enter = max_not_nan(max_not_nan(max_not_nan(tn.x, tn.y), tn.z), tmin);
    let exit = min_not_nan(max_not_nan(least * widen, least * (2.0 - widen)), tmax);
    return enter <= exit;
}

// min and max of two numbers neither of which is NaN, as a compare and a select. lavapipe
// compiles WGSL's min and max with a NaN check (three instructions, not two); the slab
// distances here may be ±inf but are never NaN (finite reciprocals, finite planes and
// origins, a finite widening), and the verdict does not depend on which zero a tie returns.
// On this project's machine (Mesa 25 lavapipe) that gave ~1.05x rays/s on cwbvh's primary
// and shadow rays.
fn min_not_nan(a: f32, b: f32) -> f32 {
    return select(b, a, a < b);
}

fn max_not_nan(a: f32, b: f32) -> f32 {
    return select(b, a, a > b);
}

// WatertightRay: permutation k (dominant axis last) and shear s.
struct Watertight {
    kx: u32,
    ky: u32,
    kz: u32,
    s: vec3<f32>,
}

// WatertightRay::new
fn watertight_setup(dir: vec3<f32>) -> Watertight {
    let a = abs(dir);
    var kz = 2u;
    if a.x >= a.y && a.x >= a.z {
        kz = 0u;
    } else if a.y >= a.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if dir[kz] < 0.0 {
        let tmp = kx;
        kx = ky;
        ky = tmp;
    }
    let sz = 1.0 / dir[kz];
    return Watertight(kx, ky, kz, vec3<f32>(dir[kx] * sz, dir[ky] * sz, sz));
}

// Result of a triangle test: ok, t, u (weight of v1), v (weight of v2), and t's error bound
// as the quotient num / det (geometry::TriHit; its in_front is computed by
// maybe_behind_origin, only where it is needed).
struct TriHit {
    ok: bool,
    t: f32,
    u: f32,
    v: f32,
    num: f32,
    det: f32,
}

// Whether the near-hit rule rejects hit h of triangle (v0, v1, v2) for ray r
// (Robustness::rejects_near_hits_of and TriHit::maybe_behind_origin): under REJECT_NEAR_HITS,
// for a ray whose interval starts at its origin or ahead (tmin ≥ 0), a hit whose t is within
// its error bound of 0. The Rust test computes in_front (geometry::grazing_in_front) inside
// the watertight test; here it is computed from the same values, in the same operations,
// only for the rare hit that needs it, so that kernels without the near-hit rule, and every
// other hit, don't carry it.
fn rejects_near_hit(h: TriHit, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, r: Ray,
                    w: Watertight) -> bool {
    if !REJECT_NEAR_HITS || !(r.tmin >= 0.0) {
        return false;
    }
    let origin = r.origin;
    if !(abs(h.t) * h.det <= h.num) {
        return false;
    }
    if MOLLER_TRUMBORE {
        return true;
    }
    let a = v0 - origin;
    let b = v1 - origin;
    let c = v2 - origin;
    let sa = vec3<f32>(a[w.kx] - w.s.x * a[w.kz], a[w.ky] - w.s.y * a[w.kz], a[w.kz]);
    let sb = vec3<f32>(b[w.kx] - w.s.x * b[w.kz], b[w.ky] - w.s.y * b[w.kz], b[w.kz]);
    let sc = vec3<f32>(c[w.kx] - w.s.x * c[w.kz], c[w.ky] - w.s.y * c[w.kz], c[w.kz]);
    let mzu = max(max(abs(a[w.kz]), abs(b[w.kz])), abs(c[w.kz]));
    return !grazing_in_front(sa, sb, sc, w.s.z, h.t, mzu);
}

// geometry::grazing_in_front
fn grazing_in_front(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, sz: f32, t: f32, mzu: f32) -> bool {
    if !(sz * a.z > 0.0 && sz * b.z > 0.0 && sz * c.z > 0.0) {
        return false;
    }
    let e1 = b - a;
    let e2 = c - a;
    let nx = e1.y * e2.z - e1.z * e2.y;
    let ny = e1.z * e2.x - e1.x * e2.z;
    let nz = e1.x * e2.y - e1.y * e2.x;
    let p = vec3<f32>(0.0 - a.x, 0.0 - a.y, t / sz - a.z);
    let plane = nx * p.x + ny * p.y + nz * p.z;
    let n = max(max(abs(nx), abs(ny)), abs(nz));
    let l1 = max_abs3(e1);
    let l2 = max_abs3(e2);
    let noise = max_abs3(p) * (l1 * l2 + mzu * (l1 + l2));
    return abs(plane) + 0.125 * NEAR_HIT_PLANE_REL * noise <= NEAR_HIT_PLANE_REL * mzu * n;
}

fn max_abs3(v: vec3<f32>) -> f32 {
    return max(max(abs(v.x), abs(v.y)), abs(v.z));
}

// TriHit::t_error
fn t_error(h: TriHit) -> f32 {
    if h.num * 1e-30 >= h.det {
        return 1e30;
    }
    return h.num / h.det;
}

// TriHit::prune
fn hit_prune(h: TriHit) -> f32 {
    return prune_bound(h.t + t_error(h));
}

// intersect_watertight (Woop, Benthin & Wald 2013)
fn intersect_watertight(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, origin: vec3<f32>, w: Watertight, tmin: f32, tmax: f32) -> TriHit {
    var res = TriHit(false, 0.0, 0.0, 0.0, 0.0, 1.0);
    let a = v0 - origin;
    let b = v1 - origin;
    let c = v2 - origin;
    let ax = a[w.kx] - w.s.x * a[w.kz];
    let ay = a[w.ky] - w.s.y * a[w.kz];
    let bx = b[w.kx] - w.s.x * b[w.kz];
    let by = b[w.ky] - w.s.y * b[w.kz];
    let cx = c[w.kx] - w.s.x * c[w.kz];
    let cy = c[w.ky] - w.s.y * c[w.kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let ww = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || ww < 0.0) && (u > 0.0 || v > 0.0 || ww > 0.0) {
        return res;
    }
    let det = u + v + ww;
    if det == 0.0 {
        return res;
    }
    let az = w.s.z * a[w.kz];
    let bz = w.s.z * b[w.kz];
    let cz = w.s.z * c[w.kz];
    let tt = u * az + v * bz + ww * cz;
    let t = tt / det;
    if t >= tmin && t <= tmax {
        let mx = max(max(abs(ax), abs(bx)), abs(cx));
        let my = max(max(abs(ay), abs(by)), abs(cy));
        let mz = max(max(abs(az), abs(bz)), abs(cz));
        let mzu = max(max(abs(a[w.kz]), abs(b[w.kz])), abs(c[w.kz]));
        let me = max(max(abs(u), abs(v)), abs(ww));
        res = TriHit(true, t, v / det, ww / det, t_error_numerator(mx, my, mz, mzu, me), abs(det));
    }
    return res;
}

// intersect_moller_trumbore
fn intersect_moller_trumbore(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, r: Ray, tmin: f32, tmax: f32) -> TriHit {
    var res = TriHit(false, 0.0, 0.0, 0.0, 0.0, 1.0);
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = cross3(r.dir, e2);
    let det = dot3(e1, p);
    if det == 0.0 {
        return res;
    }
    let inv = 1.0 / det;
    let s = r.origin - v0;
    let u = dot3(s, p) * inv;
    if !(u >= 0.0 && u <= 1.0) {
        return res;
    }
    let q = cross3(s, e1);
    let v = dot3(r.dir, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return res;
    }
    let t = dot3(e2, q) * inv;
    if t >= tmin && t <= tmax {
        res = TriHit(true, t, u, v, 0.0, 1.0);
    }
    return res;
}

// intersect_triangle: the test Robustness::triangle_test chooses.
fn intersect_tri(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, r: Ray, w: Watertight, tmin: f32, tmax: f32) -> TriHit {
    if MOLLER_TRUMBORE {
        var h = intersect_moller_trumbore(v0, v1, v2, r, tmin, tmax);
        if h.ok {
            h.num = t_error_bound(v0, v1, v2, r.origin, w);
        }
        return h;
    }
    return intersect_watertight(v0, v1, v2, r.origin, w, tmin, tmax);
}

// geometry::t_error_bound (pbrt-v4 §6.8.7): how far the exact t of a watertight hit may lie
// beyond the computed one.
fn gamma_f(n: f32) -> f32 {
    return n * HALF_EPSILON / (1.0 - n * HALF_EPSILON);
}

fn t_error_bound(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, origin: vec3<f32>, w: Watertight) -> f32 {
    var verts = array<vec3<f32>, 3>(v0 - origin, v1 - origin, v2 - origin);
    var sx = array<f32, 3>(0.0, 0.0, 0.0);
    var sy = array<f32, 3>(0.0, 0.0, 0.0);
    var mx = 0.0;
    var my = 0.0;
    var mz = 0.0;
    var mzu = 0.0;
    for (var i = 0; i < 3; i += 1) {
        let a = verts[i];
        let x = a[w.kx] - w.s.x * a[w.kz];
        let y = a[w.ky] - w.s.y * a[w.kz];
        let z = w.s.z * a[w.kz];
        mx = max(mx, abs(x));
        my = max(my, abs(y));
        mz = max(mz, abs(z));
        mzu = max(mzu, abs(a[w.kz]));
        sx[i] = x;
        sy[i] = y;
    }
    let u = sx[2] * sy[1] - sy[2] * sx[1];
    let v = sx[0] * sy[2] - sy[0] * sx[2];
    let ww = sx[1] * sy[0] - sy[1] * sx[0];
    let me = max(max(abs(u), abs(v)), abs(ww));
    return t_error(TriHit(true, 0.0, 0.0, 0.0, t_error_numerator(mx, my, mz, mzu, me), abs(u + v + ww)));
}

// t_error_numerator
fn t_error_numerator(mx: f32, my: f32, mz: f32, mzu: f32, me: f32) -> f32 {
    let dz = gamma_f(3.0) * mz;
    let dx = gamma_f(5.0) * (mx + mzu);
    let dy = gamma_f(5.0) * (my + mzu);
    let de = 2.0 * (gamma_f(2.0) * mx * my + dy * mx + dx * my);
    return 3.0 * (gamma_f(3.0) * me * mz + de * mz + dz * me);
}

// geometry::prune_bound: the best t grown by TIE_SLACK of its magnitude, never past BIG
// (a tmax of +inf gives BIG).
fn prune_bound(best_t: f32) -> f32 {
    let b = min(best_t, BIG);
    let a = abs(b);
    return b + min(a * TIE_SLACK, BIG - a);
}

// Hit::beats — the tie rule: smaller t, then smaller original index.
fn beats(t: f32, prim: u32, best_t: f32, best_prim: u32) -> bool {
    return t < best_t || (t == best_t && prim < best_prim);
}

// geometry::Affine::point and Affine::vector (rows m0, m1, m2), in the same operation
// order, unfused.
fn affine_point(m0: vec4<f32>, m1: vec4<f32>, m2: vec4<f32>, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(m0.x * p.x + m0.y * p.y + m0.z * p.z + m0.w,
                     m1.x * p.x + m1.y * p.y + m1.z * p.z + m1.w,
                     m2.x * p.x + m2.y * p.y + m2.z * p.z + m2.w);
}

fn affine_vector(m0: vec4<f32>, m1: vec4<f32>, m2: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(m0.x * v.x + m0.y * v.y + m0.z * v.z,
                     m1.x * v.x + m1.y * v.y + m1.z * v.z,
                     m2.x * v.x + m2.y * v.y + m2.z * v.z);
}
