//! What a ray asks of an acceleration structure, and the work it cost.

/// What a ray asks for. The interval is the ray's own [tmin, tmax].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Query {
    /// The nearest hit in [tmin, tmax] (ties: smaller original index).
    #[default]
    Closest,
    /// Any hit in [tmin, tmax]: the first one met in traversal order (shadow rays).
    Any,
}

/// A test a triangle's hit must also pass to count, asked where the tie rule would take the
/// hit: an alpha mask cuts holes in surfaces (render::scene materials). A hit it drops is
/// skipped by closest-hit and any-hit queries alike, as if the triangle were not there at
/// that point. WGSL twin: the kernel's `alpha_keeps`, called by `test_tri`
/// (shaders/lib/traversal.wgsl) when `ALPHA_MASK` is on.
pub trait HitMask: Sync {
    /// Whether triangle `prim` (original index; over all instances in a two-level scene)
    /// is solid at the barycentric coordinates (u, v) of a hit.
    fn keeps(&self, prim: u32, u: f32, v: f32) -> bool;
}

/// The mask a traversal tests hits with: None (the usual case) tests nothing.
pub type Mask<'a> = Option<&'a dyn HitMask>;

/// Work done for one ray: nodes (or cells) visited and triangles tested.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct RayStats {
    /// Nodes popped and box-tested (cells stepped through, for grids).
    pub nodes: u32,
    /// Ray–triangle tests.
    pub tris: u32,
}

impl RayStats {
    /// Mean nodes and triangles per ray over a batch.
    pub fn means(stats: &[RayStats]) -> (f64, f64) {
        let n = stats.len().max(1) as f64;
        let nodes: u64 = stats.iter().map(|s| s.nodes as u64).sum();
        let tris: u64 = stats.iter().map(|s| s.tris as u64).sum();
        (nodes as f64 / n, tris as f64 / n)
    }
}
