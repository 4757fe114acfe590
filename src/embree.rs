//! Embree 3 (the `embree` feature) as a reference CPU tracer: one Embree scene over the mesh's
//! triangles ([`EmbreeTracer`]), or Embree's own two levels over an [`InstanceSet`]
//! ([`EmbreeInstances`]), traced one ray at a time (`rtcIntersect1`, `rtcOccluded1`) on
//! rayon's threads. `lancer bench layouts` times the first beside lancer's layouts, `lancer
//! bench instances` both beside lancer's two levels and flattened copy; `tests/embree.rs`
//! judges their answers against lancer's CPU twins.

use std::time::Instant;

use crate::accel::trace_in_chunks;
use crate::geometry::{Affine, Hit, Ray};
use crate::mesh::{InstanceSet, Mesh};
use crate::{Error, Result};
use embree3::{
    BufferUsage, BuildQuality, Config, Device, DeviceProperty, Format, GeometryKind,
    IntersectContext, RayHit, Scene, INVALID_ID,
};

/// Bytes per triangle the scene may take, for the memory check up front: the vertex (36) and
/// index (12) buffers Embree copies plus its BVH (a medium-quality BVH4 over triangle4 leaves
/// takes well under 150).
const BYTES_PER_TRIANGLE: u128 = 200;

/// An Embree scene over a mesh's triangles, committed and ready to trace from many threads.
pub struct EmbreeTracer {
    scene: Scene<'static>,
    /// Embree's primitive ID → lancer's original triangle index (the triangles the BVH
    /// includes, in mesh order).
    prims: Vec<u32>,
    build_ms: f64,
    version: String,
}

fn embree_error(what: &str, e: embree3::Error) -> Error {
    Error::Usage(format!("Embree: {what}: {e}"))
}

impl EmbreeTracer {
    /// Builds the scene: the triangles lancer's BVH includes ([`Mesh::included`]), in mesh
    /// order, at Embree's default build quality (medium), with `threads` build threads.
    pub fn new(mesh: &Mesh, threads: usize) -> Result<EmbreeTracer> {
        let prims = mesh.included();
        let count = vertex_count(prims.len())?;
        let (device, version) = open_device(threads)?;
        let (scene, build_ms) = build_scene(&device, mesh, &prims, count)?;
        log::info!(
            "Embree {version}: scene over {} triangles built in {build_ms:.1} ms",
            prims.len()
        );
        Ok(EmbreeTracer {
            scene,
            prims,
            build_ms,
            version,
        })
    }

    /// Wall time of the scene build (the commit, its buffers filled before), in milliseconds.
    pub fn build_ms(&self) -> f64 {
        self.build_ms
    }

    /// The Embree library's version, as it reports it ("3.13.5").
    pub fn version(&self) -> &str {
        &self.version
    }

    /// Closest hits (`rtcIntersect1`), one ray at a time on rayon's threads: original triangle
    /// indices, Embree's t and barycentrics; [`Hit::miss`] on a miss or an invalid ray.
    pub fn closest(&self, rays: &[Ray]) -> Vec<Hit> {
        closest_hits(&self.scene, rays, |hit| {
            self.prims.get(hit.primID as usize).copied()
        })
    }

    /// Whether each ray is blocked (`rtcOccluded1`), one ray at a time on rayon's threads;
    /// false for an invalid ray. Embree's any-hit names no triangle.
    pub fn occluded(&self, rays: &[Ray]) -> Vec<bool> {
        occluded_rays(&self.scene, rays)
    }
}

/// Closest hits on `scene` (`rtcIntersect1`), one ray at a time on rayon's threads, each
/// hit's triangle numbered by `prim` (None: a miss); [`Hit::miss`] on a miss or an invalid
/// ray.
fn closest_hits(
    scene: &Scene<'static>,
    rays: &[Ray],
    prim: impl Fn(&embree3::Hit) -> Option<u32> + Sync,
) -> Vec<Hit> {
    trace_in_chunks(
        rays,
        Hit::miss(0.0),
        IntersectContext::incoherent,
        |ctx, r| {
            let miss = Hit::miss(r.tmax);
            if !r.is_valid() {
                return miss;
            }
            let mut rh = RayHit::from(embree_ray(r));
            scene.intersect(ctx, &mut rh);
            if rh.hit.geomID == INVALID_ID {
                return miss;
            }
            match prim(&rh.hit) {
                Some(prim) => Hit {
                    t: rh.ray.tfar,
                    prim,
                    u: rh.hit.u,
                    v: rh.hit.v,
                },
                None => miss,
            }
        },
    )
}

/// Whether each ray is blocked on `scene` (`rtcOccluded1`), one ray at a time on rayon's
/// threads; false for an invalid ray.
fn occluded_rays(scene: &Scene<'static>, rays: &[Ray]) -> Vec<bool> {
    trace_in_chunks(rays, false, IntersectContext::incoherent, |ctx, r| {
        r.is_valid() && scene.occluded(ctx, &mut embree_ray(r))
    })
}

/// Bytes an instance may take in Embree's top-level scene, for the memory check up front:
/// its geometry object, the crate's handle and the top level's share of the BVH.
const BYTES_PER_INSTANCE: u128 = 1024;

/// Embree's own two levels over an [`InstanceSet`]: one committed scene per unique mesh (a
/// triangle geometry over the triangles lancer's BVH includes, as [`EmbreeTracer`] builds
/// it), and a top-level scene of instance geometries (`rtcSetGeometryInstancedScene`, the
/// instance's map as Embree's transform), one per instance, at Embree's default build
/// quality (medium). Hits are numbered as lancer numbers the flattened scene
/// ([`InstanceSet::first_prims`] + the triangle's index in its mesh), as lancer's
/// [`TwoLevel`](crate::accel::instances::TwoLevel) numbers them.
pub struct EmbreeInstances {
    top: Scene<'static>,
    /// The meshes' scenes, which the top scene's instances refer to (dropped after it).
    _meshes: Vec<Scene<'static>>,
    /// Per mesh: Embree's primitive ID → the triangle's index in the mesh.
    prims: Vec<Vec<u32>>,
    /// Per instance, by its geometry ID in the top scene: its mesh and its first triangle
    /// index in the flattened numbering.
    instances: Vec<(u32, u32)>,
    build_ms: f64,
    version: String,
}

impl EmbreeInstances {
    /// Builds the scenes with `threads` build threads (0: all). Refused as
    /// [`InstanceSet::new`] refuses a set, or when the scenes would not fit in memory.
    /// Instances of a mesh with no usable triangle are left out of the top scene.
    pub fn new(set: &InstanceSet, threads: usize) -> Result<EmbreeInstances> {
        let set = InstanceSet::new(set.meshes.clone(), set.instances.clone())?;
        let ids = u32::try_from(set.instances.len()).map_err(|_| {
            Error::Usage(format!(
                "Embree: {} instances, more than its geometry IDs number",
                set.instances.len()
            ))
        })?;
        let triangles: usize = set.meshes.iter().map(|m| m.len()).sum();
        crate::limits::check_memory(
            &format!("Embree's two levels over {triangles} triangles and {ids} instances"),
            triangles as u128 * BYTES_PER_TRIANGLE + u128::from(ids) * BYTES_PER_INSTANCE,
            "place fewer instances",
        )?;
        let prims: Vec<Vec<u32>> = set.meshes.iter().map(|m| m.included()).collect();
        let counts = (prims.iter().map(|p| vertex_count(p.len()))).collect::<Result<Vec<_>>>()?;
        let (device, version) = open_device(threads)?;
        // The build is the commits (each mesh's scene's, then the top scene's), as
        // `build_scene` times one: filling buffers and placing instances is not timed.
        let mut build_ms = 0.0;
        let mut meshes = Vec::with_capacity(set.meshes.len());
        for ((mesh, prims), &count) in set.meshes.iter().zip(&prims).zip(&counts) {
            let (scene, ms) = build_scene(&device, mesh, prims, count)?;
            meshes.push(scene);
            build_ms += ms;
        }
        let mut top = device
            .create_scene()
            .map_err(|e| embree_error("cannot create the top-level scene", e))?;
        top.set_build_quality(BuildQuality::MEDIUM);
        let first_prims = set.first_prims();
        let mut instances = Vec::with_capacity(set.instances.len());
        for (id, (inst, &first)) in (0..ids).zip(set.instances.iter().zip(&first_prims)) {
            instances.push((inst.mesh, first));
            if counts[inst.mesh as usize] == 0 {
                continue;
            }
            let mut geometry = device
                .create_geometry(GeometryKind::INSTANCE)
                .map_err(|e| embree_error("cannot create an instance", e))?;
            geometry.set_instanced_scene(&meshes[inst.mesh as usize]);
            geometry.set_transform(0, &column_major(&inst.to_world));
            let geometry = geometry.commit();
            top.attach_geometry_by_id(&geometry, id);
        }
        let start = Instant::now();
        top.commit();
        match device.get_error() {
            embree3::Error::NONE => {}
            e => return Err(embree_error("the two-level build failed", e)),
        }
        build_ms += start.elapsed().as_secs_f64() * 1e3;
        log::info!(
            "Embree {version}: two levels over {} meshes ({triangles} triangles) and {ids} \
             instances built in {build_ms:.1} ms",
            set.meshes.len()
        );
        Ok(EmbreeInstances {
            top,
            _meshes: meshes,
            prims,
            instances,
            build_ms,
            version,
        })
    }

    /// Wall time of the build (every mesh's scene, the instances and the top level, each
    /// committed), in milliseconds.
    pub fn build_ms(&self) -> f64 {
        self.build_ms
    }

    /// The Embree library's version, as it reports it ("3.13.5").
    pub fn version(&self) -> &str {
        &self.version
    }

    /// Closest hits (`rtcIntersect1`), one ray at a time on rayon's threads: triangle
    /// indices of the flattened numbering (the instance's first index + the triangle's in
    /// its mesh), Embree's t (of the world ray) and barycentrics; [`Hit::miss`] on a miss or
    /// an invalid ray.
    pub fn closest(&self, rays: &[Ray]) -> Vec<Hit> {
        closest_hits(&self.top, rays, |hit| {
            let &(mesh, first) = self.instances.get(hit.instID[0] as usize)?;
            let prim = *self.prims.get(mesh as usize)?.get(hit.primID as usize)?;
            first.checked_add(prim)
        })
    }

    /// Whether each ray is blocked (`rtcOccluded1`), one ray at a time on rayon's threads;
    /// false for an invalid ray. Embree's any-hit names no triangle.
    pub fn occluded(&self, rays: &[Ray]) -> Vec<bool> {
        occluded_rays(&self.top, rays)
    }
}

/// An affine map as Embree's 4×4 column-major transform (last row 0, 0, 0, 1).
fn column_major(a: &Affine) -> [f32; 16] {
    let mut m = [0.0; 16];
    for (column, out) in m.chunks_exact_mut(4).enumerate() {
        for (row, o) in out.iter_mut().take(3).enumerate() {
            *o = a.rows[row][column];
        }
    }
    m[15] = 1.0;
    m
}

/// lancer's ray as Embree's: the same origin, direction and interval.
fn embree_ray(r: &Ray) -> embree3::Ray {
    embree3::Ray::segment(r.origin.to_array(), r.dir.to_array(), r.tmin, r.tmax)
}

/// The vertex count of a scene over `triangles` (three vertices each, unshared), after the
/// memory check up front; refused past what Embree's 32-bit indices address.
fn vertex_count(triangles: usize) -> Result<u32> {
    crate::limits::check_memory(
        &format!("an Embree scene over {triangles} triangles"),
        triangles as u128 * BYTES_PER_TRIANGLE,
        "use a smaller mesh",
    )?;
    let vertices = triangles * 3;
    u32::try_from(vertices).map_err(|_| {
        Error::Usage(format!(
            "Embree: {triangles} triangles need {vertices} vertex indices, more than u32 holds"
        ))
    })
}

/// An Embree device on `threads` threads (0: all), and Embree's version ("3.13.5").
fn open_device(threads: usize) -> Result<(Device, String)> {
    let config = Config {
        threads: u32::try_from(threads).unwrap_or(0),
        ..Config::default()
    };
    let device =
        Device::with_config(config).map_err(|e| embree_error("cannot create a device", e))?;
    let v = device
        .get_property(DeviceProperty::VERSION)
        .map_err(|e| embree_error("cannot read the version", e))?;
    let version = format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100);
    Ok((device, version))
}

/// A committed medium-quality scene over the triangles `prims` of `mesh` (`count`: three
/// vertices each), and the wall time of its build in ms: the commit, which builds the BVH
/// from the buffers. Filling the buffers is not timed (it took 17–20 ms of the ~230 that
/// were timed with it at 1M triangles): it is the copy lancer's own mesh layout makes
/// necessary, not Embree's work, and lancer's builds read the mesh where it is.
fn build_scene(
    device: &Device,
    mesh: &Mesh,
    prims: &[u32],
    count: u32,
) -> Result<(Scene<'static>, f64)> {
    let mut scene = device
        .create_scene()
        .map_err(|e| embree_error("cannot create a scene", e))?;
    scene.set_build_quality(BuildQuality::MEDIUM);
    if count > 0 {
        let mut geometry = device
            .create_geometry(GeometryKind::TRIANGLE)
            .map_err(|e| embree_error("cannot create a triangle mesh", e))?;
        let mut vb = geometry
            .set_new_buffer::<[f32; 3]>(BufferUsage::VERTEX, 0, Format::FLOAT3, 12, count as usize)
            .map_err(|e| embree_error("cannot allocate the vertices", e))?;
        for (dst, &p) in vb.chunks_exact_mut(3).zip(prims) {
            for (d, s) in dst.iter_mut().zip(mesh.triangles[p as usize].v) {
                *d = s.to_array();
            }
        }
        let mut ib = geometry
            .set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, prims.len())
            .map_err(|e| embree_error("cannot allocate the indices", e))?;
        for (i, dst) in (0..count).step_by(3).zip(ib.iter_mut()) {
            *dst = [i, i + 1, i + 2];
        }
        let geometry = geometry.commit();
        scene.attach_geometry(&geometry);
    }
    let start = Instant::now();
    scene.commit();
    match device.get_error() {
        embree3::Error::NONE => {}
        e => return Err(embree_error("the scene build failed", e)),
    }
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    Ok((scene, build_ms))
}

/// Embree's build, timed: medium-quality scene builds over one mesh's included triangles
/// on one device, whose threads an untimed first build starts (as lancer's thread pool is
/// running already when its builds are timed).
pub struct EmbreeBuilds<'m> {
    device: Device,
    mesh: &'m Mesh,
    prims: Vec<u32>,
    count: u32,
    version: String,
}

impl<'m> EmbreeBuilds<'m> {
    /// The device on `threads` threads (0: all), after one untimed build.
    pub fn new(mesh: &'m Mesh, threads: usize) -> Result<EmbreeBuilds<'m>> {
        let prims = mesh.included();
        let count = vertex_count(prims.len())?;
        let (device, version) = open_device(threads)?;
        build_scene(&device, mesh, &prims, count)?;
        Ok(EmbreeBuilds {
            device,
            mesh,
            prims,
            count,
            version,
        })
    }

    /// Wall time of one more scene build (the commit, its buffers filled before), in ms.
    pub fn time(&self) -> Result<f64> {
        Ok(build_scene(&self.device, self.mesh, &self.prims, self.count)?.1)
    }

    /// The Embree library's version ("3.13.5").
    pub fn version(&self) -> &str {
        &self.version
    }
}
