//! The LBVH built on the GPU (lavapipe in CI) equals its CPU twin: the same Morton order,
//! the same radix tree, the same boxes, hence the same BVH.

mod common;

use common::{gpu, load_model, soup, Rng};
use glam::Vec3;
use lancer::accel::bvh::layouts::DfsSign;
use lancer::accel::bvh::lbvh::{radix_tree, RadixTree, LEAF_BIT};
use lancer::accel::bvh::{build, BuildOptions, Builder};
use lancer::geometry::{Aabb, Triangle};
use lancer::gpu::{build_lbvh, lbvh_dfs_sign, lbvh_radix_tree};
use lancer::mesh::Mesh;

/// Scenes that stress each step: many tiles of the sort, equal codes (one cell holding many
/// triangles, and exact copies), a flat scene (one axis of zero width), negative and mixed
/// coordinates, and triangles at ±0.
fn scenes() -> Vec<(String, Vec<Triangle>)> {
    let mut rng = Rng::new(11);
    let mut v = vec![
        ("soup".to_string(), soup(&mut rng, 5000, 0.05).triangles),
        ("two".to_string(), soup(&mut rng, 2, 0.5).triangles),
    ];
    let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let mut copies = vec![t; 700];
    copies.extend(soup(&mut rng, 300, 1e-4).triangles);
    v.push(("copies".to_string(), copies));
    let flat = (0..900)
        .map(|i| {
            let o = Vec3::new((i % 30) as f32 - 15.0, (i / 30) as f32 * -0.5, 0.0);
            Triangle::new(o, o + Vec3::X, o + Vec3::Y)
        })
        .collect();
    v.push(("flat".to_string(), flat));
    let signed = (0..64)
        .map(|i| {
            let s = if i % 2 == 0 { -0.0 } else { 0.0 };
            let o = Vec3::new(s, i as f32 * 1e-3, s);
            Triangle::new(o, o + Vec3::new(s, 1.0, 1.0), o + Vec3::new(1.0, s, 1.0))
        })
        .collect();
    v.push(("signed zeros".to_string(), signed));
    if let Some(m) = load_model("stanford-bunny.obj") {
        v.push(("bunny".to_string(), m.triangles));
    }
    v
}

/// Panics naming the first place where the trees differ.
fn same_tree(name: &str, gpu: &RadixTree, cpu: &RadixTree) {
    fn first<T: PartialEq + std::fmt::Debug>(name: &str, what: &str, g: &[T], c: &[T]) {
        assert_eq!(g.len(), c.len(), "{name}: {what}: lengths");
        if let Some(i) = (0..g.len()).find(|&i| g[i] != c[i]) {
            panic!("{name}: {what} [{i}]: GPU {:?}, CPU {:?}", g[i], c[i]);
        }
    }
    first(name, "Morton order", &gpu.sorted, &cpu.sorted);
    first(name, "children", &gpu.kids, &cpu.kids);
    // Boxes equal as numbers (a -0 and a +0 of a min may come out either way).
    first(name, "node boxes", &gpu.boxes, &cpu.boxes);
}

#[test]
fn the_gpu_radix_tree_is_the_cpu_twins() {
    for (name, tris) in scenes() {
        let boxes: Vec<Aabb> = tris.iter().map(|t| t.bbox()).collect();
        let cpu = radix_tree(&boxes, true);
        let g = lbvh_radix_tree(gpu(), &tris).unwrap_or_else(|e| panic!("{name}: {e}"));
        same_tree(&name, &g, &cpu);
        println!("{name}: {} triangles, trees equal", tris.len());
    }
}

/// The comparison can fail: a tree that differs in one child, or one box, is told apart.
#[test]
fn a_changed_tree_is_told_apart() {
    let (_, tris) = scenes().swap_remove(0);
    let boxes: Vec<Aabb> = tris.iter().map(|t| t.bbox()).collect();
    let cpu = radix_tree(&boxes, false);
    let mut kids = cpu.clone();
    kids.kids[3].swap(0, 1);
    let mut wider = cpu.clone();
    wider.boxes[5].hi.x = f32::from_bits(wider.boxes[5].hi.x.to_bits() + 1);
    for changed in [kids, wider] {
        let caught = std::panic::catch_unwind(|| same_tree("changed", &changed, &cpu));
        assert!(caught.is_err());
    }
    assert!(cpu.kids.iter().flatten().any(|&k| k & LEAF_BIT != 0));
}

#[test]
fn the_gpu_lbvh_is_the_cpu_lbvh() {
    let mut rng = Rng::new(3);
    let mut mesh = soup(&mut rng, 3000, 0.1);
    // A degenerate triangle, excluded on both devices.
    mesh = Mesh::from_triangles({
        let mut t = mesh.triangles;
        t.insert(7, Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::ONE));
        t
    });
    for optimize in [false, true] {
        let opts = BuildOptions {
            builder: Builder::Lbvh,
            optimize,
            ..BuildOptions::default()
        };
        let g = build_lbvh(gpu(), &mesh, &opts).expect("GPU build");
        assert_eq!(g, build(&mesh, &opts), "optimize {optimize}");
        assert_eq!(g.order().len(), mesh.triangles.len() - 1);
    }
}

/// Built and flattened on the GPU, the dfs-sign arrays are those the CPU flattens from its
/// own LBVH: same nodes, same triangles in the same leaf order.
#[test]
fn the_gpu_flattens_the_lbvh_into_the_cpus_dfs_sign() {
    for (name, tris) in scenes() {
        let mesh = Mesh::from_triangles(tris);
        for max_leaf in [16, 1, 4] {
            let opts = BuildOptions {
                builder: Builder::Lbvh,
                max_leaf,
                t_cube: if max_leaf == 4 { 0.3 } else { 1.0 },
                ..BuildOptions::default()
            };
            let g = lbvh_dfs_sign(gpu(), &mesh, &opts).unwrap_or_else(|e| panic!("{name}: {e}"));
            let bvh = build(&mesh, &opts);
            let c = DfsSign::flatten(&bvh, &mesh);
            assert!(
                g == c,
                "{name}, max leaf {max_leaf}: the GPU's dfs-sign differs"
            );
            // The tree the arrays hold is the CPU's.
            assert!(
                g.tree(mesh.len()) == bvh,
                "{name}, max leaf {max_leaf}: tree"
            );
        }
    }
}

/// A device of its own whose recorded limits `shrink` changes (the driver's stay as they
/// are), and 3,000 triangles: the GPU's radix tree and dfs-sign arrays are the CPU's there.
fn same_on_a_shrunk_device(
    name: &str,
    shrink: impl Fn(&mut lancer::gpu::GpuContext),
) -> (lancer::gpu::GpuContext, Mesh, BuildOptions) {
    common::gpu_device(); // fails with the install hint when there is no adapter
    let mut small = lancer::gpu::GpuContext::new().unwrap();
    shrink(&mut small);
    let mesh = soup(&mut Rng::new(21), 3000, 0.1);
    let boxes: Vec<Aabb> = mesh.triangles.iter().map(|t| t.bbox()).collect();
    let tree = lbvh_radix_tree(&small, &mesh.triangles).unwrap();
    same_tree(name, &tree, &radix_tree(&boxes, false));
    let opts = BuildOptions {
        builder: Builder::Lbvh,
        ..BuildOptions::default()
    };
    let g = lbvh_dfs_sign(&small, &mesh, &opts).unwrap();
    let cpu = DfsSign::flatten(&build(&mesh, &opts), &mesh);
    assert!(g == cpu, "{name}: the dfs-sign arrays differ");
    (small, mesh, opts)
}

/// Arrays bigger than one storage binding are bound in parts: with the binding limit shrunk
/// to 16 KiB, every array of the 3,000 triangles bigger than that spans several parts (the
/// leaf triangles nine, the boxes five), and the trees are still the CPU's (the checked module reads a
/// word from a wrong part as zero). Too many parts for the device's storage buffers a stage
/// are refused, naming the limit.
#[test]
fn arrays_beyond_one_binding_are_bound_in_parts() {
    let (mut small, mesh, opts) = same_on_a_shrunk_device("parts", |ctx| {
        ctx.limits.max_storage_buffer_binding_size = 16 << 10;
    });
    small.limits.max_storage_buffers_per_shader_stage = 20;
    let Err(e) = lbvh_dfs_sign(&small, &mesh, &opts) else {
        panic!("more parts than storage buffers were bound");
    };
    let e = e.to_string();
    assert!(
        e.contains("emit_tris kernel would bind 23 storage buffers") && e.contains("allows 20"),
        "{e}"
    );
}

/// Dispatches beyond the device's workgroups per dimension run in two dimensions: with the
/// limit shrunk to 7 workgroups, the trees are still the CPU's.
#[test]
fn dispatches_beyond_the_workgroup_limit_run_in_two_dimensions() {
    same_on_a_shrunk_device("2D", |ctx| {
        ctx.limits.max_compute_workgroups_per_dimension = 7;
    });
}

/// Both devices decide an exact SAH tie alike: two triangles whose leaf and split cost the
/// same, to the bit, with a t_cube chosen for it (found by search), where a product fused
/// into an fma — as lavapipe fuses `a * b + c` unless told not to — breaks the tie the
/// other way. The CPU makes one leaf; so must the GPU.
#[test]
fn an_exact_sah_tie_is_decided_as_on_the_cpu() {
    let v = |w: [u32; 3]| Vec3::from_array(w.map(f32::from_bits));
    let mesh = Mesh::from_triangles(vec![
        Triangle::new(
            v([1033531924, 1028614334, 1056521644]),
            v([1064634576, 1060047150, 1061320145]),
            v([1056909321, 1064285970, 1051157816]),
        ),
        Triangle::new(
            v([1043503799, 1023017781, 1063190055]),
            v([1064514648, 1062508180, 1064235247]),
            v([1065308739, 1053749889, 1056559922]),
        ),
    ]);
    let opts = BuildOptions {
        builder: Builder::Lbvh,
        t_cube: f32::from_bits(1048377228),
        ..BuildOptions::default()
    };
    let cpu = build(&mesh, &opts);
    assert_eq!(cpu.root().nodes(), 1, "the CPU's tie is a leaf");
    let g = lbvh_dfs_sign(gpu(), &mesh, &opts).unwrap();
    assert!(
        g == DfsSign::flatten(&cpu, &mesh),
        "the GPU decided the tie otherwise"
    );
}

/// A tracer told to build on the GPU traces the same hits as one built on the CPU, in the
/// layout built there (dfs-sign) and in one flattened on the CPU (cwbvh); on the CPU device
/// it builds on the CPU.
#[test]
fn a_tracer_built_on_the_gpu_traces_as_one_built_on_the_cpu() {
    use lancer::trace::BuildOn;
    use lancer::{Device, LayoutKind, Query, Ray, Tracer, TracerOptions};
    let mesh = soup(&mut Rng::new(8), 2000, 0.1);
    let mut rng = Rng::new(9);
    let rays: Vec<Ray> = (0..500)
        .map(|_| Ray::new(rng.vec3(-1.5, 1.5), rng.dir(), 0.0, 1e30))
        .collect();
    let cpu = Device::cpu();
    for layout in [LayoutKind::DfsSign, LayoutKind::Cwbvh] {
        let options = |build_on| TracerOptions {
            build: BuildOptions {
                builder: Builder::Lbvh,
                ..BuildOptions::default()
            },
            layout: Some(layout),
            build_on,
            ..TracerOptions::default()
        };
        let reference = Tracer::new(&cpu, &mesh, &options(BuildOn::Cpu))
            .unwrap()
            .trace(&rays, Query::Closest)
            .unwrap()
            .hits;
        for device in [common::gpu_device(), &cpu] {
            let mut t = Tracer::new(device, &mesh, &options(BuildOn::Gpu)).unwrap();
            assert_eq!(
                t.trace(&rays, Query::Closest).unwrap().hits,
                reference,
                "{layout:?}"
            );
        }
    }
    let binned = TracerOptions {
        build_on: BuildOn::Gpu,
        ..TracerOptions::default()
    };
    assert!(Tracer::new(common::gpu_device(), &mesh, &binned).is_err());
}

/// A render whose BVH is built on the GPU is the render of the CPU-built BVH, bit for bit
/// (the same tree in the same layout), on lavapipe.
#[test]
fn a_render_built_on_the_gpu_is_the_render_built_on_the_cpu() {
    use lancer::render::{render, RenderOptions, RenderScene};
    use lancer::trace::BuildOn;
    use lancer::{AccelKind, LayoutKind};
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scene = RenderScene::from_file(&dir.join("cornell.toml")).unwrap();
    (scene.camera.width, scene.camera.height) = (32, 24);
    let image = |build_on| {
        let options = RenderOptions {
            spp: Some(2),
            accel: Some(AccelKind::Bvh(LayoutKind::DfsSign)),
            build: BuildOptions {
                builder: Builder::Lbvh,
                ..BuildOptions::default()
            },
            build_on,
            ..RenderOptions::default()
        };
        render(&scene, common::gpu_device(), &options)
            .unwrap()
            .image
    };
    assert!(image(BuildOn::Gpu) == image(BuildOn::Cpu));
}
