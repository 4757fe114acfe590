//! Every numerical-robustness knob in one struct, handed the same way to the CPU tracers,
//! the CPU renderer and the GPU kernels (as override constants), so that a knob can be
//! turned and priced without touching a tracer.

use super::TriangleTest;

/// Relative slack on the best hit's t when boxes are pruned against it (2⁻²⁰, about 8 ulps,
/// more than the slab test's own rounding). A box's entry distance and a triangle's t are
/// computed by different operations and round differently, so a box holding a triangle at
/// exactly the best t can compute an entry beyond it; cutting that box would let traversal
/// order, not the index, decide a tie. Traversals cut against
/// `prune_bound(t + t_error_bound(…))`: the triangle's own error bound, then this slack.
pub const TIE_SLACK: f32 = 1.0 / 1_048_576.0;

/// The bound boxes are tested against while the best hit is at `best_t`: `best_t` grown by
/// [`TIE_SLACK`] of its magnitude, never past `f32::MAX`: a ray's tmax of +∞ (a miss so far)
/// gives `f32::MAX`, not ∞ − ∞ = NaN, which would cull every box. WGSL `prune_bound` in
/// shaders/lib/common.wgsl is the same.
#[inline(always)]
pub fn prune_bound(best_t: f32) -> f32 {
    let b = best_t.min(f32::MAX);
    let a = b.abs();
    b + (a * TIE_SLACK).min(f32::MAX - a)
}

/// The ray–box slab test.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SlabTest {
    /// Far plane widened by 1 + 2γ(3) (Ize 2013): no false misses from rounding.
    #[default]
    Robust,
    /// The textbook test: t_far unwidened (faster to state, can miss grazing rays).
    Plain,
}

/// How secondary rays (shadow, bounce) leave the surface they start on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum RayOffset {
    /// Along the normal by the hit point's own error bound, computed from the triangle's
    /// vertices (pbrt-v4 §6.8.6): no self-intersection at any position or scale.
    #[default]
    ErrorBound,
    /// Along the normal by a fixed epsilon, [`FIXED_OFFSET`] of the scene's diagonal (the
    /// textbook choice: acne where it is too small, tunnelling where too large).
    #[cfg_attr(
        feature = "cli",
        value(
            help = "Along the normal by 1e-4 of the scene's diagonal (the textbook choice: \
                      acne where too small, tunnelling where too large)"
        )
    )]
    Fixed,
    /// No offset: the ray starts on the surface (shows self-intersection).
    None,
}

/// The fixed epsilon of [`RayOffset::Fixed`], relative to the scene's bounding-box diagonal.
pub const FIXED_OFFSET: f32 = 1e-4;

impl RayOffset {
    /// Code in the render kernel's `RAY_OFFSET` override.
    pub fn code(self) -> u32 {
        match self {
            RayOffset::ErrorBound => 0,
            RayOffset::Fixed => 1,
            RayOffset::None => 2,
        }
    }
}

/// The arithmetic of the CPU's triangle tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Precision {
    /// f32, the GPU's arithmetic: CPU and GPU agree bit for bit.
    #[default]
    F32,
    /// f64: the oracle's watertight test (`trace::oracle`) as the tracer's triangle test,
    /// whatever [`TriangleTest`] says, over the same f32 boxes. CPU only (the BVH's twin):
    /// it prices the f32 error itself.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The f64 oracle's watertight test over the same f32 boxes, whatever \
                      --triangle-test says (CPU only: prices the f32 error itself)"
        )
    )]
    F64,
}

/// The robustness settings of one trace or render. `Default` is the robust setting of
/// every knob.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Robustness {
    /// Ray–triangle test.
    pub triangle_test: TriangleTest,
    /// Ray–box test.
    pub slab_test: SlabTest,
    /// Origin offset of secondary rays (renderer only).
    pub ray_offset: RayOffset,
    /// GPU only: shader modules with bounds checks and loop bounding (`false` = trusted
    /// modules, offered only for a BVH the layout validated).
    pub checked_module: bool,
    /// CPU only: f32 or f64 triangle tests (a GPU device refuses f64).
    pub precision: Precision,
}

impl Default for Robustness {
    fn default() -> Self {
        Robustness {
            triangle_test: TriangleTest::Watertight,
            slab_test: SlabTest::Robust,
            ray_offset: RayOffset::ErrorBound,
            checked_module: true,
            precision: Precision::F32,
        }
    }
}

impl Robustness {
    /// The factor t_far is multiplied by in the slab test.
    pub fn far_widen(&self) -> f32 {
        match self.slab_test {
            SlabTest::Robust => super::FAR_WIDEN,
            SlabTest::Plain => 1.0,
        }
    }

    /// Whether traversals reject a hit whose t is within its own error bound of the origin
    /// (`t ≤ t_error_bound`, pbrt-v4): it may lie behind the origin, as the surface a
    /// secondary ray leaves does. Part of the error-bound offset; off for the fast settings.
    pub fn rejects_near_hits(&self) -> bool {
        self.ray_offset == RayOffset::ErrorBound
    }

    /// Whether traversals reject near hits ([`rejects_near_hits`](Self::rejects_near_hits))
    /// of `ray`: only of a ray whose interval starts at its origin or ahead (tmin ≥ 0). One
    /// that asks for hits behind its origin (tmin < 0) gets the surface it starts on.
    #[inline(always)]
    pub fn rejects_near_hits_of(&self, ray: &super::Ray) -> bool {
        self.rejects_near_hits() && ray.tmin >= 0.0
    }

    /// Refuses the settings no GPU kernel has (f64 precision), naming the fix.
    pub fn check_gpu(&self) -> crate::Result<()> {
        if self.precision == Precision::F64 {
            return Err(crate::Error::Usage(
                "f64 precision runs on the CPU only (the GPU kernels compute in f32): \
                 use --device cpu or --precision f32"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The WGSL override constants that carry these settings (declared in
    /// `shaders/lib/common.wgsl`).
    pub fn overrides(&self) -> [(&'static str, f64); 4] {
        let b = |x: bool| if x { 1.0 } else { 0.0 };
        [
            (
                "MOLLER_TRUMBORE",
                b(self.triangle_test == TriangleTest::MollerTrumbore),
            ),
            ("ROBUST_SLAB", b(self.slab_test == SlabTest::Robust)),
            ("RAY_OFFSET", self.ray_offset.code() as f64),
            ("REJECT_NEAR_HITS", b(self.rejects_near_hits())),
        ]
    }
}
