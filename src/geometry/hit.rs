/// Primitive index of a miss, in the API and in hit files.
pub const MISS: u32 = u32::MAX;

/// Result of tracing one ray. `prim` is the original (file-order) triangle index or
/// [`MISS`]; on a miss `t` is the ray's tmax and `u = v = 0`.
/// `u`, `v` are the barycentric weights of vertices 1 and 2.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

impl Hit {
    pub fn miss(tmax: f32) -> Hit {
        Hit {
            t: tmax,
            prim: MISS,
            u: 0.0,
            v: 0.0,
        }
    }

    pub fn is_hit(&self) -> bool {
        self.prim != MISS
    }

    /// The tie rule shared by CPU and GPU: smaller t wins; equal t → smaller index.
    #[inline]
    pub fn beats(t: f32, prim: u32, best_t: f32, best_prim: u32) -> bool {
        t < best_t || (t == best_t && prim < best_prim)
    }
}
