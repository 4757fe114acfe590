//! Every GPU form's kernel — each BVH layout's, the kd-tree's and the BIH's — against its CPU
//! twin on lavapipe (or any adapter), through the one `Tracer` API. For every ray: hit/miss and prim agree with the CPU, except genuine ties
//! the f64 oracle names; t agrees to ≤ 2 ulp where the prim agrees. Traversal statistics
//! agree exactly.

mod common;

use common::hard::nan_zero_and_empty_rays;
use common::{gpu_device, load_model, random_rays, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::{BuildOptions, Builder};
use lancer::camera::Camera;
use lancer::geometry::{Hit, Ray, Triangle, TriangleTest};
use lancer::gpu::BvhMemory;
use lancer::mesh::Mesh;
use lancer::trace::compare::compare_hits;
use lancer::{AccelKind, Device, LayoutKind, Query, Robustness, Tracer, TracerOptions};

/// One specialisation of the trace kernel.
#[derive(Clone, Copy, Debug, Default)]
struct TraceKernel {
    query: Query,
    robustness: Robustness,
    workgroup_size: Option<u32>,
    builder: Builder,
}

impl TraceKernel {
    fn options(&self, memory: BvhMemory) -> TracerOptions {
        TracerOptions {
            memory,
            robustness: self.robustness,
            workgroup_size: self.workgroup_size.unwrap_or(64),
            stats: true,
            build: BuildOptions {
                builder: self.builder,
                ..BuildOptions::default()
            },
            ..TracerOptions::default()
        }
    }
}

/// CPU hits of the default layout.
fn cpu_hits(mesh: &Mesh, rays: &[Ray], query: Query) -> Vec<Hit> {
    let cpu = Device::cpu();
    let mut t = Tracer::new(&cpu, mesh, &TracerOptions::default()).unwrap();
    t.trace(rays, query).unwrap().hits
}

/// Every structure with a GPU form: the BVH in each layout, the kd-tree, the BIH.
fn gpu_forms() -> Vec<AccelKind> {
    (LayoutKind::ALL.iter().map(|&l| AccelKind::Bvh(l)))
        .chain([AccelKind::KdTree, AccelKind::Bih])
        .collect()
}

/// Compares GPU (BVH in the default memory) with CPU on `rays` for every GPU form; returns
/// (agree, tie) of the last.
fn compare(name: &str, mesh: &Mesh, rays: &[Ray], kernel: TraceKernel) -> (usize, usize) {
    compare_in(name, mesh, rays, kernel, BvhMemory::default())
}

/// [`compare`] with the BVH in the given memory.
fn compare_in(
    name: &str,
    mesh: &Mesh,
    rays: &[Ray],
    kernel: TraceKernel,
    memory: BvhMemory,
) -> (usize, usize) {
    let mut counts = (0, 0);
    for form in gpu_forms() {
        let name = format!("{name} {form}");
        counts = compare_form(gpu_device(), &name, mesh, rays, kernel, memory, form);
    }
    counts
}

/// One GPU form on `gpu` against its CPU twin; returns (agree, tie).
fn compare_form(
    gpu: &Device,
    name: &str,
    mesh: &Mesh,
    rays: &[Ray],
    kernel: TraceKernel,
    memory: BvhMemory,
    form: AccelKind,
) -> (usize, usize) {
    let options = kernel.options(memory);
    let cpu_device = Device::cpu();
    let c = Tracer::with_structure(&cpu_device, mesh, form, &options)
        .unwrap()
        .trace(rays, kernel.query)
        .unwrap();
    let g = Tracer::with_structure(gpu, mesh, form, &options)
        .unwrap()
        .trace(rays, kernel.query)
        .unwrap();
    // No set here comes near a driver's loop cap: a retraced ray is a kernel that did not
    // finish (it would hang where the driver has no cap).
    assert_eq!(g.cpu_retraced, 0, "{name}: rays retraced on the CPU");
    let (cpu, cpu_stats, gpu_hits, gpu_stats) = (c.hits, c.stats.unwrap(), g.hits, g.stats);
    let cmp = compare_hits(mesh, rays, kernel.query, &cpu, &gpu_hits);
    let (agree, tie, bad) = (cmp.agree, cmp.ties, cmp.disagree);
    println!(
        "{name} {:?}: {agree} agree ({} identical), {tie} tie, {} disagree",
        kernel.query,
        cmp.identical,
        bad.len()
    );
    assert!(
        bad.is_empty(),
        "{name}: {} disagree; first: {:?}",
        bad.len(),
        bad[0]
    );
    // Same algorithm, same order: the work counts agree wherever the answers do.
    let gs = gpu_stats.unwrap();
    let same_work = cpu_stats.iter().zip(&gs).filter(|(a, b)| a == b).count();
    assert!(
        same_work + tie >= rays.len(),
        "{name}: stats differ on {} rays",
        rays.len() - same_work
    );
    (agree, tie)
}

fn kernels() -> [TraceKernel; 2] {
    [
        TraceKernel::default(),
        TraceKernel {
            query: Query::Any,
            ..TraceKernel::default()
        },
    ]
}

#[test]
fn spatial_split_trees_in_every_layout() {
    // Long thin triangles at every angle among small ones: the SBVH splits many of them, so
    // leaves hold parts of triangles and a triangle is in several leaves.
    let mut rng = Rng::new(77);
    let mut tris = soup(&mut rng, 1500, 0.05).triangles;
    for _ in 0..150 {
        let mut p = || Vec3::new(rng.f32(), rng.f32(), rng.f32());
        let (a, d, w) = (p(), p() - Vec3::splat(0.5), p() * 0.01);
        tris.push(Triangle::new(a, a + d, a + w));
    }
    let mesh = Mesh::from_triangles(tris);
    let tree = lancer::accel::bvh::build(
        &mesh,
        &BuildOptions {
            builder: Builder::Sbvh,
            ..BuildOptions::default()
        },
    );
    assert!(
        tree.order().len() > mesh.len() + 100,
        "{} references",
        tree.order().len()
    );
    let rays = random_rays(&mut rng, 10_000, &mesh);
    for k in kernels() {
        let k = TraceKernel {
            builder: Builder::Sbvh,
            ..k
        };
        compare("sbvh", &mesh, &rays, k);
        // The same hits as the sweep's tree, bit for bit: a split triangle is tested whole.
        let (sweep, sbvh) = (cpu_hits(&mesh, &rays, k.query), {
            let cpu = Device::cpu();
            let mut t = Tracer::new(&cpu, &mesh, &k.options(BvhMemory::default())).unwrap();
            t.trace(&rays, k.query).unwrap().hits
        });
        if k.query == Query::Closest {
            assert!(sweep == sbvh, "sbvh hits differ from the sweep tree's");
        } else {
            let hit = |h: &[Hit]| h.iter().map(|h| h.is_hit()).collect::<Vec<_>>();
            assert_eq!(hit(&sweep), hit(&sbvh));
        }
    }
}

#[test]
fn random_soups() {
    for seed in 0..3 {
        let mut rng = Rng::new(300 + seed);
        let mesh = soup(&mut rng, 3000, 0.15);
        let rays = random_rays(&mut rng, 20_000, &mesh);
        for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
            for k in kernels() {
                let name = format!("soup {seed} {memory:?}");
                let (agree, _) = compare_in(&name, &mesh, &rays, k, memory);
                assert!(agree > 19_000);
            }
        }
    }
}

#[test]
fn models_primary_random_and_inside_rays() {
    for name in ["teapot.obj", "stanford-bunny.obj"] {
        let Some(mesh) = load_model(name) else { return };
        let cam = Camera::default_view(&mesh.bounds(), 160, 120);
        compare(
            &format!("{name} primary"),
            &mesh,
            &cam.primary_rays(),
            TraceKernel::default(),
        );
        let mut rng = Rng::new(17);
        let rays = random_rays(&mut rng, 20_000, &mesh);
        for k in kernels() {
            compare(&format!("{name} random"), &mesh, &rays, k);
        }
        // Rays starting just behind random triangles (inside a closed mesh), any direction.
        let inside: Vec<Ray> = (0..20_000)
            .map(|_| {
                let t = &mesh.triangles[rng.u64() as usize % mesh.len()];
                let c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
                let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
                Ray::new(
                    c - n * 1e-3 * mesh.bounds().extent().length(),
                    rng.dir(),
                    0.0,
                    3.4e38,
                )
            })
            .collect();
        compare(
            &format!("{name} inside"),
            &mesh,
            &inside,
            TraceKernel::default(),
        );
    }
}

#[test]
fn rays_starting_on_a_surface_with_tmin_zero_or_below() {
    // The near-hit rule applies to tmin ≥ 0 only: rays from the centroids of a soup's
    // triangles, half of them asking for hits behind their origin (tmin = -1), the same on
    // every GPU form as on its twin, and judged by the oracle.
    let mut rng = Rng::new(45);
    let mesh = soup(&mut rng, 1500, 0.2);
    let rays: Vec<Ray> = (0..4000)
        .map(|i| {
            let t = &mesh.triangles[rng.u64() as usize % mesh.len()];
            let c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            Ray::new(c, rng.dir(), if i % 2 == 0 { -1.0 } else { 0.0 }, 3.4e38)
        })
        .collect();
    compare("on a surface", &mesh, &rays, TraceKernel::default());
}

#[test]
fn shadow_rays_from_primary_hits() {
    let Some(mesh) = load_model("stanford-bunny.obj") else {
        return;
    };
    let cam = Camera::default_view(&mesh.bounds(), 160, 120);
    let primary = cam.primary_rays();
    let hits = cpu_hits(&mesh, &primary, Query::Closest);
    let b = mesh.bounds();
    let light = b.center() + Vec3::new(0.3, 1.0, 0.5) * b.extent().length();
    let shadow: Vec<Ray> = primary
        .iter()
        .zip(&hits)
        .filter(|(_, h)| h.is_hit())
        .map(|(r, h)| {
            let p = r.origin + r.dir * h.t;
            let to = light - p;
            // Offset relative to the hit distance, as a renderer would, then up to the light.
            Ray::new(p, to.normalize(), 1e-4 * h.t, to.length())
        })
        .collect();
    assert!(shadow.len() > 1000);
    compare(
        "bunny shadow",
        &mesh,
        &shadow,
        TraceKernel {
            query: Query::Any,
            ..TraceKernel::default()
        },
    );
}

#[test]
fn every_variant_matches_the_cpu() {
    // Workgroup sizes, trusted modules, Möller–Trumbore and both BVH memories: one source,
    // same answers.
    let mut rng = Rng::new(44);
    let mesh = soup(&mut rng, 2000, 0.2);
    let rays = random_rays(&mut rng, 5000, &mesh);
    for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
        for workgroup_size in [32, 64, 128] {
            for trusted in [false, true] {
                for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
                    let k = TraceKernel {
                        workgroup_size: Some(workgroup_size),
                        robustness: Robustness {
                            triangle_test: test,
                            checked_module: !trusted,
                            ..Robustness::default()
                        },
                        ..TraceKernel::default()
                    };
                    let name = format!("{memory:?} wg{workgroup_size} trusted={trusted} {test:?}");
                    compare_in(&name, &mesh, &rays, k, memory);
                }
            }
        }
    }
}

#[test]
fn bad_rays_terminate_as_misses() {
    let mut rng = Rng::new(2);
    let mesh = soup(&mut rng, 500, 0.2);
    let rays = nan_zero_and_empty_rays();
    for &layout in LayoutKind::ALL {
        let options = TracerOptions {
            stats: true,
            layout: Some(layout),
            ..TracerOptions::default()
        };
        let mut tracer = Tracer::new(gpu_device(), &mesh, &options).unwrap();
        let result = tracer.trace(&rays, Query::Closest).unwrap();
        assert_eq!(result.cpu_retraced, 0, "{layout}");
        for ((r, h), s) in rays.iter().zip(&result.hits).zip(result.stats.unwrap()) {
            assert!(!h.is_hit(), "{layout} {r:?} hit");
            assert_eq!(s.nodes, 0, "{layout} {r:?} traversed");
        }
    }
}

#[test]
fn large_batches_are_split_and_complete() {
    // More rays than one dispatch holds: the result is the CPU's, in order.
    let mut rng = Rng::new(8);
    let mesh = soup(&mut rng, 1000, 0.1);
    let rays = random_rays(&mut rng, (1 << 18) + 12345, &mesh);
    let cpu = cpu_hits(&mesh, &rays, Query::Closest);
    let mut tracer = Tracer::new(gpu_device(), &mesh, &TracerOptions::default()).unwrap();
    let g = tracer.trace(&rays, Query::Closest).unwrap().hits;
    assert_eq!(g.len(), rays.len());
    let same = cpu.iter().zip(&g).filter(|(a, b)| a.prim == b.prim).count();
    assert!(
        same as f64 >= 0.999 * rays.len() as f64,
        "{same} of {}",
        rays.len()
    );
    assert_eq!(cpu.last().unwrap().prim, g.last().unwrap().prim);
}

#[test]
fn axis_parallel_rays_on_box_faces() {
    // Origins exactly on node-box face planes with zero (and −0.0) direction components:
    // the slab test's parallel-axis rule, identical on both sides.
    let mut rng = Rng::new(21);
    let mesh = soup(&mut rng, 400, 0.2);
    let b = mesh.bounds();
    let mut rays = Vec::new();
    for i in 0..=20 {
        for j in 0..=20 {
            let (u, v) = (i as f32 / 20.0, j as f32 / 20.0);
            for (o, d) in [
                (
                    Vec3::new(b.lo.x + u * (b.hi.x - b.lo.x), b.hi.y, b.lo.z - 1.0),
                    Vec3::Z,
                ),
                (
                    Vec3::new(b.hi.x, b.lo.y + u * (b.hi.y - b.lo.y), b.hi.z + 1.0),
                    Vec3::new(-0.0, 0.0, -1.0),
                ),
                (
                    Vec3::new(
                        b.lo.x - 1.0,
                        b.lo.y + u * (b.hi.y - b.lo.y),
                        b.lo.z + v * (b.hi.z - b.lo.z),
                    ),
                    Vec3::X,
                ),
            ] {
                rays.push(Ray::new(o, d, 0.0, 100.0));
            }
        }
    }
    compare("axis-parallel", &mesh, &rays, TraceKernel::default());
    compare(
        "axis-parallel",
        &mesh,
        &rays,
        TraceKernel {
            query: Query::Any,
            ..TraceKernel::default()
        },
    );
}

#[test]
fn axis_parallel_rays_on_exact_planes_of_every_layout() {
    // Integer vertices, so every layout's boxes are exact, cwbvh's 8-bit ones included (its
    // frames' steps are powers of two no coarser than 1): vertical rays through every vertex
    // and edge midpoint start on box planes, the grid's last row and column on the high planes
    // of every box that holds them. The parallel-axis rule keeps those boxes entered; a slab
    // test without it ends each such interval at t = 0 and misses the grid's border.
    let n = 16;
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let p = |a: usize, b: usize| Vec3::new(a as f32, b as f32, 0.0);
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    let mesh = Mesh::from_triangles(tris);
    let mut rays = Vec::new();
    for i in 0..=2 * n {
        for j in 0..=2 * n {
            let (x, y) = (i as f32 / 2.0, j as f32 / 2.0);
            for d in [Vec3::NEG_Z, Vec3::new(-0.0, -0.0, -1.0)] {
                rays.push(Ray::new(Vec3::new(x, y, 1.0), d, 0.0, 10.0));
            }
        }
    }
    let cpu = cpu_hits(&mesh, &rays, Query::Closest);
    let border = rays.len() - cpu.iter().filter(|h| h.is_hit()).count();
    assert_eq!(border, 0, "{border} rays missed the grid on the CPU");
    compare("exact planes", &mesh, &rays, TraceKernel::default());
}

#[test]
fn deep_stacks_spill_and_refill() {
    // Levels of 64 squares, each level half as far from x = 0 and half as wide as the last,
    // the squares of a level one after another along x: the builders nest the levels, and a
    // ray from x < 0 along +x near the axis enters every box, so the levels' subtrees wait on
    // the stack while the deeper (nearer) ones are visited. cwbvh's stack reaches six groups,
    // past the four it holds in variables (cwbvh.wgsl, group_push; the models reach five):
    // this fails if the kernel drops the groups it moves to its array, or stores them in the
    // wrong place (both checked).
    let mut tris = Vec::new();
    for level in 0..30 {
        let s = 0.5f32.powi(level);
        for j in 0..64 {
            let x = s * (1.0 + j as f32 / 256.0);
            let p = |y: f32, z: f32| Vec3::new(x, y * s, z * s);
            tris.push(Triangle::new(p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0)));
            tris.push(Triangle::new(p(-1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)));
        }
    }
    let mesh = Mesh::from_triangles(tris);
    let mut rng = Rng::new(11);
    let mut rays = Vec::new();
    for _ in 0..2000 {
        // Offsets from the axis spread over many scales, so rays end at many depths.
        let scale = 0.5f32.powi((rng.u64() % 30) as i32);
        let (y, z) = (rng.range(-1.0, 1.0) * scale, rng.range(-1.0, 1.0) * scale);
        let dir = Vec3::new(1.0, rng.range(-1e-3, 1e-3), rng.range(-1e-3, 1e-3));
        rays.push(Ray::new(Vec3::new(-1.0, y, z), dir, 0.0, f32::INFINITY));
    }
    let cpu = cpu_hits(&mesh, &rays, Query::Closest);
    let hits = cpu.iter().filter(|h| h.is_hit()).count();
    assert!(hits > rays.len() / 2, "only {hits} rays hit the squares");
    for kernel in kernels() {
        compare("deep stacks", &mesh, &rays, kernel);
    }
}

#[test]
fn oversized_bvh_is_refused_naming_size_and_limit() {
    // A device of our own whose recorded limits we shrink: the checks run before upload.
    gpu_device(); // fails with the install hint when there is no adapter
    let mut ctx = lancer::gpu::GpuContext::new().unwrap();
    ctx.limits.max_storage_buffer_binding_size = 1024;
    ctx.limits.max_buffer_size = 1024;
    ctx.limits.max_texture_dimension_2d = 1024;
    let device = Device::gpu(ctx);
    let mut rng = Rng::new(5);
    let mesh = soup(&mut rng, 100, 0.2);
    for (memory, limit) in [
        (BvhMemory::Buffers, "max_buffer_size"),
        (BvhMemory::Textures, "max_texture_dimension_2d"),
    ] {
        // dfs-sign's arrays: a size in KiB (the default layout's may be smaller).
        let options = TracerOptions {
            memory,
            layout: Some(lancer::LayoutKind::DfsSign),
            ..TracerOptions::default()
        };
        let e = Tracer::new(&device, &mesh, &options)
            .err()
            .unwrap_or_else(|| panic!("{memory:?}: an oversized BVH was uploaded"))
            .to_string();
        assert!(e.contains(limit), "{memory:?}: {e}");
        assert!(e.contains("KiB"), "{memory:?}: the size is not named: {e}");
    }
}

/// Node and triangle arrays bigger than one storage binding in buffer memory are bound in
/// parts: on a device whose recorded binding limit is shrunk to 2 KiB (parts of 128 words),
/// every GPU form traces what its CPU twin does, closest and any hit, in the checked module
/// (whose bounds checks turn a word read from the wrong part into zero) and the trusted one.
/// Too many parts for the device's storage buffers a stage are refused, naming the limit.
#[test]
fn arrays_beyond_one_binding_are_bound_in_parts() {
    gpu_device(); // fails with the install hint when there is no adapter
    let mut ctx = lancer::gpu::GpuContext::new().unwrap();
    ctx.limits.max_storage_buffer_binding_size = 2048;
    let mut rng = Rng::new(17);
    let mesh = soup(&mut rng, 100, 0.2);
    let rays = random_rays(&mut rng, 1000, &mesh);
    let bvh = lancer::accel::bvh::build(&mesh, &BuildOptions::default());
    let dfs = lancer::accel::bvh::layouts::flatten(LayoutKind::DfsSign, &bvh, &mesh);
    let parts = lancer::gpu::GpuTracer::new(&ctx, dfs.as_ref(), BvhMemory::Buffers)
        .unwrap()
        .parts();
    assert!(parts.nodes > 1 && parts.tris > 1, "{parts:?}");
    assert_eq!(parts.shift, 7);
    let mut few = lancer::gpu::GpuContext::new().unwrap();
    few.limits.max_storage_buffer_binding_size = 2048;
    few.limits.max_storage_buffers_per_shader_stage = 6;
    let e = lancer::gpu::GpuTracer::new(&few, dfs.as_ref(), BvhMemory::Buffers)
        .err()
        .expect("more storage buffers than the device allows")
        .to_string();
    assert!(
        e.contains("storage buffers") && e.contains("allows 6"),
        "{e}"
    );

    let gpu = Device::gpu(ctx);
    for checked_module in [true, false] {
        let robustness = Robustness {
            checked_module,
            ..Robustness::default()
        };
        for kernel in kernels() {
            let kernel = TraceKernel {
                robustness,
                ..kernel
            };
            for form in gpu_forms() {
                let name = format!("parts {form} checked {checked_module}");
                compare_form(&gpu, &name, &mesh, &rays, kernel, BvhMemory::Buffers, form);
            }
        }
    }
}

/// A layout whose triangles may have been moved after it was built: its validation runs
/// the layout's own checks on the arrays it uploads.
struct Moved {
    inner: Box<dyn lancer::accel::GpuForm>,
    kind: LayoutKind,
    tris: Vec<u8>,
}

impl lancer::accel::Accel for Moved {
    fn bounds(&self) -> lancer::geometry::Aabb {
        self.inner.bounds()
    }

    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: lancer::accel::Mask<'_>,
        stats: &mut lancer::accel::RayStats,
    ) -> Hit {
        self.inner
            .intersect_masked(ray, query, robustness, mask, stats)
    }
}

impl lancer::accel::GpuForm for Moved {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn arrays(&self) -> lancer::accel::GpuArrays<'_> {
        lancer::accel::GpuArrays::new(self.inner.arrays().nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        self.inner.wgsl()
    }

    fn validate(&self) -> Result<(), String> {
        lancer::accel::bvh::layouts::from_arrays(self.kind, self.arrays()).map(|_| ())
    }

    fn node_bytes(&self) -> usize {
        self.inner.node_bytes()
    }
}

/// The upload's validation decides: a layout whose first triangle was moved out of its
/// boxes is refused in both memories, naming what is wrong; the same layout unmoved is
/// uploaded.
#[test]
fn a_layout_failing_validation_is_refused_in_both_memories() {
    let ctx = common::gpu();
    let mut rng = Rng::new(23);
    let mesh = soup(&mut rng, 300, 0.2);
    let bvh = lancer::accel::bvh::build(&mesh, &BuildOptions::default());
    for kind in [LayoutKind::Cwbvh, LayoutKind::DfsSign] {
        let inner = lancer::accel::bvh::layouts::flatten(kind, &bvh, &mesh);
        let tris = inner.arrays().tris.to_vec();
        let mut moved = Moved { inner, kind, tris };
        for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
            let uploaded = lancer::gpu::GpuTracer::new(ctx, &moved, memory);
            assert!(
                uploaded.is_ok(),
                "{kind} {memory:?}: the unmoved layout refused"
            );
        }
        moved.tris[..4].copy_from_slice(&1.0e6f32.to_le_bytes());
        for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
            let e = match lancer::gpu::GpuTracer::new(ctx, &moved, memory) {
                Ok(_) => panic!("{kind} {memory:?}: a moved triangle was uploaded"),
                Err(e) => e.to_string(),
            };
            assert!(
                e.contains("refusing to upload an invalid BVH"),
                "{kind}: {e}"
            );
        }
    }
}

/// A layout's arrays read in place by a device whose memory is the host's (lavapipe:
/// `VK_EXT_external_memory_host`) trace as copied ones, hit for hit and node for node, in
/// both memories and for every BVH layout. On lavapipe arrays are imported: a texture's only
/// where its flatten left room for it (arrays of at least `ROOM_MIN_BYTES`) and it starts on
/// the driver's image alignment (which, with the allocator's placement, decides), a buffer's
/// wherever it starts aligned as bindings need; nothing is imported where the
/// context says not to. The tracer alone keeps the layout alive while the device reads it,
/// and lets it go once the device is done; words read in place cannot be written over.
#[test]
fn arrays_read_in_place_trace_as_copied_ones() {
    use std::sync::Arc;
    gpu_device(); // fails with the install hint when there is no adapter
    let ctx = lancer::gpu::GpuContext::new().unwrap();
    let lavapipe = ctx.adapter.name.contains("llvmpipe");
    if lavapipe {
        assert!(ctx.import_host_memory, "lavapipe imports host memory");
    }
    // See the end: where every texture array with room must be imported.
    let mesa22 = ctx.adapter.driver.contains("Mesa 22.");
    let mut copying = ctx.clone();
    copying.import_host_memory = false;
    let mut rng = Rng::new(29);
    // Triangle arrays of 1.4 MB, node arrays either side of ROOM_MIN_BYTES.
    let mesh = soup(&mut rng, 30_000, 0.02);
    let rays = random_rays(&mut rng, 2000, &mesh);
    let bvh = lancer::accel::bvh::build(&mesh, &BuildOptions::default());
    let mut imported = [0usize; 2];
    for &kind in LayoutKind::ALL {
        for memory in [BvhMemory::Textures, BvhMemory::Buffers] {
            let mut traced = Vec::new();
            for c in [&ctx, &copying] {
                let layout: Arc<dyn lancer::accel::GpuForm> =
                    lancer::accel::bvh::layouts::flatten(kind, &bvh, &mesh).into();
                let a = layout.arrays();
                let roomy = [a.room()[0] > a.nodes.len(), a.room()[1] > a.tris.len()];
                assert_eq!(
                    roomy,
                    [a.nodes.len(), a.tris.len()].map(|n| n >= lancer::accel::ROOM_MIN_BYTES),
                    "{kind}: room"
                );
                let weak = Arc::downgrade(&layout);
                let mut t = lancer::gpu::GpuTracer::new_shared(c, &layout, memory).unwrap();
                drop(layout);
                let in_place = t.in_place();
                let name = format!("{kind} {memory:?} import {}", c.import_host_memory);
                println!("{name}: room {roomy:?}, in place {in_place:?}");
                if !c.import_host_memory {
                    assert_eq!(in_place, [false; 2], "{name}");
                } else if lavapipe && memory == BvhMemory::Textures && mesa22 {
                    assert_eq!(in_place, roomy, "{name}");
                }
                for k in 0..2 {
                    // A texture's last rows need the room; a buffer needs none.
                    let needs_room = memory == BvhMemory::Textures;
                    assert!(
                        roomy[k] || !in_place[k] || !needs_room,
                        "{name}: past the room"
                    );
                    imported[k] += in_place[k] as usize;
                }
                assert_eq!(
                    weak.upgrade().is_some(),
                    in_place.contains(&true),
                    "{name}: kept"
                );
                if in_place[0] {
                    let e = t.write_node_words(0, &[0; 16]).unwrap_err().to_string();
                    assert!(e.contains("read in place"), "{e}");
                }
                if in_place[1] {
                    let e = t.write_tri_words(0, &[0; 16]).unwrap_err().to_string();
                    assert!(e.contains("read in place"), "{e}");
                }
                let k = lancer::gpu::TraceKernel {
                    stats: true,
                    ..Default::default()
                };
                traced.push(t.trace(&rays, k).unwrap());
                drop(t);
                let _ = c
                    .device
                    .poll(lancer::gpu::wgpu::PollType::wait_indefinitely());
                assert!(
                    weak.upgrade().is_none(),
                    "{name}: the layout outlived the device's use"
                );
            }
            let (a, b) = (&traced[0], &traced[1]);
            let bits = |h: &[Hit]| -> Vec<(u32, u32)> {
                h.iter().map(|h| (h.prim, h.t.to_bits())).collect()
            };
            assert_eq!(bits(&a.0), bits(&b.0), "{kind} {memory:?}: hits");
            assert_eq!(a.1, b.1, "{kind} {memory:?}: statistics");
        }
    }
    // Mesa 22's lavapipe (Debian 12's, CI's) asks 16-byte image alignment, which every
    // allocation meets: there every texture array with room is read in place. Later ones ask
    // more, which this test's allocator meets by chance (the CLI's mimalloc places big
    // arrays aligned), so there only what was imported is checked.
    if lavapipe && mesa22 {
        assert!(imported[0] > 0 && imported[1] > 0, "imported {imported:?}");
    }
    println!("arrays read in place: {imported:?} (nodes, triangles)");
}
