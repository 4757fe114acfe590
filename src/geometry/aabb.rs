use glam::{Vec3, Vec3A};

use super::Ray;

/// Conservative far-plane widening of Ize 2013 ("Robust BVH Ray Traversal", JCGT 2(2)):
/// t_far is multiplied by 1 + 2·γ(3), γ(n) = n·ε/(1 − n·ε), ε = 2⁻²⁴. Rounded to f32 this is
/// 1 + 3·2⁻²³; the WGSL kernel uses the same literal.
pub const FAR_WIDEN: f32 = 1.000_000_4;

/// |safe_recip(d)| at or above this marks an axis the ray is parallel to. Same in WGSL.
pub const PARALLEL_INV: f32 = 5e29;

/// Axis-aligned bounding box. An empty box has `lo > hi` (lo = +MAX, hi = −MAX).
/// `Zeroable` so that arrays of boxes written in full can be allocated zeroed (pages the
/// threads fault in as they write, not one initialising pass).
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Zeroable)]
pub struct Aabb {
    /// Minimum corner.
    pub lo: Vec3,
    /// Maximum corner.
    pub hi: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (lo = +MAX, hi = −MAX): growing it by anything gives that thing.
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::MAX),
        hi: Vec3::splat(-f32::MAX),
    };

    /// Smallest box containing `points`; [`EMPTY`](Self::EMPTY) for none.
    pub fn from_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    /// This box extended to contain the point `p`.
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    /// Smallest box containing both boxes.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    /// Whether `lo > hi` on some axis (the box holds no point).
    pub fn is_empty(&self) -> bool {
        self.lo.x > self.hi.x || self.lo.y > self.hi.y || self.lo.z > self.hi.z
    }

    /// `hi − lo`; zero for an empty box.
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.hi - self.lo
        }
    }

    /// Midpoint of `lo` and `hi` (meaningless for an empty box).
    pub fn center(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }

    /// Surface area; 0 for an empty box.
    pub fn area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Axis of the largest extent: 0 = x, 1 = y, 2 = z; ties go to the lower axis.
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Whether `o` lies inside this box, faces included.
    pub fn contains(&self, o: &Aabb) -> bool {
        self.lo.cmple(o.lo).all() && self.hi.cmpge(o.hi).all()
    }

    /// Robust slab test: `inv_dir` from [`safe_recip`](super::safe_recip), so no 0·∞ NaN can
    /// arise; far distances moved outwards by the factor `widen` ([`FAR_WIDEN`] robust, 1
    /// plain): t·widen for t ≥ 0, t·(2 − widen) for t < 0 (a box behind the origin, for a
    /// ray with tmin < 0, must not shrink). An axis the ray is parallel to
    /// (|inv| ≥ PARALLEL_INV, i.e. |d| ≲ 2e-30) does not limit the interval when the origin
    /// lies within that slab, boundary planes included, and empties it otherwise — so an
    /// origin exactly on either face plane behaves the same. Returns whether
    /// [max(t_near, tmin), min(t_far, tmax)] is non-empty. WGSL `slab_hit` is the same.
    #[inline]
    pub fn slab_hit(&self, origin: Vec3, inv_dir: Vec3, tmin: f32, tmax: f32, widen: f32) -> bool {
        let (enter, exit) = self.slab_interval(origin, inv_dir, tmin, tmax, widen);
        enter <= exit
    }

    /// The interval [enter, exit] of [`slab_hit`](Self::slab_hit): the ray is in the box
    /// for t in it, and hits the box when enter ≤ exit. WGSL `slab_interval` is the same.
    #[inline]
    pub fn slab_interval(
        &self,
        origin: Vec3,
        inv_dir: Vec3,
        tmin: f32,
        tmax: f32,
        widen: f32,
    ) -> (f32, f32) {
        let t0 = (self.lo - origin) * inv_dir;
        let t1 = (self.hi - origin) * inv_dir;
        let parallel = inv_dir.abs().cmpge(Vec3::splat(PARALLEL_INV));
        let far = t0.max(t1);
        // Outwards whatever t_far's sign: a negative t_far times widen would move inwards.
        let (mut tn, mut tf) = (t0.min(t1), (far * widen).max(far * (2.0 - widen)));
        // Rare (axis-aligned rays): a predictable branch keeps the common path short; the
        // result equals the WGSL select() form on every input.
        if parallel.any() {
            let inside = self.lo.cmple(origin) & origin.cmple(self.hi);
            let big = Vec3::select(inside, Vec3::splat(f32::MAX), Vec3::splat(-f32::MAX));
            tn = Vec3::select(parallel, -big, tn);
            tf = Vec3::select(parallel, big, tf);
        }
        // max/min with the ray bounds last.
        let enter = tn.x.max(tn.y).max(tn.z).max(tmin);
        let exit = tf.x.min(tf.y).min(tf.z).min(tmax);
        (enter, exit)
    }

    /// [`slab_hit`](Self::slab_hit) for a ray with no parallel axis (|inv| < PARALLEL_INV on
    /// all three), in SIMD lanes. No operand can be NaN here (finite box, origin and
    /// reciprocal; overflow gives ±∞, never ∞−∞ or 0·∞), so the lane-wise min/max, which
    /// do not handle NaN, give exactly the scalar result. The CPU tracer's hot path.
    #[inline(always)]
    pub fn slab_hit_nonparallel(
        lo: Vec3A,
        hi: Vec3A,
        origin: Vec3A,
        inv_dir: Vec3A,
        tmin: f32,
        tmax: f32,
        widen: f32,
    ) -> bool {
        let (enter, exit) =
            Self::slab_interval_nonparallel(lo, hi, origin, inv_dir, tmin, tmax, widen);
        enter <= exit
    }

    /// The interval of [`slab_hit_nonparallel`](Self::slab_hit_nonparallel), equal to
    /// [`slab_interval`](Self::slab_interval)'s for such rays (up to the sign of a zero).
    #[inline(always)]
    pub fn slab_interval_nonparallel(
        lo: Vec3A,
        hi: Vec3A,
        origin: Vec3A,
        inv_dir: Vec3A,
        tmin: f32,
        tmax: f32,
        widen: f32,
    ) -> (f32, f32) {
        let t0 = (lo - origin) * inv_dir;
        let t1 = (hi - origin) * inv_dir;
        let tn = t0.min(t1);
        let far = t0.max(t1);
        let tf = (far * widen).max(far * (2.0 - widen));
        // min/max of non-NaN values is exact in any association (±0 may differ, which no
        // comparison below can see).
        let enter = tn.max_element();
        let exit = tf.min_element();
        let enter = if enter > tmin { enter } else { tmin };
        let exit = if exit < tmax { exit } else { tmax };
        (enter, exit)
    }

    /// Convenience wrapper for a whole ray.
    pub fn hit_ray(&self, ray: &Ray) -> bool {
        self.slab_hit(ray.origin, ray.inv_dir(), ray.tmin, ray.tmax, FAR_WIDEN)
    }
}
