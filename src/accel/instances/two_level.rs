//! [`TwoLevel`]: the top level over instances composed with a bottom-level structure per
//! mesh, traced on the CPU.

use std::mem::MaybeUninit;
use std::sync::Arc;

use super::interleaved::CwbvhLevels;
use super::top_level::TopLevel;
use super::{Affine, Instance, InstanceSet};
use crate::accel::bvh::layouts::{trace_chunk, Cwbvh, DfsNodeRay};
use crate::accel::bvh::{BuildOptions, MAX_DEPTH};
use crate::accel::{
    trace_chunks, trace_in_chunks, Accel, AccelKind, HitMask, Mask, Query, RayStats,
};
use crate::geometry::{
    intersect_triangle_bounded, prune_bound, triangle_hit_f64, Aabb, Hit, Precision, Ray,
    Robustness, Triangle, WatertightRay,
};
use crate::mesh::Mesh;

/// A two-level structure: a top-level BVH over instances, one bottom-level structure per
/// unique mesh (any [`AccelKind`]). Its [`Accel`] walks the top level as dfs-sign walks its
/// nodes (the far child stacked, the near one by the ray's sign on the split axis), moves
/// the ray into each instance's object space and continues the trace in its mesh's bottom
/// level, numbering hits as the flattened scene does ([`InstanceSet::flatten`]).
///
/// `B` is the bottom levels' type: any structure (`dyn Accel`), or a GPU form for the
/// two-level GPU form ([`GpuTwoLevel`](super::GpuTwoLevel)), whose CPU twin this is.
pub struct TwoLevel<B: Accel + ?Sized = dyn Accel> {
    pub(super) top: TopLevel,
    /// Shared with the structures made from this one ([`TwoLevel::moved`]).
    pub(super) bottoms: Vec<Arc<B>>,
    pub(super) meshes: Vec<Arc<Mesh>>,
    /// The instances, in order.
    instances: Vec<Instance>,
}

impl TwoLevel {
    /// Builds a `kind` structure over each of `set`'s meshes (the BVH with `options`) and the
    /// top level over its instances (the BVH builder of `options`, one instance a leaf).
    /// Refused as [`InstanceSet::new`] refuses, or as [`accel::build`](crate::accel::build)
    /// refuses a mesh.
    pub fn build(
        kind: AccelKind,
        set: &InstanceSet,
        options: &BuildOptions,
    ) -> crate::Result<TwoLevel> {
        TwoLevel::over(set, |_, m| crate::accel::build(kind, m, options), options)
    }
}

impl<B: Accel + ?Sized> TwoLevel<B> {
    /// The top level over `set`'s instances and the bottom levels `bottom(mesh)` made for
    /// each of its meshes, after [`InstanceSet::new`]'s checks.
    pub(super) fn over(
        set: &InstanceSet,
        bottom: impl Fn(usize, &Mesh) -> crate::Result<Box<B>>,
        options: &BuildOptions,
    ) -> crate::Result<TwoLevel<B>> {
        let set = InstanceSet::new(set.meshes.clone(), set.instances.clone())?;
        let bottoms = (set.meshes.iter().enumerate())
            .map(|(k, m)| bottom(k, m).map(Arc::from))
            .collect::<crate::Result<Vec<_>>>()?;
        let top = TopLevel::build(&set, options);
        log::debug!(
            "two-level: {} meshes, {} instances ({} placed), {} top-level nodes",
            set.meshes.len(),
            set.instances.len(),
            top.entries.len(),
            top.nodes.len()
        );
        Ok(TwoLevel {
            top,
            bottoms,
            meshes: set.meshes,
            instances: set.instances,
        })
    }

    /// The same meshes and bottom levels (shared, not rebuilt) with the instances moved:
    /// `maps[i]` places instance i, in order; only the top level is built again (with
    /// `options`' builder). Refused, as [`InstanceSet::new`] refuses a map, or when
    /// `maps` is not one map an instance.
    pub fn moved(&self, maps: &[Affine], options: &BuildOptions) -> crate::Result<TwoLevel<B>> {
        if maps.len() != self.instances.len() {
            return Err(crate::Error::Usage(format!(
                "{} maps for {} instances: give one map an instance, in order",
                maps.len(),
                self.instances.len()
            )));
        }
        let instances = (self.instances.iter().zip(maps))
            .map(|(i, &to_world)| Instance {
                mesh: i.mesh,
                to_world,
            })
            .collect();
        self.with(
            self.meshes.clone(),
            self.bottoms.clone(),
            instances,
            options,
        )
    }

    /// The same instances with mesh `k` replaced by `mesh` (its triangles moved) under the
    /// bottom level `bottom`; the top level is built again over the moved mesh.
    pub(super) fn with_mesh(
        &self,
        k: usize,
        mesh: Arc<Mesh>,
        bottom: Arc<B>,
        options: &BuildOptions,
    ) -> crate::Result<TwoLevel<B>> {
        let (mut meshes, mut bottoms) = (self.meshes.clone(), self.bottoms.clone());
        meshes[k] = mesh;
        bottoms[k] = bottom;
        self.with(meshes, bottoms, self.instances.clone(), options)
    }

    /// A top level built over `instances` of `meshes`, above `bottoms`.
    fn with(
        &self,
        meshes: Vec<Arc<Mesh>>,
        bottoms: Vec<Arc<B>>,
        instances: Vec<Instance>,
        options: &BuildOptions,
    ) -> crate::Result<TwoLevel<B>> {
        let set = InstanceSet::new(meshes, instances)?;
        Ok(TwoLevel {
            top: TopLevel::build(&set, options),
            bottoms,
            meshes: set.meshes,
            instances: set.instances,
        })
    }

    /// Whether `set` places the meshes this structure was built over (the same meshes, by
    /// pointer, each instance the same mesh): [`TwoLevel::moved`] then takes its maps.
    pub fn places(&self, set: &InstanceSet) -> bool {
        set.meshes.len() == self.meshes.len()
            && (set.meshes.iter().zip(&self.meshes)).all(|(a, b)| Arc::ptr_eq(a, b))
            && set.instances.len() == self.instances.len()
            && (set.instances.iter().zip(&self.instances)).all(|(i, j)| i.mesh == j.mesh)
    }

    /// Nodes of the top level.
    pub fn top_nodes(&self) -> usize {
        self.top.nodes.len()
    }

    /// Instances in the top level (those whose mesh has a usable triangle).
    pub fn placed_instances(&self) -> usize {
        self.top.entries.len()
    }
}

/// The prune bound a leaf step moves to when it takes triangle `tri`'s hit at `t` on `ray`
/// (the same test again: [`TriHit::prune`](crate::geometry::TriHit::prune)), so the top
/// level culls instances as a flattened traversal culls boxes after that hit: for bottom
/// levels that do not report it ([`Accel::intersect_pruned`]; the BVH layouts do).
fn prune_after(tri: &Triangle, ray: &Ray, robustness: &Robustness, t: f32) -> f32 {
    let h = match (robustness.precision, robustness.triangle_test) {
        (Precision::F64, _) => triangle_hit_f64(tri, ray, ray.tmin, t),
        (_, test) => {
            intersect_triangle_bounded(test, tri, ray, &WatertightRay::new(ray.dir), ray.tmin, t)
        }
    };
    h.map_or(prune_bound(t), |h| h.prune())
}

/// A mask over all instances asked of one instance's triangles, numbered from `base`.
struct Shifted<'a> {
    mask: &'a dyn HitMask,
    base: u32,
}

impl HitMask for Shifted<'_> {
    fn keeps(&self, prim: u32, u: f32, v: f32) -> bool {
        self.mask.keeps(self.base + prim, u, v)
    }
}

impl<B: Accel + ?Sized> Accel for TwoLevel<B> {
    fn bounds(&self) -> Aabb {
        self.top.bounds()
    }

    /// The top level walked as dfs-sign walks its nodes; at an instance, the ray in object
    /// space goes to its bottom level with tmax cut to the top level's prune bound once a
    /// hit is known (a bottom hit beyond the best one is then dropped by the tie rule).
    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        let mut best = Hit::miss(ray.tmax);
        if !ray.is_valid() || self.top.nodes.is_empty() {
            return best;
        }
        let boxes = DfsNodeRay::new(ray, robustness);
        let mut prune = prune_bound(best.t);
        // Left uninitialised: zeroing its 64 entries for every ray cost ~5% of a trace
        // through one instance of the bunny (one thread). Only pushed entries are read.
        let mut stack = [MaybeUninit::<u32>::uninit(); MAX_DEPTH];
        let mut sp = 0usize;
        let mut idx = 0usize;
        loop {
            let node = &self.top.nodes[idx];
            stats.nodes += 1;
            if boxes.enters(node, prune) {
                if !node.is_leaf() {
                    let (first, second) = (idx + 1, node.a as usize);
                    let (near, far) = if ray.dir[node.axis()] < 0.0 {
                        (second, first)
                    } else {
                        (first, second)
                    };
                    stack[sp] = MaybeUninit::new(far as u32);
                    sp += 1;
                    idx = near;
                    continue;
                }
                // A leaf holds one instance (TopLevel::build).
                let e = &self.top.entries[node.a as usize];
                let mut local = e.to_object.ray(ray);
                if best.is_hit() {
                    local.tmax = prune;
                }
                // The mask is asked of the instance's triangles (WGSL: bottom_prim_base).
                let shifted = mask.map(|mask| Shifted {
                    mask,
                    base: e.first_prim,
                });
                let (h, h_prune) = self.bottoms[e.mesh as usize].intersect_pruned(
                    &local,
                    query,
                    robustness,
                    shifted.as_ref().map(|s| s as &dyn HitMask),
                    stats,
                );
                let prim = e.first_prim.wrapping_add(h.prim);
                if h.is_hit() && Hit::beats(h.t, prim, best.t, best.prim) {
                    best = Hit { prim, ..h };
                    if query == Query::Any {
                        return best;
                    }
                    prune = h_prune.unwrap_or_else(|| {
                        let tri = &self.meshes[e.mesh as usize].triangles[h.prim as usize];
                        prune_after(tri, &local, robustness, h.t)
                    });
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written by a push above.
            idx = unsafe { stack[sp].assume_init() } as usize;
        }
        best
    }

    /// Over cwbvh bottom levels, two rays walked at a time, as cwbvh's own batches are
    /// walked (`interleaved.rs`: the same answers as [`Accel::intersect`]); over others, one
    /// ray at a time.
    fn trace_hits(&self, rays: &[Ray], query: Query, robustness: &Robustness) -> Vec<Hit> {
        let bottoms: Option<Vec<&Cwbvh>> = self.bottoms.iter().map(|b| b.as_cwbvh()).collect();
        if let Some(bottoms) = bottoms.filter(|b| !b.is_empty()) {
            let levels = CwbvhLevels {
                top: &self.top,
                bottoms,
            };
            return trace_chunks(rays, Hit::miss(0.0), |rays, out| {
                trace_chunk(&levels, rays, out, query, robustness)
            });
        }
        trace_in_chunks(rays, Hit::miss(0.0), RayStats::default, |stats, r| {
            self.intersect(r, query, robustness, stats)
        })
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::bvh::layouts::{flatten, LayoutKind};
    use crate::accel::bvh::{build, BuildOptions};
    use crate::geometry::{Robustness, TriangleTest};

    /// Every BVH layout hands up the prune bound of the hit it returns, the one the triangle
    /// test gives again (what the walk computes for structures that do not hand it up).
    #[test]
    fn every_layout_reports_the_prune_bound_of_its_hit() {
        // A soup of small triangles in the unit cube, from a fixed linear congruential stream.
        let mut state = 12345u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut point = || Vec3::new(next(), next(), next());
        let tris: Vec<Triangle> = (0..400)
            .map(|_| {
                let c = point();
                Triangle::new(c, c + 0.1 * point(), c + 0.1 * point())
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let bvh = build(&mesh, &BuildOptions::default());
        let rays: Vec<Ray> = (0..2000)
            .map(|_| {
                let o = 3.0 * point() - Vec3::splat(1.0);
                Ray::new(o, point() - o, 0.0, f32::INFINITY)
            })
            .collect();
        let tests = [TriangleTest::Watertight, TriangleTest::MollerTrumbore];
        let robs = (tests.map(|triangle_test| Robustness {
            triangle_test,
            ..Robustness::default()
        }))
        .into_iter()
        .chain([Robustness {
            precision: Precision::F64,
            ..Robustness::default()
        }]);
        for rob in robs {
            for &kind in LayoutKind::ALL {
                let layout = flatten(kind, &bvh, &mesh);
                let mut hits = 0;
                for ray in &rays {
                    let mut stats = RayStats::default();
                    let (h, prune) =
                        layout.intersect_pruned(ray, Query::Closest, &rob, None, &mut stats);
                    if !h.is_hit() {
                        continue;
                    }
                    hits += 1;
                    let again = prune_after(&mesh.triangles[h.prim as usize], ray, &rob, h.t);
                    assert_eq!(prune.map(f32::to_bits), Some(again.to_bits()), "{kind:?}");
                }
                assert!(hits > 100, "{kind:?}: {hits} hits");
            }
        }
    }
}
