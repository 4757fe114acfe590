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
