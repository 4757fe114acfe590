//! The CPU reference tracer. It runs the GPU kernel's algorithm step for step: the same
//! stack discipline (push the far child, descend into the near one), the same ray-sign
//! child order, the same slab and triangle tests in the same operation order, and the same
//! tie rule, all in f32.

use rayon::prelude::*;

use crate::accel::bvh::{FlatBvh, MAX_DEPTH};
use glam::{Vec3, Vec3A};

use crate::geometry::{
    intersect_moller_trumbore, intersect_watertight, Aabb, Hit, Ray, TriangleTest, WatertightRay,
    MISS, PARALLEL_INV,
};

/// What a ray asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Query {
    /// The nearest hit in [tmin, tmax] (ties: smaller original index).
    #[default]
    Closest,
    /// Any hit in [tmin, tmax]: the first one met in traversal order (shadow rays).
    Any,
}

/// Work done for one ray: nodes popped (box tests) and triangles tested.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct RayStats {
    pub nodes: u32,
    pub tris: u32,
}

/// Traces one ray through a flat BVH.
pub fn trace_ray(
    bvh: &FlatBvh,
    ray: &Ray,
    query: Query,
    test: TriangleTest,
    stats: &mut RayStats,
) -> Hit {
    let mut best = Hit::miss(ray.tmax);
    if !ray.is_valid() {
        return best;
    }
    let inv = ray.inv_dir();
    let parallel = inv.abs().cmpge(Vec3::splat(PARALLEL_INV)).any();
    let (origin_a, inv_a) = (Vec3A::from(ray.origin), Vec3A::from(inv));
    let wr = WatertightRay::new(ray.dir);
    let mut stack = [0u32; MAX_DEPTH];
    let mut sp = 0usize;
    let mut idx = 0usize;
    loop {
        let node = &bvh.nodes[idx];
        stats.nodes += 1;
        let enter = if parallel {
            node.bbox().slab_hit(ray.origin, inv, ray.tmin, best.t)
        } else {
            Aabb::slab_hit_nonparallel(
                Vec3A::from_array(node.lo),
                Vec3A::from_array(node.hi),
                origin_a,
                inv_a,
                ray.tmin,
                best.t,
            )
        };
        if enter {
            if !node.is_leaf() {
                let (first, second) = (idx + 1, node.a as usize);
                let (near, far) = if ray.dir[node.axis()] < 0.0 {
                    (second, first)
                } else {
                    (first, second)
                };
                stack[sp] = far as u32;
                sp += 1;
                idx = near;
                continue;
            }
            let first = node.a as usize;
            for gt in &bvh.tris[first..first + node.count() as usize] {
                stats.tris += 1;
                let tri = gt.triangle();
                let h = match test {
                    TriangleTest::Watertight => {
                        intersect_watertight(&tri, ray.origin, &wr, ray.tmin, best.t)
                    }
                    TriangleTest::MollerTrumbore => {
                        intersect_moller_trumbore(&tri, ray, ray.tmin, best.t)
                    }
                };
                if let Some((t, u, v)) = h {
                    if Hit::beats(t, gt.prim, best.t, best.prim) {
                        best = Hit {
                            t,
                            prim: gt.prim,
                            u,
                            v,
                        };
                        if query == Query::Any {
                            return best;
                        }
                    }
                }
            }
        }
        if sp == 0 {
            break;
        }
        sp -= 1;
        idx = stack[sp] as usize;
    }
    debug_assert!(best.prim == MISS || best.t >= ray.tmin);
    best
}

/// Traces a batch of rays in parallel; returns hits and per-ray work counts.
pub fn trace_batch(
    bvh: &FlatBvh,
    rays: &[Ray],
    query: Query,
    test: TriangleTest,
) -> (Vec<Hit>, Vec<RayStats>) {
    rays.par_iter()
        .map(|r| {
            let mut s = RayStats::default();
            let h = trace_ray(bvh, r, query, test, &mut s);
            (h, s)
        })
        .unzip()
}
