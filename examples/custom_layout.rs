//! Plug a GPU layout in from outside lancer, through `Tracer::with_layout`.
//!
//! `cargo run --release --example custom_layout`
//!
//! A layout is a structure's GPU face: the arrays it uploads, the WGSL that walks them, and
//! a CPU twin that walks the same arrays in the same order (the trait `lancer::GpuForm`,
//! whose supertrait `lancer::Accel` is the CPU side). Here `MyLayout`, a type of this
//! example, implements both by handing each call to a BVH flattened in lancer's `bvh8`
//! layout, and counts the rays its CPU twin answers: the place where your own arrays,
//! traversal and WGSL would go. It then traces the same rays with it on the CPU and the
//! GPU, and checks the hits equal those of `Tracer::new` bit for bit.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::accel::{GpuArrays, Mask};
use lancer::geometry::Aabb;
use lancer::{Accel, Device, DeviceChoice, GpuForm, Hit, Mesh, Query, Ray, RayStats};
use lancer::{Robustness, Tracer, TracerOptions, Vec3};

/// Your layout. A real one would hold its own node array; this one wraps lancer's.
struct MyLayout {
    inner: Box<dyn GpuForm>,
    /// Rays the CPU twin traced (to show that the tracer calls this type).
    cpu_rays: AtomicUsize,
}

impl MyLayout {
    fn new(mesh: &Mesh) -> MyLayout {
        // Build a binary BVH over the mesh's usable triangles (SAH), then flatten it.
        let bvh = build(mesh, &BuildOptions::default());
        MyLayout {
            inner: flatten(LayoutKind::Bvh8, &bvh, mesh),
            cpu_rays: AtomicUsize::new(0),
        }
    }
}

/// The CPU side: what `Tracer` runs on the CPU (and for any ray a GPU driver cuts short).
/// It must run the WGSL's algorithm in the same order, in f32, with the same tie rule
/// (smaller t wins; equal t: the smaller triangle index), so CPU and GPU agree bit for bit.
impl Accel for MyLayout {
    fn bounds(&self) -> Aabb {
        self.inner.bounds()
    }

    // One ray. `mask` (None but in renders of alpha-masked materials) must be asked of
    // every hit the tie rule would take, as the WGSL's `test_tri` asks `alpha_keeps`.
    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        rob: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        self.cpu_rays.fetch_add(1, Ordering::Relaxed);
        self.inner.intersect_masked(ray, query, rob, mask, stats)
    }

    // Batches: the default runs `intersect` on every thread; bvh8's twin answers whole
    // chunks of rays faster, so hand batches to it too.
    fn trace_hits(&self, rays: &[Ray], query: Query, rob: &Robustness) -> Vec<Hit> {
        self.cpu_rays.fetch_add(rays.len(), Ordering::Relaxed);
        self.inner.trace_hits(rays, query, rob)
    }
}

/// The GPU side: what the kernel uploads and runs.
impl GpuForm for MyLayout {
    fn name(&self) -> &'static str {
        "my-layout"
    }

    /// The node array and the triangles in leaf order, as bytes (16-byte words).
    fn arrays(&self) -> GpuArrays<'_> {
        self.inner.arrays()
    }

    /// WGSL defining `fn traverse(r: Ray, any_hit: bool) -> Hit` over those arrays (see
    /// "Adding a layout" in docs/src/library.md for the helpers it may call).
    fn wgsl(&self) -> String {
        self.inner.wgsl()
    }

    fn subgroup_wgsl(&self) -> Option<String> {
        self.inner.subgroup_wgsl()
    }

    /// Override constants the WGSL declares, with this instance's values.
    fn overrides(&self) -> Vec<(&'static str, f64)> {
        self.inner.overrides()
    }

    /// Every invariant the traversal relies on (indices in range, depth within the stack):
    /// checked before trusted (unchecked) GPU modules read the arrays.
    fn validate(&self) -> Result<(), String> {
        self.inner.validate()
    }

    fn node_bytes(&self) -> usize {
        self.inner.node_bytes()
    }
}

fn main() -> lancer::Result<()> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.obj");
    let mesh = lancer::mesh::load_mesh(&path)?;
    let layout = Arc::new(MyLayout::new(&mesh));
    println!(
        "{}: {} triangles, {} bytes on the GPU ({}-byte nodes)",
        layout.name(),
        layout.triangles(),
        layout.bytes(),
        layout.node_bytes()
    );

    // 32×32 rays from the Cornell box's camera towards its back wall.
    let eye = Vec3::new(278.0, 273.0, 1359.2);
    let rays: Vec<Ray> = (0..32 * 32)
        .map(|i| {
            let (x, y) = ((i % 32) as f32 / 31.0, (i / 32) as f32 / 31.0);
            let target = Vec3::new(556.0 * x, 548.0 * y, 0.0);
            Ray::new(eye, (target - eye).normalize(), 0.0, 1e30)
        })
        .collect();

    let options = TracerOptions::default();
    let cpu = Device::open(DeviceChoice::Cpu)?;
    let devices = match Device::open(DeviceChoice::Gpu) {
        Ok(gpu) => vec![cpu, gpu],
        Err(e) => {
            println!("gpu: skipped, no GPU adapter opened ({e})");
            vec![cpu]
        }
    };
    for device in &devices {
        // Your layout: the tracer uploads its arrays and compiles its WGSL on a GPU, and
        // runs its CPU twin on the CPU. Several tracers may share one layout (an Arc).
        let mut mine = Tracer::with_layout(device, layout.clone(), &options)?;
        // lancer's own: builds and flattens the BVH in the device's default layout.
        let mut lancers = Tracer::new(device, &mesh, &options)?;
        let got = mine.trace(&rays, Query::Closest)?.hits;
        let want = lancers.trace(&rays, Query::Closest)?.hits;
        let hits = got.iter().filter(|h| h.is_hit()).count();
        let same = got.iter().zip(&want).all(|(a, b)| bits(a) == bits(b));
        println!(
            "{device}: {hits} of {} rays hit; the same hits as Tracer::new bit for bit: {same}",
            rays.len()
        );
        assert!(same, "{} disagrees with Tracer::new", layout.name());
    }
    println!(
        "{}'s CPU twin traced {} rays",
        layout.name(),
        layout.cpu_rays.load(Ordering::Relaxed)
    );
    Ok(())
}

/// A hit as its bits: equal bits, the same hit (`==` on f32 would let -0 equal +0).
fn bits(h: &Hit) -> [u32; 4] {
    [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()]
}
