/// Primitive index of a miss, in the API and in hit files.
pub const MISS: u32 = u32::MAX;

/// Result of tracing one ray. `prim` is the original (file-order) triangle index or
/// [`MISS`]; on a miss `t` is the ray's tmax and `u = v = 0`.
/// `u`, `v` are the barycentric weights of vertices 1 and 2.
/// WGSL twin: `Hit` in shaders/lib/common.wgsl; tests/layout.rs checks the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Hit {
    /// Ray parameter of the hit (point = origin + t·dir); the ray's tmax on a miss.
    pub t: f32,
    /// Original (file-order) triangle index, or [`MISS`].
    pub prim: u32,
    /// Barycentric weight of vertex 1 (0 on a miss).
    pub u: f32,
    /// Barycentric weight of vertex 2 (0 on a miss).
    pub v: f32,
}

impl Hit {
    /// The miss of a ray whose interval ends at `tmax`.
    pub fn miss(tmax: f32) -> Hit {
        Hit {
            t: tmax,
            prim: MISS,
            u: 0.0,
            v: 0.0,
        }
    }

    /// Whether a triangle was hit (`prim != MISS`).
    pub fn is_hit(&self) -> bool {
        self.prim != MISS
    }

    /// The tie rule shared by CPU and GPU: smaller t wins; equal t → smaller index.
    #[inline]
    pub fn beats(t: f32, prim: u32, best_t: f32, best_prim: u32) -> bool {
        t < best_t || (t == best_t && prim < best_prim)
    }
}
