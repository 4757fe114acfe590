//! A ray's slab test against [`DfsNode`] boxes, shared by the twins of the layouts built on
//! those nodes (dfs-sign, dfs-distance, threaded): the scalar test (parallel-axis rule) for a
//! ray parallel to an axis, else the SIMD one, which equals it; WGSL `slab_interval`.

use glam::{Vec3, Vec3A};

use super::DfsNode;
use crate::geometry::{Aabb, Ray, Robustness, PARALLEL_INV};

/// A valid ray set up for [`DfsNode`] slab tests.
pub(crate) struct DfsNodeRay {
    origin: Vec3,
    inv: Vec3,
    origin_a: Vec3A,
    inv_a: Vec3A,
    parallel: bool,
    tmin: f32,
    widen: f32,
}

impl DfsNodeRay {
    /// `ray` (valid) with the robustness settings' far widening.
    #[inline(always)]
    pub fn new(ray: &Ray, robustness: &Robustness) -> DfsNodeRay {
        let inv = ray.inv_dir();
        DfsNodeRay {
            origin: ray.origin,
            inv,
            origin_a: Vec3A::from(ray.origin),
            inv_a: Vec3A::from(inv),
            parallel: inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any(),
            tmin: ray.tmin,
            widen: robustness.far_widen(),
        }
    }

    /// The interval [enter, exit] of `node`'s box before `tmax` (entered when enter ≤ exit).
    #[inline(always)]
    pub fn interval(&self, node: &DfsNode, tmax: f32) -> (f32, f32) {
        if self.parallel {
            node.bbox()
                .slab_interval(self.origin, self.inv, self.tmin, tmax, self.widen)
        } else {
            Aabb::slab_interval_nonparallel(
                Vec3A::from_array(node.lo),
                Vec3A::from_array(node.hi),
                self.origin_a,
                self.inv_a,
                self.tmin,
                tmax,
                self.widen,
            )
        }
    }

    /// Whether the ray enters `node`'s box before `tmax` (WGSL `slab_hit`).
    #[inline(always)]
    pub fn enters(&self, node: &DfsNode, tmax: f32) -> bool {
        let (enter, exit) = self.interval(node, tmax);
        enter <= exit
    }
}
