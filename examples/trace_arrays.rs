//! Trace your own rays against your own triangles, both held in plain arrays.
//!
//! `cargo run --release --example trace_arrays`
//!
//! Builds a mesh from vertex positions and index triples (`Mesh::from_indexed`), makes a few
//! rays in code, and traces them on the CPU and, where an adapter opens, on the GPU: the
//! hits are the same, bit for bit.

use lancer::{Device, DeviceChoice, Hit, Mesh, Query, Ray, Tracer, TracerOptions, Vec3};

/// The end of the rays' interval: far beyond the mesh (finite: a GPU's arithmetic on
/// infinities is not defined in WGSL).
const FAR: f32 = 1e30;

fn main() -> lancer::Result<()> {
    // A unit cube: 8 corners and 12 triangles (two per face), indices counted from 0.
    // Positions may be `[f32; 3]` (as here) or `lancer::Vec3`.
    let positions: [[f32; 3]; 8] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    // Two triangles per face, in the order: z = 0, z = 1, y = 0, y = 1, x = 0, x = 1.
    let indices: [[u32; 3]; 12] = [
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [3, 7, 6],
        [3, 6, 2],
        [0, 4, 7],
        [0, 7, 3],
        [1, 2, 6],
        [1, 6, 5],
    ];
    // A hit names its triangle by its place in `indices`. Bad triangles (an index past the
    // positions, NaN, zero area) keep their place but stay out of the BVH, never hit, and
    // are counted in `mesh.status`. (Indices kept flat, three per triangle, become triples
    // with `flat.as_chunks::<3>().0`.)
    let mesh = Mesh::from_indexed(&positions, &indices)?;
    let bounds = mesh.bounds();
    println!(
        "mesh: {} triangles from {} to {}",
        mesh.len(),
        bounds.lo,
        bounds.hi
    );

    // Rays: origin, direction, and the interval [tmin, tmax] along it.
    let rays = [
        Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z, 0.0, FAR), // into face z = 0
        Ray::new(Vec3::new(0.25, 2.0, 0.75), Vec3::NEG_Y, 0.0, FAR), // from above
        Ray::new(Vec3::splat(0.5), Vec3::X, 0.0, FAR),          // from inside
        Ray::new(Vec3::new(3.0, 3.0, 3.0), Vec3::X, 0.0, FAR),  // misses
        Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z, 0.0, 0.5), // stops short: a miss
    ];

    // The CPU: always there.
    let cpu = Device::open(DeviceChoice::Cpu)?;
    let cpu_hits = trace(&cpu, &mesh, &rays)?;
    for (ray, hit) in rays.iter().zip(&cpu_hits) {
        if hit.is_hit() {
            let p = ray.origin + hit.t * ray.dir;
            println!(
                "cpu: ray from {} hits triangle {} at t = {}, point {p}",
                ray.origin, hit.prim, hit.t
            );
        } else {
            // A miss: nothing in the ray's interval (the last ray ends before the cube).
            let ends = match ray.tmax < FAR {
                true => format!(" before t = {}", ray.tmax),
                false => String::new(),
            };
            println!("cpu: ray from {} misses{ends}", ray.origin);
        }
    }

    // `Auto` takes a hardware GPU and falls back to the CPU without one (a software adapter
    // such as lavapipe is slower than the CPU tracer); `Gpu` takes any adapter or fails.
    for choice in [DeviceChoice::Auto, DeviceChoice::Gpu] {
        match Device::open(choice) {
            Ok(device) if device.is_cpu() => println!(
                "DeviceChoice::{choice:?} chose the CPU ({})",
                device.fallback().unwrap_or("asked for")
            ),
            Ok(device) => {
                let hits = trace(&device, &mesh, &rays)?;
                let same = hits.iter().zip(&cpu_hits).all(|(g, c)| bits(g) == bits(c));
                println!("DeviceChoice::{choice:?} opened {device}; hits bit-identical to the CPU's: {same}");
                assert!(same, "the GPU and the CPU disagree");
            }
            Err(e) => println!("DeviceChoice::{choice:?}: skipped, no GPU adapter opened ({e})"),
        }
    }
    Ok(())
}

/// Builds the BVH on `device` and returns the closest hit of each ray.
fn trace(device: &Device, mesh: &Mesh, rays: &[Ray]) -> lancer::Result<Vec<Hit>> {
    let mut tracer = Tracer::new(device, mesh, &TracerOptions::default())?;
    Ok(tracer.trace(rays, Query::Closest)?.hits)
}

/// A hit as its bits: equal bits, the same hit (`==` on f32 would let -0 equal +0).
fn bits(h: &Hit) -> [u32; 4] {
    [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()]
}
