//! Ray and hit files. Rays: 32 bytes each, little-endian f32 origin xyz, tmin, direction
//! xyz, tmax. Hits: 16 bytes each, t f32, prim u32 (0xFFFFFFFF = miss, t = tmax), u, v.

use std::path::Path;

use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray};

const RAY_BYTES: usize = std::mem::size_of::<Ray>();

/// Reads a ray file (32 little-endian bytes a ray); refuses a size not a multiple of 32.
pub fn read_rays(path: &Path) -> Result<Vec<Ray>> {
    let bytes = crate::input::read(path)?;
    decode_rays(path, &bytes)
}

/// The rays of a ray file's bytes (read from `name`, which errors and warnings name);
/// refuses a size not a multiple of 32 and counts invalid rays in a warning.
pub fn decode_rays(name: &Path, bytes: &[u8]) -> Result<Vec<Ray>> {
    let rays = decode_ray_bytes(name, bytes)?;
    let invalid = rays.iter().filter(|r| !r.is_valid()).count();
    if invalid > 0 {
        log::warn!(
            "{}: {invalid} of {} rays are invalid (NaN/Inf, an origin beyond ±1e12, a zero \
             direction or an empty interval); they are reported as misses",
            name.display(),
            rays.len()
        );
    }
    Ok(rays)
}

/// Checks a ray file before it is read: a regular file of whole rays (32 bytes each), so
/// that a bad one is refused before work that precedes the read (the ray file itself is
/// read and checked again when its rays are needed).
pub fn check_ray_file(path: &Path) -> Result<()> {
    whole_rays(path, crate::input::regular_file(path)?)
}

/// Refuses a size (`len` bytes, of `path`) that is not whole rays.
fn whole_rays(path: &Path, len: u64) -> Result<()> {
    if len.is_multiple_of(RAY_BYTES as u64) {
        return Ok(());
    }
    Err(Error::input(
        path,
        None,
        format!(
            "size {len} bytes is not a multiple of {RAY_BYTES} (one ray = origin xyz, tmin, direction xyz, tmax as f32); the last {} bytes are a partial ray",
            len % RAY_BYTES as u64
        ),
    ))
}

fn decode_ray_bytes(path: &Path, bytes: &[u8]) -> Result<Vec<Ray>> {
    whole_rays(path, bytes.len() as u64)?;
    // The file's bytes are held already: the rays decoded from them, and the hits a trace
    // of them makes (16 bytes a ray), must fit beside them.
    let rays = (bytes.len() / RAY_BYTES) as u128;
    crate::limits::check_memory(
        &format!("{}: {rays} rays and their hits", path.display()),
        rays * (RAY_BYTES + std::mem::size_of::<Hit>()) as u128,
        "free memory, or trace the rays in smaller files",
    )?;
    // Decode explicitly little-endian, whatever the host.
    Ok(bytes
        .chunks_exact(RAY_BYTES)
        .map(|c| {
            let f =
                |i: usize| f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]);
            Ray::new(
                glam::Vec3::new(f(0), f(1), f(2)),
                glam::Vec3::new(f(4), f(5), f(6)),
                f(3),
                f(7),
            )
        })
        .collect())
}

/// Writes rays as a ray file (32 little-endian bytes a ray).
pub fn write_rays(path: &Path, rays: &[Ray]) -> Result<()> {
    crate::output::write_bytes(path, &encode_rays(rays))
}

/// The bytes of a ray file holding `rays`.
pub fn encode_rays(rays: &[Ray]) -> Vec<u8> {
    let mut out = Vec::with_capacity(rays.len() * RAY_BYTES);
    for r in rays {
        for x in [
            r.origin.x, r.origin.y, r.origin.z, r.tmin, r.dir.x, r.dir.y, r.dir.z, r.tmax,
        ] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Writes hits as a hit file (16 little-endian bytes a hit).
pub fn write_hits(path: &Path, hits: &[Hit]) -> Result<()> {
    crate::output::write_bytes(path, &encode_hits(hits))
}

/// The bytes of a hit file holding `hits`.
pub fn encode_hits(hits: &[Hit]) -> Vec<u8> {
    let mut out = Vec::with_capacity(hits.len() * 16);
    for h in hits {
        out.extend_from_slice(&h.t.to_le_bytes());
        out.extend_from_slice(&h.prim.to_le_bytes());
        out.extend_from_slice(&h.u.to_le_bytes());
        out.extend_from_slice(&h.v.to_le_bytes());
    }
    out
}

/// Reads a hit file (16 little-endian bytes a hit); refuses a size not a multiple of 16.
pub fn read_hits(path: &Path) -> Result<Vec<Hit>> {
    let bytes = crate::input::read(path)?;
    if bytes.len() % 16 != 0 {
        return Err(Error::input(
            path,
            None,
            "size is not a multiple of 16 (one hit = t, prim, u, v)",
        ));
    }
    // The hits decoded must fit beside the file's bytes, held already.
    crate::limits::check_memory(
        &format!("{}: {} hits", path.display(), bytes.len() / 16),
        bytes.len() as u128,
        "free memory, or compare the hits in smaller files",
    )?;
    Ok(bytes
        .chunks_exact(16)
        .map(|c| {
            let w = |i: usize| [c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]];
            Hit {
                t: f32::from_le_bytes(w(0)),
                prim: u32::from_le_bytes(w(1)),
                u: f32::from_le_bytes(w(2)),
                v: f32::from_le_bytes(w(3)),
            }
        })
        .collect())
}

/// Shadow rays from the hit points of `primary` towards a point light, for every ray that
/// hit. tmin is a small fraction of the hit distance, tmax ends at the light.
pub fn shadow_rays(primary: &[Ray], hits: &[Hit], light: glam::Vec3) -> Vec<Ray> {
    primary
        .iter()
        .zip(hits)
        .filter(|(_, h)| h.is_hit())
        .map(|(r, h)| {
            let p = r.origin + r.dir * h.t;
            let to = light - p;
            Ray::new(p, to.normalize(), 1e-4 * h.t, to.length())
        })
        .collect()
}

/// The point light of the preview and of benchmark shadow rays: in front of the mesh (on
/// the default view's side), up and to the right.
pub fn default_light(bounds: &crate::geometry::Aabb) -> glam::Vec3 {
    bounds.center() + glam::Vec3::new(0.25, 0.3, 0.9) * bounds.extent().length()
}

/// Diffuse bounce rays: from the hit points of `primary`, one cosine-distributed direction
/// about the hit triangle's normal (turned towards the incoming ray), for every ray that hit
/// — the incoherent rays of a path tracer's second bounce. Deterministic in `seed`.
pub fn bounce_rays(mesh: &crate::mesh::Mesh, primary: &[Ray], hits: &[Hit], seed: u64) -> Vec<Ray> {
    // SplitMix64: a well-mixed u64 from a counter, two uniform numbers a ray.
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let unit = |z: u64| (z >> 40) as f32 / (1u64 << 24) as f32;
    primary
        .iter()
        .zip(hits)
        .enumerate()
        .filter_map(|(i, (r, h))| {
            let tri = mesh.triangles.get(h.prim as usize)?;
            let n = (tri.v[1] - tri.v[0])
                .cross(tri.v[2] - tri.v[0])
                .normalize_or_zero();
            if n == glam::Vec3::ZERO {
                return None;
            }
            let n = if n.dot(r.dir) > 0.0 { -n } else { n };
            let z = mix(seed.wrapping_add(0x9e37_79b9_7f4a_7c15u64.wrapping_mul(i as u64 + 1)));
            let (u1, u2) = (unit(z), unit(mix(z)));
            let (t, b) = n.any_orthonormal_pair();
            let (rad, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
            let d = t * (rad * phi.cos()) + b * (rad * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt();
            let p = r.origin + r.dir * h.t;
            Some(Ray::new(
                p,
                d.normalize(),
                1e-4 * h.t,
                crate::camera::PRIMARY_TMAX,
            ))
        })
        .collect()
}

/// A named ray set and the query it is traced with.
pub type RaySet = (String, crate::accel::Query, Vec<Ray>);

/// The rays benches and checks trace: the default view's primary rays (closest hit), shadow
/// rays from their hits to the default light (any hit) and diffuse bounce rays from the same
/// hits (closest hit, incoherent), named "primary", "shadow" and "bounce". `accel` finds the
/// primary hits. Refuses a view too large for memory (about 200 bytes a pixel).
pub fn view_ray_sets(
    mesh: &crate::mesh::Mesh,
    accel: &dyn crate::accel::Accel,
    width: u32,
    height: u32,
    robustness: &crate::geometry::Robustness,
) -> Result<Vec<RaySet>> {
    use crate::accel::Query;
    crate::limits::check_image(width, height, 200, "use a smaller --width/--height")?;
    let primary = crate::camera::Camera::default_view(&mesh.bounds(), width, height).primary_rays();
    let (hits, _) = accel.trace_batch(&primary, Query::Closest, robustness);
    let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
    let bounce = bounce_rays(mesh, &primary, &hits, 1);
    Ok(vec![
        ("primary".into(), Query::Closest, primary),
        ("shadow".into(), Query::Any, shadow),
        ("bounce".into(), Query::Closest, bounce),
    ])
}
