//! The library as an application meets it: a mesh from its own arrays
//! (`Mesh::from_indexed`), its own wgpu device and queue (`GpuContext::from_wgpu`), and a
//! layout handed in from outside (`Tracer::with_layout`). Hits on the application's device
//! equal the CPU's bit for bit.

use std::sync::Arc;

use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::gpu::{wgpu, GpuContext};
use lancer::mesh::TriStatus;
use lancer::render::{render, AlphaMask, EffectSet};
use lancer::{Device, GpuForm, Hit, Mesh, Query, Ray, RenderOptions, RenderScene, Vec3};
use lancer::{Tracer, TracerOptions};

/// A grid of `n`×`n` quads (two triangles each) on a bumpy height field, as an application
/// would hold it: positions and index triples. One extra triangle names a vertex that does
/// not exist, another has zero area.
fn height_field(n: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            let y = 0.1 * (7.0 * x).sin() * (5.0 * z).cos();
            positions.push([x, y, z]);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            indices.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            indices.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    indices.push([0, 1, u32::MAX]);
    indices.push([0, 0, 1]);
    (positions, indices)
}

/// Rays from above the height field, straight down and slanted, some missing it.
fn rays() -> Vec<Ray> {
    let mut rays = Vec::new();
    for j in 0..24 {
        for i in 0..24 {
            let o = Vec3::new(
                -0.1 + 1.2 * i as f32 / 23.0,
                1.0,
                -0.1 + 1.2 * j as f32 / 23.0,
            );
            let d = Vec3::new(0.3 * (i as f32 / 23.0 - 0.5), -1.0, 0.2).normalize();
            rays.push(Ray::new(o, d, 0.0, 1e30));
        }
    }
    rays
}

fn bits(hits: &[Hit]) -> Vec<[u32; 4]> {
    hits.iter()
        .map(|h| [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()])
        .collect()
}

/// The application's own device: its own instance, adapter and descriptor (wgpu's default
/// limits and no optional feature), as an application that renders with wgpu opens it.
fn app_device(limits: wgpu::Limits) -> (wgpu::Device, wgpu::Queue) {
    pollster::block_on(async {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            // Vulkan, Metal, DX12: the GL backend probes window systems on a headless host.
            desc.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(desc);
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions::default())
            .await
            .expect("the library tests need a GPU adapter (lavapipe will do)");
        println!("adapter: {}", adapter.get_info().name);
        adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("the application's device"),
                required_limits: limits,
                ..Default::default()
            })
            .await
            .expect("a device opens")
    })
}

#[test]
fn mesh_from_arrays_traces_like_any_mesh() {
    let (positions, indices) = height_field(8);
    let mesh = Mesh::from_indexed(&positions, &indices).unwrap();
    assert_eq!(mesh.len(), indices.len());
    assert_eq!(mesh.status[128], TriStatus::OutOfRange);
    assert_eq!(mesh.status[129], TriStatus::Degenerate);
    assert_eq!(mesh.included().len(), 128);
    // glam vectors work too, and give the same mesh.
    let vecs: Vec<Vec3> = positions.iter().map(|&p| p.into()).collect();
    let same = Mesh::from_indexed(&vecs, &indices).unwrap();
    assert_eq!(same.status, mesh.status);
    // Indices kept flat, three per triangle, become triples without a copy.
    let flat: Vec<u32> = indices.iter().flatten().copied().collect();
    let (triples, rest) = flat.as_chunks::<3>();
    assert!(rest.is_empty());
    assert_eq!(
        Mesh::from_indexed(&positions, triples).unwrap().len(),
        mesh.len()
    );

    let device = Device::cpu();
    let mut tracer = Tracer::new(&device, &mesh, &TracerOptions::default()).unwrap();
    let hits = tracer.trace(&rays(), Query::Closest).unwrap().hits;
    let hit = hits.iter().filter(|h| h.is_hit()).count();
    assert!(
        hit > 100 && hit < hits.len(),
        "{hit} of {} rays hit",
        hits.len()
    );
    assert!(hits.iter().all(|h| !h.is_hit() || h.prim < 128));
    // Handing the mesh over (freed before the upload) traces the same.
    let mut owned = Tracer::from_mesh(&device, mesh, &TracerOptions::default()).unwrap();
    assert_eq!(
        bits(&owned.trace(&rays(), Query::Closest).unwrap().hits),
        bits(&hits)
    );
}

#[test]
fn an_applications_own_device_traces_like_the_cpu() {
    let (device, queue) = app_device(wgpu::Limits::default());
    let ctx = GpuContext::from_wgpu(device.clone(), queue).unwrap();
    // Only what the device was created with: no timestamps, no subgroups, no ray queries.
    assert!(!ctx.timestamps && ctx.subgroups.is_none() && !ctx.ray_query);
    assert_eq!(ctx.limits, device.limits());
    let gpu = Device::gpu(ctx);

    let (positions, indices) = height_field(16);
    let mesh = Mesh::from_indexed(&positions, &indices).unwrap();
    let rays = rays();
    let cpu = Device::cpu();
    let options = TracerOptions::default();
    for query in [Query::Closest, Query::Any] {
        let want = Tracer::new(&cpu, &mesh, &options)
            .unwrap()
            .trace(&rays, query);
        let got = Tracer::new(&gpu, &mesh, &options)
            .unwrap()
            .trace(&rays, query);
        let (want, got) = (want.unwrap(), got.unwrap());
        assert_eq!(got.cpu_retraced, 0);
        match query {
            Query::Closest => assert_eq!(bits(&got.hits), bits(&want.hits)),
            // Any hit: the same rays hit (which triangle may differ between layouts).
            Query::Any => assert!(got
                .hits
                .iter()
                .zip(&want.hits)
                .all(|(g, w)| g.is_hit() == w.is_hit())),
        }
    }

    // The same layout, handed in from outside, on the application's device and the CPU.
    let layout: Arc<dyn GpuForm> = flatten(
        LayoutKind::Bvh8,
        &build(&mesh, &BuildOptions::default()),
        &mesh,
    )
    .into();
    let mut on_gpu = Tracer::with_layout(&gpu, layout.clone(), &options).unwrap();
    let mut on_cpu = Tracer::with_layout(&cpu, layout, &options).unwrap();
    for query in [Query::Closest, Query::Any] {
        let got = on_gpu.trace(&rays, query).unwrap().hits;
        let want = on_cpu.trace(&rays, query).unwrap().hits;
        assert_eq!(bits(&got), bits(&want), "{query:?}");
    }

    // The application keeps using its device after lancer's work.
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("the application's buffer"),
        size: 16,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    assert_eq!(buffer.size(), 16);
}

/// The Cornell box at 8×8 pixels, and options for one sample a pixel.
fn small_cornell() -> (RenderScene, RenderOptions) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let mut scene = RenderScene::from_file(&path).unwrap();
    (scene.camera.width, scene.camera.height) = (8, 8);
    let options = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    (scene, options)
}

#[test]
fn an_applications_own_device_renders() {
    let (device, queue) = app_device(wgpu::Limits::default());
    let gpu = Device::gpu(GpuContext::from_wgpu(device, queue).unwrap());
    let (scene, options) = small_cornell();
    let rendered = render(&scene, &gpu, &options).unwrap();
    assert_eq!((rendered.image.width, rendered.image.height), (8, 8));
}

#[test]
fn a_device_too_small_for_the_kernels_is_refused() {
    // wgpu's downlevel limits: four storage buffers per stage, fewer than the trace kernel's.
    let (device, queue) = app_device(wgpu::Limits::downlevel_defaults());
    let e = GpuContext::from_wgpu(device, queue).err().expect("refused");
    assert!(e.to_string().contains("storage buffers"), "{e}");
}

/// What an application assembles itself, with arrays that disagree, is refused with an
/// error rather than a panic, wherever the library takes it (found by a probe of the API).
#[test]
fn inconsistent_arrays_made_in_code_are_refused_not_panicked_on() {
    use lancer::accel::bvh::{build_boxes, Builder};
    use lancer::accel::instances::{Affine, Instance, InstanceSet};
    use lancer::geometry::Aabb;

    let cpu = Device::cpu();
    let (p, t) = height_field(4);
    let mesh = Mesh::from_indexed(&p, &t).unwrap();

    // A mesh with a status missing.
    let mut short = mesh.clone();
    short.status.pop();
    let e = Tracer::new(&cpu, &short, &TracerOptions::default())
        .err()
        .expect("refused");
    assert!(e.to_string().contains("statuses"), "{e}");

    // Instances of a mesh that is not there, flattened or in two levels.
    let set = InstanceSet {
        meshes: vec![Arc::new(mesh.clone())],
        instances: vec![Instance {
            mesh: 5,
            to_world: Affine::IDENTITY,
        }],
    };
    for flatten in [true, false] {
        let options = TracerOptions {
            flatten,
            ..TracerOptions::default()
        };
        let e = Tracer::with_instances(&cpu, &set, &options)
            .err()
            .expect("refused");
        assert!(e.to_string().contains("places mesh 5"), "{e}");
    }
    // Its counts skip the missing mesh (they indexed past the meshes), and its flattened
    // copy is refused as the set is.
    assert_eq!(set.triangle_count(), 0);
    assert_eq!(set.first_prims(), [0]);
    assert_eq!(set.bounds(), Aabb::EMPTY);
    let e = set.flatten().expect_err("refused");
    assert!(e.to_string().contains("places mesh 5"), "{e}");

    // Placed too small to trace in world space: refused as the same mesh that small is.
    let tiny =
        Affine::from_mat3_translation(glam::Mat3::from_diagonal(Vec3::splat(1e-14)), Vec3::ZERO);
    let placed = |to_world| InstanceSet {
        meshes: vec![Arc::new(mesh.clone())],
        instances: vec![Instance { mesh: 0, to_world }; 2],
    };
    let path = std::path::Path::new("forest.glb");
    placed(Affine::IDENTITY)
        .check_usable(path)
        .expect("a set at its size is usable");
    let e = placed(tiny).check_usable(path).expect_err("refused");
    assert!(
        e.to_string().contains("forest.glb: the scene is") && e.to_string().contains("across"),
        "{e}"
    );
    let e =
        lancer::mesh::check_usable(path, &placed(tiny).flatten().unwrap()).expect_err("refused");
    assert!(e.to_string().contains("the mesh is"), "{e}");

    // A scene whose material names a texture it does not have, or whose material indices
    // are short, on the CPU and on the GPU.
    let (scene, options) = small_cornell();
    let mut no_texture = scene.clone();
    no_texture.materials[0].texture = Some(99);
    let mut short_materials = scene.clone();
    short_materials.material_of.pop();
    let gpu = Device::open(lancer::DeviceChoice::Gpu).ok();
    for device in std::iter::once(&cpu).chain(gpu.as_ref()) {
        let e = render(&no_texture, device, &options).expect_err("refused");
        assert!(e.to_string().contains("texture 99"), "{e}");
        let e = render(&short_materials, device, &options).expect_err("refused");
        assert!(e.to_string().contains("material indices"), "{e}");
    }
    render(&scene, &cpu, &options).expect("the scene as read renders");
    // The same scenes through the lower-level entry points that indexed their arrays
    // unchecked: an alpha mask, the flattened scene, a frame.
    let e = AlphaMask::new(&no_texture, EffectSet::of(&no_texture))
        .err()
        .expect("refused");
    assert!(e.to_string().contains("texture 99"), "{e}");
    let short_fx = EffectSet::of(&short_materials); // reads the materials it can name
    let e = AlphaMask::new(&short_materials, short_fx)
        .err()
        .expect("refused");
    assert!(e.to_string().contains("material indices"), "{e}");
    let e = short_materials.at_frame(0).expect_err("refused");
    assert!(e.to_string().contains("material indices"), "{e}");
    assert!(AlphaMask::new(&scene, EffectSet::of(&scene)).is_ok());

    // Settings a render cannot run with, refused before any work: more bounces than paths
    // may follow (a closed scene's samples would each take billions: a hang), no sample.
    let max = lancer::limits::MAX_BOUNCES;
    let mut endless = scene.clone();
    endless.settings.max_bounces = 4_000_000_000;
    let mut deepest = scene.clone();
    deepest.settings.max_bounces = max;
    let mut no_samples = scene.clone();
    no_samples.settings.spp = 0;
    for device in std::iter::once(&cpu).chain(gpu.as_ref()) {
        let e = render(&endless, device, &options).expect_err("refused");
        assert!(e.to_string().contains(&format!("more than {max}")), "{e}");
        let e = render(&no_samples, device, &options).expect_err("refused");
        assert!(e.to_string().contains("spp must be at least 1"), "{e}");
        // An spp of 0 asked of a renderer is a usage error, not an interrupted render.
        let zero = RenderOptions {
            spp: Some(0),
            ..options.clone()
        };
        let e = render(&scene, device, &zero).expect_err("refused");
        assert!(matches!(e, lancer::Error::Usage(_)), "{e:?}");
    }
    let one = RenderOptions {
        spp: Some(1),
        ..options.clone()
    };
    render(&deepest, &cpu, &one).expect("the most bounces render");

    // An image with fewer pixels than its size.
    let dir = std::env::temp_dir().join(format!("lancer-short-image-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("short.png");
    let e = lancer::render::save_image(&png, &[Vec3::ONE; 2], 4, 4).expect_err("refused");
    assert!(e.to_string().contains("2 pixels for a 4×4 image"), "{e}");
    assert!(!png.exists());
    std::fs::remove_dir_all(&dir).ok();

    // NaN boxes: every builder makes a tree over all of them (PLOC named no neighbour).
    let nan = Aabb {
        lo: Vec3::NAN,
        hi: Vec3::NAN,
    };
    for builder in [
        Builder::Sweep,
        Builder::Binned,
        Builder::Median,
        Builder::Ploc,
    ] {
        let opts = BuildOptions {
            builder,
            ..BuildOptions::default()
        };
        assert_eq!(
            build_boxes(&[nan; 4], &opts).order().len(),
            4,
            "{builder:?}"
        );
    }
}
