//! The benches as library code (`lancer::bench`), in process: each bench's `run` on a tiny
//! input (the Cornell box's 32 triangles, 8×8 to 16×16 rays, one timed run), its report's
//! structure and invariants (a row for every layout or structure and ray set, positive
//! speeds, ratios and derived columns consistent with the speeds, the markdown text), and
//! the results page `--report` writes. No timed assertions: speeds are only positive.

use std::cell::RefCell;
use std::path::Path;

use lancer::accel::bvh::layouts::LayoutKind;
use lancer::bench::{self, page, BenchReport, Progress};
use lancer::mesh::{load_mesh, Mesh};
use lancer::{AccelKind, DeviceChoice, RenderScene};

fn cornell() -> Mesh {
    load_mesh(Path::new("scenes/cornell-box.obj")).expect("the Cornell box loads")
}

/// Runs a bench with a progress callback that records every report, and checks them: the
/// count never goes back, and ends at its total.
fn with_progress<R>(run: impl FnOnce(&dyn Fn(Progress)) -> lancer::Result<R>) -> R {
    let seen = RefCell::new(Vec::<Progress>::new());
    let report = run(&|p| seen.borrow_mut().push(p)).expect("the bench runs");
    let seen = seen.into_inner();
    assert!(!seen.is_empty(), "no progress reported");
    assert!(seen.windows(2).all(|w| w[0].done <= w[1].done), "{seen:?}");
    let last = seen.last().unwrap();
    assert_eq!(last.done, last.total, "{seen:?}");
    report
}

/// The JSON object of a report, with its keys.
fn json(report: &impl serde::Serialize) -> serde_json::Value {
    serde_json::to_value(report).unwrap()
}

fn trace_config(device: DeviceChoice) -> bench::trace::Config {
    bench::trace::Config {
        mesh: cornell(),
        name: "scenes/cornell-box.obj".into(),
        width: 16,
        height: 16,
        device,
        repeat: 1,
        accel: AccelKind::Bvh(LayoutKind::DfsSign),
        build: Default::default(),
    }
}

#[test]
fn trace_times_the_cpu_and_says_so_in_its_table() {
    let config = trace_config(DeviceChoice::Cpu);
    let report = with_progress(|p| bench::trace::run(&config, p));
    assert_eq!((report.width, report.height, report.repeat), (16, 16, 1));
    assert_eq!(report.triangles, 32);
    assert_eq!(report.adapter, None);
    let sets: Vec<_> = report.runs.iter().map(|r| r.rays).collect();
    assert_eq!(sets, ["primary closest-hit", "shadow any-hit"]);
    assert_eq!(report.runs[0].count, 256);
    for r in &report.runs {
        assert_eq!(r.device, "cpu");
        assert!(r.mrays_per_s_wall > 0.0 && r.nodes_per_ray >= 1.0, "{r:?}");
        assert_eq!(r.mrays_per_s_gpu_time, Some(r.mrays_per_s_wall));
    }
    let text = report.text();
    assert!(text.starts_with("mesh scenes/cornell-box.obj  32 triangles in leaves  16x16"));
    assert!(
        text.contains("| rays | count | device | BVH memory |"),
        "{text}"
    );
    let row = format!(
        "| primary closest-hit | 256 | cpu ({} threads) |",
        report.cpu_threads
    );
    assert!(text.contains(&row), "{text}");
    let v = json(&report);
    assert_eq!(v["runs"].as_array().unwrap().len(), 2);
    assert!(v["adapter"].is_null() && v["runs"][0]["bvh_memory"].is_null());

    // A structure without a GPU kernel is refused by name.
    let config = bench::trace::Config {
        accel: AccelKind::Octree,
        ..trace_config(DeviceChoice::Cpu)
    };
    let e = bench::trace::run(&config, &bench::silent).unwrap_err();
    assert!(e.to_string().contains("bench structures"), "{e}");
}

#[test]
fn trace_on_the_gpu_times_every_memory_workgroup_and_module() {
    let config = trace_config(DeviceChoice::Gpu);
    let report = bench::trace::run(&config, &bench::silent).unwrap();
    assert!(report.adapter.is_some());
    // Per set: the CPU, then 2 memories × 3 workgroup sizes × 2 modules.
    assert_eq!(report.runs.len(), 2 * (1 + 12));
    for r in report.runs.iter().filter(|r| r.device == "gpu") {
        assert!(
            r.bvh_memory.is_some() && r.workgroup_size.is_some(),
            "{r:?}"
        );
        assert!(matches!(r.module, Some("checked" | "trusted")), "{r:?}");
        assert!(r.mrays_per_s_wall > 0.0, "{r:?}");
    }
}

#[test]
fn render_prices_both_kernels_and_its_numbers_agree() {
    let mut scene = RenderScene::from_file(Path::new("scenes/textured.toml")).unwrap();
    (scene.camera.width, scene.camera.height) = (8, 6);
    let config = bench::render::Config {
        scene,
        name: "scenes/textured.toml".into(),
        spp: 1,
        device: DeviceChoice::Cpu,
        build: Default::default(),
        layout: None,
    };
    let report = with_progress(|p| bench::render::run(&config, p));
    assert_eq!((report.width, report.height, report.samples), (8, 6, 1));
    assert_eq!(report.effects, "shadows textures environment");
    let kernels: Vec<_> = (report.runs.iter())
        .map(|r| (r.device, r.kernel.as_str()))
        .collect();
    assert_eq!(
        kernels,
        [
            ("cpu", "specialised"),
            ("cpu", "all effects"),
            ("cpu", "without shadows"),
            ("cpu", "without textures"),
            ("cpu", "without environment"),
        ]
    );
    for r in &report.runs {
        assert!(
            r.ms_min <= r.ms_per_spp && r.ms_per_spp <= r.ms_max,
            "{r:?}"
        );
        let mrays = 48.0 / (r.ms_per_spp * 1e-3) * 1e-6;
        assert!((r.mrays_per_s - mrays).abs() <= 1e-9 * mrays, "{r:?}");
    }
    let text = report.text();
    assert!(text.contains("| device | mode | kernel | ms per spp (median of 1) |"));
    assert!(text.contains("| cpu | – | specialised |"), "{text}");
    let (s, a) = (report.runs[0].ms_per_spp, report.runs[1].ms_per_spp);
    let saves = format!("cpu: specialisation saves {:.1}%", 100.0 * (a - s) / a);
    assert!(text.contains(&saves), "{text}");
    assert!(json(&report).get("not_run").is_none());
    let config = bench::render::Config { spp: 0, ..config };
    assert!(bench::render::run(&config, &bench::silent).is_err());
}

fn layouts_config(device: DeviceChoice) -> bench::layouts::Config {
    bench::layouts::Config {
        mesh: cornell(),
        name: "scenes/cornell-box.obj".into(),
        width: 8,
        height: 8,
        device,
        bvh_memory: Default::default(),
        layouts: LayoutKind::ALL.to_vec(),
        driver: true,
        repeat: 1,
        build: Default::default(),
    }
}

#[test]
fn layouts_measures_every_layout_on_every_ray_set() {
    let config = layouts_config(DeviceChoice::Cpu);
    let report = with_progress(|p| bench::layouts::run(&config, p));
    let sizes: Vec<_> = report.layouts.iter().map(|s| s.layout).collect();
    assert_eq!(sizes, LayoutKind::ALL);
    for s in &report.layouts {
        assert!(s.bytes > 0 && s.flatten_ms >= 0.0, "{s:?}");
        assert_eq!(s.per_tri, s.bytes as f64 / 32.0);
    }
    assert_eq!(report.adapter, "none (CPU only)");
    assert_eq!(report.driver_build_ms, None);
    // Embree 3 runs beside every timed run exactly with the `embree` feature.
    let embree = report.embree_version.is_some();
    assert_eq!(embree, cfg!(feature = "embree"));
    let embree_rows: Vec<_> = (report.runs.iter())
        .filter(|r| r.layout == "embree")
        .collect();
    assert_eq!(embree_rows.len(), if embree { 4 } else { 0 });
    assert!(embree_rows.iter().all(|r| r.cpu_mrays.unwrap() > 0.0));
    for kind in LayoutKind::ALL {
        let mine: Vec<_> = (report.runs.iter())
            .filter(|r| r.layout == kind.name())
            .collect();
        let sets: Vec<_> = mine.iter().map(|r| r.rays.as_str()).collect();
        assert_eq!(sets, ["primary", "shadow", "bounce", "random"], "{kind}");
        for r in mine {
            assert_eq!(r.mode, "per-ray");
            let (nodes, tris) = (r.nodes.unwrap(), r.tris.unwrap());
            assert!(nodes >= 1.0, "{r:?}");
            // Nodes × node size + triangles × 48: at least the triangles' share.
            assert!(r.bytes_loaded.unwrap() >= tris * 48.0, "{r:?}");
            assert!(r.cpu_mrays.unwrap() > 0.0 && r.gpu_mrays.is_none(), "{r:?}");
            assert_eq!(r.cpu_vs_embree.is_some(), embree, "{r:?}");
        }
    }
    let primary = report.runs.iter().find(|r| r.rays == "primary").unwrap();
    let random = report.runs.iter().find(|r| r.rays == "random").unwrap();
    assert_eq!((primary.count, random.count), (64, 64));
    let text = report.text();
    assert!(text.contains("| layout | flatten ms | bytes | bytes/triangle |"));
    assert!(text.contains("| layout | mode | rays | count | nodes/ray |"));
    assert!(text.contains("| bvh8 | per-ray | random | 64 |"), "{text}");
    assert_eq!(text.contains("CPU ÷ Embree"), embree);
    let v = json(&report);
    for key in [
        "nodes_per_ray",
        "bytes_loaded_per_ray",
        "cpu_mrays_per_s",
        "cpu_vs_embree",
    ] {
        assert!(v["runs"][0].get(key).is_some(), "{key}: {v}");
    }
    assert!(v.get("builder").is_none() && v.get("gpu_driver").is_none());
}

#[test]
fn layouts_on_the_gpu_give_every_row_a_gpu_speed() {
    let config = bench::layouts::Config {
        layouts: vec![LayoutKind::DfsSign, LayoutKind::Bvh4],
        driver: false,
        ..layouts_config(DeviceChoice::Gpu)
    };
    let report = bench::layouts::run(&config, &bench::silent).unwrap();
    assert_ne!(report.adapter, "none (CPU only)");
    assert!(report.driver_build_ms.is_none());
    assert!(report.runs.iter().all(|r| r.layout != "driver"));
    for r in report.runs.iter().filter(|r| r.layout != "embree") {
        assert!(r.gpu_mrays.unwrap() > 0.0, "{r:?}");
        // Subgroup rows have no CPU twin of their own.
        assert_eq!(r.cpu_mrays.is_some(), r.mode == "per-ray", "{r:?}");
    }
    assert!(report
        .text()
        .contains("| dfs-sign | per-ray | primary | 64 |"));
}

#[test]
fn structures_measures_every_structure_with_a_gpu_flag_that_matches_the_registry() {
    let config = bench::structures::Config {
        mesh: cornell(),
        camera: None,
        name: "scenes/cornell-box.obj".into(),
        width: 8,
        height: 8,
        random: Some(20),
        device: DeviceChoice::Cpu,
        bvh_memory: Default::default(),
        repeat: 1,
        build: Default::default(),
    };
    let report = with_progress(|p| bench::structures::run(&config, p));
    assert_eq!(report.triangles, 32);
    assert_eq!(report.structures.len(), AccelKind::ALL.len());
    for kind in AccelKind::ALL {
        let size = (report.structures.iter())
            .find(|s| s.structure == kind.name())
            .unwrap();
        assert!(size.bytes > 0, "{size:?}");
        let gpu = lancer::accel::build_gpu(*kind, &config.mesh, &Default::default())
            .unwrap()
            .is_some();
        assert_eq!(size.gpu, gpu, "{size:?}");
        let mine: Vec<_> = (report.runs.iter())
            .filter(|r| r.structure == kind.name())
            .collect();
        let sets: Vec<_> = mine.iter().map(|r| r.rays).collect();
        assert_eq!(sets, ["primary", "shadow", "random"]);
        for r in mine {
            assert!(
                r.cpu_mrays_per_s > 0.0 && r.gpu_mrays_per_s.is_none(),
                "{r:?}"
            );
        }
    }
    let random = report.runs.iter().find(|r| r.rays == "random").unwrap();
    assert_eq!(random.count, 20);
    let text = report.text();
    assert!(text.contains("| structure | build ms | bytes |"), "{text}");
    assert!(text.contains("| octree | primary | 64 |"), "{text}");
    assert!(text.contains("8x8 primary"), "{text}");

    // A scene brings its camera.
    let (mesh, camera) = bench::structures::load(Path::new("scenes/textured.toml")).unwrap();
    assert!(camera.is_some() && !mesh.included().is_empty());
    assert!(bench::structures::load(Path::new("scenes/cornell-box.obj"))
        .unwrap()
        .1
        .is_none());
}

/// `bench accuracy` on `scene` at a tiny size: 8×8 rays, 4×4 renders against a reference of
/// `reference_spp`, spp rows up to `max_spp`, one bounce, one timed run.
fn tiny_accuracy(
    scene: &str,
    device: DeviceChoice,
    reference_spp: u32,
    max_spp: u32,
) -> bench::accuracy::Config {
    let render_scene = RenderScene::from_file(Path::new(scene)).unwrap();
    bench::accuracy::Config {
        width: 8,
        height: 8,
        render_size: 4,
        reference_spp,
        max_spp,
        reference_bounces: 1,
        repeat: 1,
        device,
        ..bench::accuracy::Config::new(render_scene, scene)
    }
}

#[test]
fn accuracy_prices_every_knob_against_the_defaults() {
    let config = tiny_accuracy("scenes/textured.toml", DeviceChoice::Cpu, 16, 4);
    let report = with_progress(|p| bench::accuracy::run(&config, p));
    assert!(report.rows.iter().all(|r| r.device == "cpu" && r.ms > 0.0));
    let row = |setting: &str| report.rows.iter().find(|r| r.setting == setting);
    let defaults = row(bench::accuracy::DEFAULTS).unwrap();
    assert_eq!(defaults.relative, Some(1.0));
    assert!(defaults.leaks.is_some() && defaults.error_pct.is_some());
    // The shader checks are a GPU knob; f64 a CPU one.
    assert!(row("trusted").is_none() && row("f64").is_some());
    for r in report
        .rows
        .iter()
        .filter(|r| r.knob != "spp" && r.knob != "max bounces")
    {
        let ratio = r.ms / defaults.ms;
        assert!(
            (r.relative.unwrap() - ratio).abs() <= 1e-12 * ratio,
            "{r:?}"
        );
        assert!(r.sah.is_some() && r.rmse.is_none(), "{r:?}");
        assert_eq!(r.error_pct.is_some(), r.knob != "BVH builder", "{r:?}");
    }
    let spp: Vec<_> = (report.rows.iter())
        .filter(|r| r.knob == "spp")
        .map(|r| r.spp)
        .collect();
    assert_eq!(spp, [Some(1), Some(4)]);
    let bounces = report.rows.iter().filter(|r| r.knob == "max bounces");
    assert_eq!(bounces.count(), 5);
    assert!(report
        .rows
        .iter()
        .filter(|r| r.spp.is_some())
        .all(|r| r.rmse.unwrap() >= 0.0 && r.bias_pct.is_some()));
    let text = report.text();
    assert!(text.contains("| knob | setting | device | ms |"), "{text}");
    assert!(text.contains("cpu: the robust defaults take"), "{text}");
    assert!(
        text.contains("renders: 4x4 px; reference 16 spp, 1 bounces"),
        "{text}"
    );
}

/// On a GPU every trace row counts the answers that are not the CPU twin's: none with the
/// defaults (the promise), and where the adapter takes lancer's exact SPIR-V, a row prices
/// wgpu's own translation against it.
#[test]
fn accuracy_counts_gpu_answers_that_are_not_the_twins() {
    let config = tiny_accuracy("scenes/cornell.toml", DeviceChoice::Gpu, 4, 1);
    let report = with_progress(|p| bench::accuracy::run(&config, p));
    let exact = lancer::gpu::GpuContext::new().unwrap().exact_spirv;
    let trace_rows = || (report.rows.iter()).filter(|r| r.knob != "spp" && r.knob != "max bounces");
    for r in trace_rows() {
        assert_eq!(r.twin_mismatches.is_some(), r.device == "gpu", "{r:?}");
    }
    let gpu = |setting: &str| (trace_rows()).find(|r| r.device == "gpu" && r.setting == setting);
    // Where wgpu translates the WGSL (not Vulkan, or LANCER_WGSL=1), a driver may fuse and
    // move an answer: only the exact SPIR-V promises none.
    let defaults = gpu(bench::accuracy::DEFAULTS).unwrap().twin_mismatches;
    if exact {
        assert_eq!(defaults, Some(0));
    }
    let translated = gpu(bench::accuracy::WGPU_ARITHMETIC);
    assert_eq!(translated.is_some(), exact, "{translated:?}");
    let text = report.text();
    assert!(text.contains("≠ CPU twin"), "{text}");
    assert_eq!(
        text.contains("gpu: lancer's exact SPIR-V takes"),
        exact,
        "{text}"
    );
}

#[test]
fn report_writes_a_dated_page_with_its_chart_beside_it() {
    let report = bench::trace::run(&trace_config(DeviceChoice::Cpu), &bench::silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trace-run.md");
    std::fs::write(&path, "an older page").unwrap();
    let outputs = page::outputs::<bench::trace::Report>(&path);
    assert_eq!(outputs, [path.clone(), dir.path().join("trace-run.png")]);
    page::write(&path, &report, "lancer bench trace scenes/cornell-box.obj").unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let today = page::utc(std::time::SystemTime::now());
    let day = today.split(' ').next().unwrap();
    assert!(
        text.starts_with(&format!("# bench trace: cornell-box.obj, {day}\n")),
        "{text}"
    );
    for part in [
        "- **date**: ",
        " UTC\n",
        "- **machine**: ",
        " cores (",
        "- **CPU threads**: ",
        "- **adapter and driver**: none (CPU only)\n",
        "- **lancer**: ",
        ", commit ",
        "```sh\n  lancer bench trace scenes/cornell-box.obj\n  ```",
        "## Results\n\nmesh scenes/cornell-box.obj",
        "\n\n| rays | count | device |",
        "## Chart\n\n![trace-run.png](trace-run.png)\n",
    ] {
        assert!(text.contains(part), "{part:?} not in:\n{text}");
    }
    let png = image::open(dir.path().join("trace-run.png")).unwrap();
    assert!(png.width() > 100 && png.height() > 100);
    // Replaced whole, atomically: the page and its chart, no temporary file left.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);

    // Accuracy's page draws a chart a device, and links only those drawn.
    let outputs = page::outputs::<bench::accuracy::Report>(&path);
    let names: Vec<_> = outputs[1..]
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "trace-run-cpu.png",
            "trace-run-gpu.png",
            "trace-run-spp.png"
        ]
    );
}

fn builders_config(device: DeviceChoice) -> bench::builders::Config {
    let teapot = load_mesh(Path::new("../shared/models/teapot.obj")).expect("../shared/models");
    bench::builders::Config {
        meshes: vec![
            ("scenes/cornell-box.obj".into(), cornell()),
            ("teapot".into(), teapot),
        ],
        builders: lancer::accel::bvh::Builder::ALL.to_vec(),
        optimize: false,
        build: Default::default(),
        width: 8,
        height: 8,
        device,
        bvh_memory: Default::default(),
        repeat: 1,
    }
}

#[test]
fn builders_measures_every_builder_on_every_mesh_and_ranks_the_costs() {
    let config = builders_config(DeviceChoice::Cpu);
    let report = with_progress(|p| bench::builders::run(&config, p));
    let embree = cfg!(feature = "embree");
    assert_eq!(report.embree_version.is_some(), embree);
    let builders = lancer::accel::bvh::Builder::ALL.len();
    assert_eq!(report.builds.len(), 2 * (builders + embree as usize));
    for b in &report.builds {
        let [lo, hi] = b.build_ms_range;
        assert!(
            lo <= b.build_ms && b.build_ms <= hi,
            "{b:?}: median outside the range"
        );
    }
    for b in report
        .builds
        .iter()
        .filter(|b| b.builder != "embree-medium")
    {
        let (sah, epo) = (b.sah.unwrap(), b.epo.unwrap());
        assert!(b.build_ms > 0.0 && sah > 0.0 && epo >= 0.0, "{b:?}");
        // The library's tests run without the counting allocator: no peak is made up.
        assert_eq!(b.peak_mib, None, "{b:?}");
        assert!(
            b.nodes.unwrap() >= 1 && b.flatten_ms.unwrap() >= 0.0,
            "{b:?}"
        );
    }
    assert_eq!(report.runs.len(), 2 * builders * 4);
    for r in &report.runs {
        assert!(
            r.cpu_mrays > 0.0 && r.nodes_per_ray >= 1.0 && r.gpu_mrays.is_none(),
            "{r:?}"
        );
    }
    // SAH, EPO and measured work × four ray sets, on the CPU: one ρ per mesh each.
    assert_eq!(report.correlations.len(), 3 * 4);
    for c in &report.correlations {
        assert_eq!(c.device, "CPU");
        assert_eq!(c.rho.len(), 2);
        assert!(
            c.rho.iter().flatten().all(|r| (-1.0..=1.0).contains(r)),
            "{c:?}"
        );
        assert!(c.picks_fastest <= 2);
    }
    let text = report.text();
    assert!(
        text.contains(
            "| mesh | builder | build ms (range) | flatten ms | (build + flatten) ÷ Embree |"
        ),
        "{text}"
    );
    assert!(
        text.contains("| cornell-box.obj | median | random |"),
        "{text}"
    );
    assert!(text.contains("| SAH | primary | CPU |"), "{text}");
    let v = json(&report);
    for key in ["build_ms", "build_ms_range", "peak_mib", "sah", "epo"] {
        assert!(v["builds"][0].get(key).is_some(), "{key}: {v}");
    }
    assert!(v["correlations"][0].get("mean_rho").is_some(), "{v}");
}

#[test]
fn builders_on_the_gpu_give_every_run_a_gpu_speed() {
    use lancer::accel::bvh::Builder;
    let config = bench::builders::Config {
        builders: vec![Builder::Median, Builder::Lbvh],
        optimize: true,
        ..builders_config(DeviceChoice::Gpu)
    };
    let report = bench::builders::run(&config, &bench::silent).unwrap();
    assert!(report.gpu_layout.is_some());
    assert!(report.runs.iter().all(|r| r.gpu_mrays.unwrap() > 0.0));
    assert!(report.correlations.iter().any(|c| c.device == "GPU"));
    let names: Vec<_> = report.builds.iter().map(|b| b.builder.as_str()).collect();
    let expected = [
        "median",
        "median+reinsert",
        "lbvh",
        "lbvh+reinsert",
        "lbvh@gpu",
    ];
    assert_eq!(names[..5], expected);
    // The LBVH built on the GPU is timed beside the CPU's, with the CPU's (equal) tree's
    // costs; its traversal is the CPU row's, so it has no runs of its own.
    let (cpu, gpu) = (&report.builds[2], &report.builds[4]);
    assert!(gpu.build_ms > 0.0 && gpu.sah == cpu.sah && gpu.nodes == cpu.nodes);
    assert!(report.runs.iter().all(|r| r.builder != "lbvh@gpu"));
    // Reinsertion never raises the SAH.
    let sah: Vec<f64> = report.builds[..2].iter().map(|b| b.sah.unwrap()).collect();
    assert!(sah[1] <= sah[0], "{sah:?}");
}

#[test]
fn instances_measure_both_variants_on_both_devices_and_the_top_level_at_every_count() {
    let config = bench::instances::Config {
        mesh: cornell(),
        name: "cornell".into(),
        copies: 4,
        width: 24,
        height: 16,
        device: DeviceChoice::Gpu,
        bvh_memory: Default::default(),
        layout: Some(LayoutKind::DfsSign),
        repeat: 1,
        build: Default::default(),
    };
    let report = with_progress(|p| bench::instances::run(&config, p));
    let j = json(&report);
    let tris = config.mesh.len() as u64;
    assert_eq!(j["variants"][0]["triangles"], tris);
    assert_eq!(j["variants"][1]["triangles"], 4 * tris);
    assert!(report.variants[0].bytes < report.variants[1].bytes);
    assert_eq!(report.runs.len(), 4);
    for r in &report.runs {
        assert!(
            r.cpu_mrays_per_s > 0.0 && r.gpu_mrays_per_s.is_some_and(|g| g > 0.0),
            "{r:?}"
        );
        assert!(r.nodes_per_ray >= 1.0, "{r:?}");
    }
    // The primary rays are the same set for both variants (runs: each ray set, instanced
    // then flattened).
    assert_eq!(
        (report.runs[0].rays, report.runs[1].rays),
        ("primary", "primary")
    );
    assert_eq!(report.runs[0].count, 24 * 16);
    assert_eq!(report.runs[0].count, report.runs[1].count);
    assert_eq!(report.runs[2].count, report.runs[3].count);
    for rays in ["primary", "shadow"] {
        for gpu in [false, true] {
            assert!(report.cost_ratio(rays, gpu).is_some_and(f64::is_finite));
        }
    }
    let counts: Vec<usize> = report.top_level.iter().map(|t| t.instances).collect();
    assert_eq!(counts, bench::instances::TOP_LEVEL_COUNTS);
    let text = report.text();
    assert!(
        text.contains("instanced ÷ flattened") && text.contains("100000"),
        "{text}"
    );
}

#[test]
fn refit_measures_every_step_against_a_rebuild_on_both_devices() {
    let config = bench::refit::Config {
        mesh: cornell(),
        name: "cornell".into(),
        steps: 2,
        max_twist: 60.0,
        width: 24,
        height: 16,
        device: DeviceChoice::Gpu,
        bvh_memory: Default::default(),
        layout: Some(LayoutKind::DfsSign),
        repeat: 1,
        build: Default::default(),
    };
    let report = with_progress(|p| bench::refit::run(&config, p));
    let twists: Vec<f64> = report.steps.iter().map(|s| s.twist_deg).collect();
    assert_eq!(twists, [0.0, 30.0, 60.0]);
    // Undeformed, the refit tree is the built tree: the same cost, the same work.
    let first = &report.steps[0];
    assert_eq!(first.refit_sah, first.rebuild_sah);
    assert_eq!(first.refit_nodes_per_ray, first.rebuild_nodes_per_ray);
    for s in &report.steps {
        assert!(s.refit_ms > 0.0 && s.rebuild_ms > 0.0, "{s:?}");
        assert!(s.cpu_mrays_per_s.iter().all(|&m| m > 0.0), "{s:?}");
        assert!(s
            .gpu_mrays_per_s
            .is_some_and(|g| g.iter().all(|&m| m > 0.0)));
    }
    // Twisted, the meshes differ from the undeformed one: the trees' bounds moved.
    let twisted = bench::refit::twisted(&config.mesh, 60.0);
    assert_ne!(twisted.bounds(), config.mesh.bounds());
    let text = report.text();
    assert!(text.contains("SAH refit ÷ rebuilt"), "{text}");
    assert_eq!(json(&report)["steps"].as_array().unwrap().len(), 3);
}

#[test]
fn scale_times_each_step_from_the_file_on_both_devices() {
    let path = Path::new("scenes/cornell-box.obj");
    let sources = cornell().sources;
    let bytes: u64 = sources
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert!(
        bytes > std::fs::metadata(path).unwrap().len(),
        "its materials count too"
    );
    for device in [DeviceChoice::Cpu, DeviceChoice::Gpu] {
        let config = bench::scale::Config {
            meshes: vec![path.into(), path.into()],
            width: 12,
            height: 8,
            device,
            bvh_memory: Default::default(),
            layout: None,
            repeat: 2,
            build: Default::default(),
        };
        let report = with_progress(|p| bench::scale::run(&config, p));
        let gpu = device == DeviceChoice::Gpu;
        assert_eq!((report.gpu_driver.is_some(), report.repeat), (gpu, 2));
        if !gpu {
            assert_eq!(report.layout, lancer::trace::defaults::CPU_LAYOUT.name());
        }
        assert_eq!(report.rows.len(), 2);
        for r in &report.rows {
            assert_eq!(
                (r.triangles, r.rays, r.file_bytes),
                (32, 96, bytes),
                "{r:?}"
            );
            let steps = [r.read_ms, r.build_ms, r.flatten_ms, r.first_trace_ms];
            assert!(steps.iter().all(|&ms| ms > 0.0), "{r:?}");
            // The device step is timed on a GPU only; the ratio counts what was timed.
            assert_eq!(r.to_device_ms.is_some_and(|ms| ms > 0.0), gpu, "{r:?}");
            // So is the check alone, part of it.
            assert_eq!(r.checked_ms.is_some_and(|ms| ms > 0.0), gpu, "{r:?}");
            let ratio = (r.flatten_ms + r.to_device_ms.unwrap_or(0.0)) / r.build_ms;
            assert!((r.flatten_and_device_per_build - ratio).abs() <= 1e-9 * ratio);
            let rate = bytes as f64 / 1e3 / r.read_ms;
            assert!((r.read_mb_per_s - rate).abs() <= 1e-9 * rate, "{r:?}");
            if cfg!(target_os = "linux") {
                let (peak, start) = (r.peak_bytes.unwrap(), r.start_bytes.unwrap());
                assert!(peak >= start && start > 0, "{r:?}");
                let added = (peak - start) as f64 / 32.0;
                assert_eq!(r.added_bytes_per_triangle, Some(added), "{r:?}");
            }
        }
        let text = report.text();
        assert!(text.contains("| cornell-box.obj | 32 |"), "{text}");
        if cfg!(target_os = "linux") {
            // The peak columns filled: a dash is the device step the CPU does not take.
            assert_eq!(text.contains("| – |"), !gpu, "{text}");
        }
        assert_eq!(json(&report)["rows"].as_array().unwrap().len(), 2);
    }
}
