//! Embree 3 (the `embree` feature) as a reference CPU tracer: one Embree scene over the mesh's
//! triangles, traced one ray at a time (`rtcIntersect1`, `rtcOccluded1`) on rayon's threads.
//! `lancer bench layouts` times it beside lancer's layouts; `tests/embree.rs` judges its
//! answers against the CPU twin with the f64 oracle.

use std::time::Instant;

use crate::accel::trace_in_chunks;
use crate::geometry::{Hit, Ray};
use crate::mesh::Mesh;
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

    /// Wall time of the scene build (commit included), in milliseconds.
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
                self.scene.intersect(ctx, &mut rh);
                if rh.hit.geomID == INVALID_ID {
                    return miss;
                }
                match self.prims.get(rh.hit.primID as usize) {
                    Some(&prim) => Hit {
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

    /// Whether each ray is blocked (`rtcOccluded1`), one ray at a time on rayon's threads;
    /// false for an invalid ray. Embree's any-hit names no triangle.
    pub fn occluded(&self, rays: &[Ray]) -> Vec<bool> {
        trace_in_chunks(rays, false, IntersectContext::incoherent, |ctx, r| {
            r.is_valid() && self.scene.occluded(ctx, &mut embree_ray(r))
        })
    }
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
/// vertices each), and the wall time of its build in ms: buffers filled, BVH built.
fn build_scene(
    device: &Device,
    mesh: &Mesh,
    prims: &[u32],
    count: u32,
) -> Result<(Scene<'static>, f64)> {
    let start = Instant::now();
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

    /// Wall time of one more scene build (buffers filled, BVH built), in ms.
    pub fn time(&self) -> Result<f64> {
        Ok(build_scene(&self.device, self.mesh, &self.prims, self.count)?.1)
    }

    /// The Embree library's version ("3.13.5").
    pub fn version(&self) -> &str {
        &self.version
    }
}
