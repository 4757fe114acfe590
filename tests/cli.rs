//! The `lancer` binary end to end: build/rays/trace, file formats, exit codes.

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn lancer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs lancer and fails the test with its stderr unless it succeeds.
fn lancer_ok(args: &[&str]) -> Output {
    let out = lancer(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs lancer and fails the test unless it exits 2 (the input or the command line
/// refused); returns its stderr, where the reason stands.
fn lancer_refused(args: &[&str]) -> String {
    let out = lancer(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    err
}

/// A folder of its own per test: tests run in parallel, and two of them rewriting one
/// shared file let a third read it half-written.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new() -> Self {
        Scratch(
            tempfile::Builder::new()
                .prefix("lancer-cli-")
                .tempdir()
                .unwrap(),
        )
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.path().join(name)
    }

    fn quad(&self) -> PathBuf {
        let p = self.path("quad.obj");
        std::fs::write(&p, "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n").unwrap();
        p
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `lancer rays`: the default view of `model`, `width`×`height` rays, written to `out` (the
/// ray file most tests trace); fails the test unless it succeeds.
fn view_rays(model: &Path, width: u32, height: u32, out: &Path) {
    let (w, h) = (width.to_string(), height.to_string());
    lancer_ok(&[
        "rays",
        s(model),
        "--width",
        &w,
        "--height",
        &h,
        "-o",
        s(out),
    ]);
}

/// `--build-on gpu` builds the LBVH on the adapter (lavapipe in CI): the same tree as the
/// CPU's, saying where; any other builder is refused as a usage error.
#[test]
fn build_on_gpu_makes_the_cpus_lbvh_and_refuses_other_builders() {
    let dir = Scratch::new();
    let mesh = dir.path("soup.obj");
    let mut obj = String::new();
    for i in 0..200 {
        let (x, y) = ((i % 20) as f32 * 0.7, (i / 20) as f32 * 0.9);
        obj += &format!(
            "v {x} {y} {}\nv {} {y} 0.5\nv {x} {} 0\n",
            i % 3,
            x + 1.0,
            y + 1.0
        );
        obj += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    std::fs::write(&mesh, obj).unwrap();
    let json = |on: &str| {
        let out = lancer_ok(&[
            "build",
            s(&mesh),
            "--builder",
            "lbvh",
            "--build-on",
            on,
            "--json",
        ]);
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (cpu, gpu) = (json("cpu"), json("gpu"));
    assert!(cpu.get("built_on").is_none());
    assert!(gpu["built_on"].as_str().is_some_and(|a| !a.is_empty()));
    for k in [
        "triangles",
        "nodes",
        "leaves",
        "max_depth",
        "sah_cost",
        "bytes",
    ] {
        assert_eq!(cpu[k], gpu[k], "{k}");
    }
    let err = lancer_refused(&[
        "build",
        s(&mesh),
        "--builder",
        "binned",
        "--build-on",
        "gpu",
    ]);
    assert!(err.contains("--builder lbvh"), "{err}");
}

#[test]
fn build_json_has_the_documented_keys() {
    let dir = Scratch::new();
    let q = dir.quad();
    let out = lancer(&["build", s(&q), "--json"]);
    assert!(out.status.success());
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for k in [
        "triangles",
        "nodes",
        "leaves",
        "max_depth",
        "sah_cost",
        "build_ms",
        "bytes",
    ] {
        assert!(j.get(k).is_some(), "missing {k}");
    }
    assert_eq!(j["triangles"], 2);
    if cfg!(target_os = "linux") {
        // The whole process: at least the binary's own pages, well under a gigabyte here.
        let peak = j["peak_memory_bytes"]
            .as_u64()
            .expect("peak memory on Linux");
        assert!((1 << 20..1 << 30).contains(&peak), "{peak}");
    }
}

#[test]
fn rays_then_trace_writes_hits_of_the_default_view() {
    let dir = Scratch::new();
    let q = dir.quad();
    let (r, h) = (dir.path("q.rays"), dir.path("q.hits"));
    assert!(
        lancer(&["rays", s(&q), "--width", "8", "--height", "6", "-o", s(&r)])
            .status
            .success()
    );
    assert_eq!(std::fs::metadata(&r).unwrap().len(), 8 * 6 * 32);
    lancer_ok(&[
        "trace",
        s(&q),
        "--rays",
        s(&r),
        "--out",
        s(&h),
        "--device",
        "cpu",
    ]);
    let hits = lancer::trace::files::read_hits(&h).unwrap();
    assert_eq!(hits.len(), 48);
    // The centre pixels look at the quad (prims 0 and 1), row 0 is the top.
    let centre = hits[3 * 8 + 4];
    assert!(centre.prim <= 1 && centre.t > 0.0);
}

#[test]
fn rays_and_render_take_the_view_from_the_command_line() {
    let dir = Scratch::new();
    let q = dir.quad();
    let rays = |extra: &[&str]| {
        let r = dir.path("v.rays");
        let size = ["rays", s(&q), "--width", "4", "--height", "2", "-o", s(&r)];
        lancer_ok(&[&size[..], extra].concat());
        lancer::trace::files::read_rays(&r).unwrap()
    };
    let default = rays(&[]);
    // The eye where it is asked to be, looking at the point asked for.
    let from = rays(&["--look-from", "-1,2,3", "--look-at", "0,0,-1"]);
    assert!(from
        .iter()
        .all(|r| r.origin == glam::Vec3::new(-1.0, 2.0, 3.0)));
    let mean = from.iter().map(|r| r.dir).sum::<glam::Vec3>().normalize();
    let toward = (glam::Vec3::new(1.0, -2.0, -4.0)).normalize();
    assert!(mean.dot(toward) > 0.99, "{mean} vs {toward}");
    // A narrower field of view keeps a mesh framed: the eye moves back, the rays narrow.
    let narrow = rays(&["--fov", "10"]);
    let spread = |rs: &[lancer::geometry::Ray]| rs[0].dir.dot(rs[rs.len() - 1].dir);
    assert!(spread(&narrow) > spread(&default));
    assert!(narrow[0].origin.length() > 3.0 * default[0].origin.length());
    for bad in [
        &["--fov", "180"][..],
        &["--look-from", "1,2"],
        &["--look-from", "0,1,0", "--look-at", "0,1,0"],
    ] {
        let out = dir.path("bad.png");
        let o = lancer(
            &[
                &["render", s(&q), "-o", s(&out), "--device", "cpu"][..],
                bad,
            ]
            .concat(),
        );
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {o:?}");
        assert!(!out.exists());
    }
}

/// A glTF quad with three cameras: a perspective one at (0, 0, 5) looking down −Z, "Side"
/// at (5, 0, 0) turned to look down −X, and an orthographic one (not used).
fn gltf_with_cameras(d: &Scratch) -> PathBuf {
    let m = common::writers::Indexed {
        verts: vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ],
        faces: vec![vec![0, 1, 2], vec![0, 2, 3]],
    };
    let bin = common::writers::gltf_buffer(&m);
    let mut doc = common::writers::gltf_json(&m, Some(common::writers::data_uri(&bin)));
    let h = std::f32::consts::FRAC_1_SQRT_2;
    doc["cameras"] = serde_json::json!([
        { "type": "perspective", "perspective": { "yfov": 0.6, "aspectRatio": 2.0, "znear": 0.1 } },
        { "type": "perspective", "name": "Side", "perspective": { "yfov": 0.5, "znear": 0.1 } },
        { "type": "orthographic", "orthographic": { "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10 } }
    ]);
    doc["nodes"] = serde_json::json!([
        { "mesh": 0 },
        { "camera": 2, "translation": [0, 0, 9] },
        { "camera": 0, "translation": [0, 0, 5] },
        { "camera": 1, "translation": [5, 0, 0], "rotation": [0, h, 0, h] }
    ]);
    doc["scenes"] = serde_json::json!([{ "nodes": [0, 1, 2, 3] }]);
    let p = d.path("cameras.gltf");
    std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
    p
}

#[test]
fn gltf_cameras_give_the_view_and_camera_picks_one() {
    let dir = Scratch::new();
    let g = gltf_with_cameras(&dir);
    let rays = |extra: &[&str]| {
        let r = dir.path("c.rays");
        let size = ["rays", s(&g), "--width", "4", "--height", "4", "-o", s(&r)];
        lancer_ok(&[&size[..], extra].concat());
        lancer::trace::files::read_rays(&r).unwrap()
    };
    let mean =
        |rs: &[lancer::geometry::Ray]| rs.iter().map(|r| r.dir).sum::<glam::Vec3>().normalize();
    // The first perspective camera (the orthographic one is left out).
    let loaded = lancer::mesh::load_gltf(&g).unwrap();
    assert_eq!(loaded.cameras.len(), 2, "{:?}", loaded.cameras);
    let first = rays(&[]);
    let at = |r: &lancer::geometry::Ray, p: glam::Vec3| (r.origin - p).length() < 1e-5;
    assert!(
        first.iter().all(|r| at(r, glam::Vec3::new(0.0, 0.0, 5.0))),
        "{:?}",
        first[0]
    );
    assert!(mean(&first).dot(-glam::Vec3::Z) > 0.999);
    for pick in ["Side", "1"] {
        let side = rays(&["--camera", pick]);
        assert!(
            (side[0].origin - glam::Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5,
            "{pick}"
        );
        assert!(mean(&side).dot(-glam::Vec3::X) > 0.999, "{pick}");
    }
    // The file's camera renders as the CPU sees it from there: the quad fills the middle.
    let scene = lancer::RenderScene::from_mesh(&g, 8, 8).unwrap();
    assert_eq!(scene.camera.eye, glam::Vec3::new(0.0, 0.0, 5.0));
    assert!((scene.camera.vfov_deg - 0.6f32.to_degrees()).abs() < 1e-4);
    // The first camera's aspect ratio (2) shapes the image where the size is not given
    // whole; "Side" has none: the mesh's own 640 × 480.
    let size = |width: Option<u32>, height: Option<u32>, camera: Option<&str>| {
        let size = lancer::render::ImageSize {
            width,
            height,
            scale: None,
        };
        let view = lancer::camera::ViewChange {
            camera: camera.map(str::to_string),
            ..Default::default()
        };
        let scene = lancer::RenderScene::open(&g, &size, &view).unwrap();
        (scene.camera.width, scene.camera.height)
    };
    assert_eq!(size(None, None, None), (640, 320));
    assert_eq!(size(Some(100), None, None), (100, 50));
    assert_eq!(size(Some(30), Some(30), None), (30, 30));
    assert_eq!(size(None, None, Some("Side")), (640, 480));
    // `rays` shapes its 512-wide default alike.
    let r = dir.path("shaped.rays");
    lancer_ok(&["rays", s(&g), "-o", s(&r)]);
    assert_eq!(
        lancer::trace::files::read_rays(&r).unwrap().len(),
        512 * 256
    );
    // An unknown camera names the ones there are; a scene file has its own.
    let out = dir.path("x.png");
    let err = lancer_refused(&[
        "render",
        s(&g),
        "-o",
        s(&out),
        "--camera",
        "Top",
        "--device",
        "cpu",
    ]);
    assert!(
        err.contains(r#"the file's cameras are 0 "", 1 "Side""#),
        "{err}"
    );
    let toml = dir.path("s.toml");
    std::fs::write(&toml, "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\n[[objects]]\nshape = \"box\"\n").unwrap();
    let o = lancer(&[
        "render",
        s(&toml),
        "-o",
        s(&out),
        "--camera",
        "0",
        "--device",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists());
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    let dir = Scratch::new();
    let q = dir.quad();
    let r = dir.path("short.rays");
    std::fs::write(&r, [0u8; 33]).unwrap();
    let err = lancer_refused(&[
        "trace",
        s(&q),
        "--rays",
        s(&r),
        "--out",
        s(&dir.path("x.hits")),
    ]);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("not a multiple of 32"), "{err}");

    let bad = dir.path("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 1\n").unwrap();
    assert!(lancer_refused(&["build", s(&bad)]).contains("bad.obj:2:"));

    let empty = dir.path("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    assert!(lancer_refused(&["build", s(&empty)]).contains("no usable triangle"));
}

#[test]
fn render_writes_the_same_png_on_cpu_and_gpu() {
    let dir = Scratch::new();
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.obj");
    let (c, g) = (dir.path("cornell-cpu.png"), dir.path("cornell-gpu.png"));
    let args = |out: &Path, dev: &'static str| {
        vec![
            "render".to_string(),
            s(&scene).into(),
            "-o".into(),
            s(out).into(),
            "--width".into(),
            "64".into(),
            "--height".into(),
            "48".into(),
            "--spp".into(),
            "2".into(),
            "--device".into(),
            dev.into(),
        ]
    };
    let run = |a: Vec<String>| {
        Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(a)
            .output()
            .unwrap()
    };
    let out = run(args(&c, "cpu"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cpu = image::open(&c).unwrap().to_rgb8();
    assert_eq!(cpu.dimensions(), (64, 48));
    // The box is lit: some pixels are much brighter than the background.
    assert!(cpu.pixels().filter(|p| p[0] > 150).count() > 200);
    let out = run(args(&g, "gpu"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let gpu = image::open(&g).unwrap().to_rgb8();
    // Same integrator and random numbers on both: at most a few pixels whose path
    // branched differently on an ulp (the tolerance of tests/render.rs).
    let differ = cpu
        .pixels()
        .zip(gpu.pixels())
        .filter(|(a, b)| (0..3).any(|k| a[k].abs_diff(b[k]) > 2))
        .count();
    assert!(
        differ * 50 <= 64 * 48,
        "{differ} pixels differ between CPU and GPU renders"
    );
}

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

#[test]
fn render_writes_exr_and_refuses_unknown_formats_before_rendering() {
    let dir = Scratch::new();
    let ao = scene("ao.toml");
    let exr = dir.path("ao.exr");
    let small = [
        "--width", "16", "--height", "12", "--spp", "1", "--device", "cpu",
    ];
    lancer_ok(&[&["render", s(&ao), "-o", s(&exr)][..], &small].concat());
    let img = image::open(&exr).unwrap().to_rgb32f();
    assert_eq!(img.dimensions(), (16, 12));
    // Linear AO values: the white background is 1, occluded floor is below it.
    assert!(img.pixels().any(|p| p[0] > 0.99) && img.pixels().any(|p| p[0] < 0.9));

    let jpg = dir.path("ao.jpg");
    let err = lancer_refused(&[&["render", s(&ao), "-o", s(&jpg)][..], &small].concat());
    assert!(err.contains("unknown image type"), "{err}");
    assert!(!err.contains("spp ->"), "rendered before refusing: {err}");
    assert!(!jpg.exists());
}

/// `bench render` of the textured scene at 16×12, 3 timed samples, on `device`: its stdout.
fn bench_render_small(device: &str) -> String {
    let textured = scene("textured.toml");
    let args = [
        "bench",
        "render",
        s(&textured),
        "--width",
        "16",
        "--height",
        "12",
    ];
    let out = lancer_ok(&[&args[..], &["--spp", "3", "--device", device]].concat());
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn bench_render_prints_both_kernels() {
    let text = bench_render_small("cpu");
    assert!(text.contains("| cpu | – | specialised |"), "{text}");
    assert!(text.contains("| cpu | – | all effects |"), "{text}");
    assert!(text.contains("effects: shadows textures"), "{text}");
    assert!(text.contains("median of 3"), "{text}");
    // A median needs samples to choose from: fewer than 3 is a usage error.
    lancer_refused(&["bench", "render", s(&scene("textured.toml")), "--spp", "2"]);
}

#[test]
fn bench_render_prices_both_gpu_modes() {
    // lavapipe has subgroups: the GPU rows come in both traversal modes, with their ratio.
    let text = bench_render_small("gpu");
    for row in [
        "| gpu | per-ray | specialised |",
        "| gpu | per-ray | all effects |",
        "| gpu | subgroup | specialised |",
        "| gpu | subgroup | all effects |",
        "| cpu | – | specialised |",
        "gpu: subgroup traversal takes",
    ] {
        assert!(text.contains(row), "{row}: {text}");
    }
    assert!(!text.contains("not run"), "{text}");
}

/// The traversal modes a layout runs in on this adapter: per-ray, and subgroup where both
/// the layout and the adapter have it.
fn subgroup_modes(layout: lancer::LayoutKind) -> Vec<lancer::TraversalMode> {
    let mesh = lancer::Mesh::from_triangles(vec![lancer::geometry::Triangle::new(
        lancer::Vec3::ZERO,
        lancer::Vec3::X,
        lancer::Vec3::Y,
    )]);
    let tree = lancer::accel::bvh::build(&mesh, &Default::default());
    let has = lancer::accel::bvh::layouts::flatten(layout, &tree, &mesh)
        .subgroup_wgsl()
        .is_some();
    let mut modes = vec![lancer::TraversalMode::PerRay];
    let adapter_has = lancer::gpu::GpuContext::new().is_ok_and(|c| c.subgroups.is_some());
    if has && adapter_has {
        modes.push(lancer::TraversalMode::Subgroup);
    }
    modes
}

#[test]
fn check_compares_every_layout_on_the_gpu_with_its_twin() {
    let Some(teapot) = common::model("teapot.obj") else {
        return;
    };
    let out = lancer_ok(&[
        "check",
        s(&teapot),
        "--width",
        "48",
        "--height",
        "32",
        "--device",
        "gpu",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    for layout in lancer::LayoutKind::ALL {
        for mode in subgroup_modes(*layout) {
            for set in ["primary", "shadow", "bounce"] {
                let row = format!("| {layout} | {mode} | {set} |");
                assert!(text.contains(&row), "no row {row} in:\n{text}");
            }
        }
    }
    assert!(text.contains("every answer agrees"), "{text}");
    // No GPU, no check, and never a silent pass on the CPU alone: --device cpu is a usage
    // error (exit 2; exit 1 is a disagreement or a device that fails to open).
    assert!(lancer_refused(&["check", s(&teapot), "--device", "cpu"])
        .contains("--device cpu leaves no GPU"));
}

#[test]
fn bench_layouts_measures_every_layout_and_writes_json() {
    let Some(teapot) = common::model("teapot.obj") else {
        return;
    };
    let dir = Scratch::new();
    let json = dir.path("layouts.json");
    let out = lancer_ok(&[
        "bench",
        "layouts",
        s(&teapot),
        "--width",
        "24",
        "--height",
        "16",
        "--repeat",
        "1",
        "--device",
        "gpu",
        "--json",
        s(&json),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let runs = v["runs"].as_array().unwrap();
    for layout in lancer::LayoutKind::ALL {
        for mode in subgroup_modes(*layout) {
            assert!(
                text.contains(&format!("| {layout} | {mode} | primary |")),
                "{text}"
            );
            let mine: Vec<_> = runs
                .iter()
                .filter(|r| r["layout"] == layout.name() && r["mode"] == mode.name())
                .collect();
            assert_eq!(
                mine.len(),
                4,
                "primary, shadow, bounce, random for {layout} {mode}"
            );
            for r in mine {
                // Work was counted: every ray visits the root at least.
                assert!(r["nodes_per_ray"].as_f64().unwrap() >= 1.0, "{r}");
                // The CPU twin traces per ray only; subgroup rows are the GPU's.
                let cpu = r["cpu_mrays_per_s"].as_f64();
                match mode {
                    lancer::TraversalMode::PerRay => assert!(cpu.unwrap() > 0.0, "{r}"),
                    lancer::TraversalMode::Subgroup => {
                        assert!(cpu.is_none(), "{r}");
                        assert!(r["gpu_mrays_per_s"].as_f64().unwrap() > 0.0, "{r}");
                    }
                }
            }
        }
    }
    // Embree's rows: with the `embree` feature one per ray set, CPU speed only; else none.
    let embree: Vec<_> = runs.iter().filter(|r| r["layout"] == "embree").collect();
    if cfg!(feature = "embree") {
        assert_eq!(embree.len(), 4, "{v}");
        for r in embree {
            assert_eq!(r["mode"], "single-ray", "{r}");
            assert!(r["cpu_mrays_per_s"].as_f64().unwrap() > 0.0, "{r}");
            assert!(r["gpu_mrays_per_s"].is_null(), "{r}");
        }
        assert!(v["embree_build_ms"].as_f64().unwrap() >= 0.0, "{v}");
        assert!(text.contains("embree rows: Embree 3."), "{text}");
    } else {
        assert!(embree.is_empty(), "{v}");
        assert!(v["embree_build_ms"].is_null(), "{v}");
    }
    // Paired ratios to Embree: with the feature, on every other row that has the speed they
    // divide (and in two columns of the table); without it, none.
    let paired = cfg!(feature = "embree");
    assert_eq!(
        text.contains("| CPU ÷ Embree | GPU ÷ Embree |"),
        paired,
        "{text}"
    );
    for r in runs.iter().filter(|r| r["layout"] != "embree") {
        for (speed, ratio) in [
            ("cpu_mrays_per_s", "cpu_vs_embree"),
            ("gpu_mrays_per_s", "gpu_vs_embree"),
        ] {
            let expected = paired && r[speed].is_f64();
            assert_eq!(r[ratio].as_f64().is_some_and(|x| x > 0.0), expected, "{r}");
            assert_eq!(r[ratio].is_null(), !expected, "{r}");
        }
    }
}

#[test]
fn compare_tells_equal_from_different_images_and_hit_files() {
    let d = Scratch::new();
    let quad = d.quad();
    let (a, b, diff) = (d.path("a.png"), d.path("b.png"), d.path("diff.png"));
    lancer_ok(&[
        "heatmap",
        s(&quad),
        "-o",
        s(&a),
        "--width",
        "32",
        "--height",
        "24",
        "--device",
        "cpu",
    ]);
    let mut img = image::open(&a).unwrap().to_rgb8();
    for x in 0..8 {
        img.put_pixel(x, 3, image::Rgb([255, 0, 0]));
    }
    img.save(&b).unwrap();
    let same = lancer_ok(&["compare", s(&a), s(&a)]);
    assert!(String::from_utf8_lossy(&same.stdout).contains("pixels: bit-identical"));
    let differ = lancer(&["compare", s(&a), s(&b), "-o", s(&diff)]);
    assert_eq!(differ.status.code(), Some(1));
    let text = String::from_utf8_lossy(&differ.stdout).into_owned();
    assert!(
        text.contains("8 differ") && text.contains("8 pixels"),
        "{text}"
    );
    assert!(image::open(&diff).is_ok(), "no difference picture");
    lancer_ok(&["compare", s(&a), s(&b), "--tolerance", "5"]);
    let rays = d.path("r.bin");
    let (ha, hb) = (d.path("a.hits"), d.path("b.hits"));
    view_rays(&quad, 16, 16, &rays);
    lancer_ok(&[
        "trace",
        s(&quad),
        "--rays",
        s(&rays),
        "--out",
        s(&ha),
        "--device",
        "cpu",
    ]);
    let mixed = lancer(&["compare", s(&ha), s(&a)]);
    assert_eq!(mixed.status.code(), Some(2));
    // One hit moved further along its ray: a wrong answer, with or without the oracle.
    let mut bytes = std::fs::read(&ha).unwrap();
    let k = (bytes
        .chunks(16)
        .position(|h| h[4..8] != [0xff; 4])
        .expect("a hit"))
        * 16;
    let t = f32::from_le_bytes(bytes[k..k + 4].try_into().unwrap()) * 1.5;
    bytes[k..k + 4].copy_from_slice(&t.to_le_bytes());
    std::fs::write(&hb, bytes).unwrap();
    lancer_ok(&[
        "compare",
        s(&ha),
        s(&ha),
        "--mesh",
        s(&quad),
        "--rays",
        s(&rays),
    ]);
    assert_eq!(lancer(&["compare", s(&ha), s(&hb)]).status.code(), Some(1));
    let judged = lancer(&[
        "compare",
        s(&ha),
        s(&hb),
        "--mesh",
        s(&quad),
        "--rays",
        s(&rays),
    ]);
    assert_eq!(judged.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&judged.stdout).contains("1 disagree"));
    // Every hit's t 4 ulps further (another kernel's arithmetic): beyond --t-ulps 2 without
    // the oracle, within its error bound with it.
    let mut bytes = std::fs::read(&ha).unwrap();
    for h in bytes.chunks_mut(16).filter(|h| h[4..8] != [0xff; 4]) {
        let t = u32::from_le_bytes(h[..4].try_into().unwrap()) + 4;
        h[..4].copy_from_slice(&t.to_le_bytes());
    }
    std::fs::write(&hb, bytes).unwrap();
    assert_eq!(lancer(&["compare", s(&ha), s(&hb)]).status.code(), Some(1));
    lancer_ok(&["compare", s(&ha), s(&hb), "--t-ulps", "4"]);
    let judged = lancer_ok(&[
        "compare",
        s(&ha),
        s(&hb),
        "--mesh",
        s(&quad),
        "--rays",
        s(&rays),
    ]);
    assert!(String::from_utf8_lossy(&judged.stdout).contains(" 0 disagree"));
}

/// "Check your own kernel": a kernel with another triangle test (Möller–Trumbore, as
/// `trace --triangle-test moller-trumbore` runs it) gives the default's triangles at a t a
/// few ulps away; `compare --mesh --rays` judges those t by the oracle and passes them,
/// where a bit-for-bit comparison (`--t-ulps 0`) finds them.
#[test]
fn compare_passes_a_correct_kernel_of_another_triangle_test() {
    let d = Scratch::new();
    let mesh = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.obj");
    let (rays, wt, mt) = (d.path("r.bin"), d.path("wt.hits"), d.path("mt.hits"));
    let size = ["--width", "64", "--height", "64"];
    lancer_ok(&[&["rays", s(&mesh), "-o", s(&rays)][..], &size].concat());
    let trace = |out: &PathBuf, test: &str| {
        lancer_ok(&[
            "trace",
            s(&mesh),
            "--rays",
            s(&rays),
            "-o",
            s(out),
            "--device",
            "cpu",
            "--triangle-test",
            test,
        ])
    };
    trace(&wt, "watertight");
    trace(&mt, "moller-trumbore");
    let exact = lancer(&["compare", s(&wt), s(&mt), "--t-ulps", "0"]);
    assert_eq!(
        exact.status.code(),
        Some(1),
        "the two tests gave the same bits"
    );
    let judged = lancer_ok(&[
        "compare",
        s(&wt),
        s(&mt),
        "--mesh",
        s(&mesh),
        "--rays",
        s(&rays),
    ]);
    let text = String::from_utf8_lossy(&judged.stdout).into_owned();
    assert!(text.contains(" 0 disagree"), "{text}");
}

/// scenes/teapot-in-stadium.toml, when ../shared/models (its teapot) is present.
fn teapot_in_stadium() -> Option<PathBuf> {
    common::model("teapot.obj")?;
    Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/teapot-in-stadium.toml"))
}

#[test]
fn the_teapot_in_a_stadium_is_a_small_dense_mesh_in_a_large_sparse_one() {
    let (Some(scene), Some(teapot)) = (teapot_in_stadium(), common::model("teapot.obj")) else {
        return;
    };
    let mesh = lancer::RenderScene::from_file(&scene).unwrap().mesh;
    let teapot = lancer::mesh::load_mesh(&teapot).unwrap();
    // The teapot's triangles first (file order), then the stadium's.
    let (dense, sparse) = mesh.triangles.split_at(teapot.len());
    assert!(
        sparse.len() >= 100 && sparse.len() * 20 < dense.len(),
        "{}",
        sparse.len()
    );
    let area =
        |t: &lancer::geometry::Triangle| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
    let largest_dense = dense.iter().map(area).fold(0.0, f32::max);
    let smallest_sparse = sparse.iter().map(area).fold(f32::MAX, f32::min);
    assert!(
        smallest_sparse > 100.0 * largest_dense,
        "{smallest_sparse} vs {largest_dense}"
    );
    // The teapot stands inside the bowl, which is ~100 times its size.
    let (b, t) = (mesh.bounds(), teapot.bounds());
    assert!(b.lo.cmple(t.lo).all() && t.hi.cmple(b.hi).all());
    assert!(b.extent().length() > 50.0 * t.extent().length());
}

#[test]
fn bench_structures_runs_every_structure_on_the_teapot_in_a_stadium() {
    let Some(scene) = teapot_in_stadium() else {
        return;
    };
    let dir = Scratch::new();
    let (json, chart) = (dir.path("structures.json"), dir.path("structures.png"));
    let out = lancer_ok(&[
        "bench",
        "structures",
        s(&scene),
        "--width",
        "16",
        "--height",
        "12",
        "--random",
        "100",
        "--repeat",
        "1",
        "--device",
        "gpu",
        "--json",
        s(&json),
        "--chart",
        s(&chart),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let mesh = lancer::RenderScene::from_file(&scene).unwrap().mesh;
    assert_eq!(v["triangles"], mesh.included().len());
    assert!(v["adapter"].as_str().unwrap() != "none (CPU only)", "{v}");
    let (sizes, runs) = (
        v["structures"].as_array().unwrap(),
        v["runs"].as_array().unwrap(),
    );
    assert_eq!(sizes.len(), lancer::AccelKind::ALL.len());
    for kind in lancer::AccelKind::ALL {
        let name = kind.name();
        let size = sizes.iter().find(|s| s["structure"] == name).unwrap();
        assert!(size["bytes"].as_u64().unwrap() > 0, "{size}");
        assert!(size["build_ms"].as_f64().unwrap() >= 0.0, "{size}");
        let gpu = lancer::accel::build_gpu(*kind, &mesh, &Default::default())
            .unwrap()
            .is_some();
        assert_eq!(size["gpu"], gpu, "{size}");
        let mine: Vec<_> = runs.iter().filter(|r| r["structure"] == name).collect();
        let sets: Vec<_> = mine.iter().map(|r| r["rays"].as_str().unwrap()).collect();
        assert_eq!(sets, ["primary", "shadow", "random"], "{name}");
        for r in mine {
            assert!(
                text.contains(&format!(
                    "| {name} | {} | {} |",
                    r["rays"].as_str().unwrap(),
                    r["count"]
                )),
                "{text}"
            );
            assert!(r["cpu_mrays_per_s"].as_f64().unwrap() > 0.0, "{r}");
            // A GPU rate exactly for the structures with a GPU kernel.
            assert_eq!(r["gpu_mrays_per_s"].as_f64().is_some(), gpu, "{r}");
            if r["rays"] == "random" {
                // Origins inside the bounds: every ray enters the structure.
                assert_eq!(r["count"], 100);
                assert!(r["nodes_per_ray"].as_f64().unwrap() >= 1.0, "{r}");
            }
        }
    }
    let png = std::fs::read(&chart).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "the chart is a PNG");
}

#[test]
fn mesh_and_scene_files_are_chosen_by_extension_and_unknown_ones_refused() {
    let dir = Scratch::new();
    let quad = dir.quad();
    let text = std::fs::read_to_string(&quad).unwrap();
    let stl = dir.path("quad.stl");
    std::fs::write(&stl, &text).unwrap();
    let png = dir.path("x.png");
    for args in [
        vec!["build", s(&stl)],
        vec!["heatmap", s(&stl), "-o", s(&png)],
        vec!["render", s(&stl), "-o", s(&png)],
    ] {
        let cmd = args[0];
        let out = lancer(&args);
        assert_eq!(out.status.code(), Some(2), "{cmd}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{cmd}: {err}");
        assert!(err.contains("unknown file type '.stl'"), "{cmd}: {err}");
    }

    // The same quad as ASCII PLY builds to the same triangle count as the OBJ.
    let ply = dir.path("quad.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         -1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
    let count = |p: &Path| {
        let out = lancer_ok(&["build", s(p), "--json"]);
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        j["triangles"].as_u64().unwrap()
    };
    assert_eq!(count(&ply), 2);
    assert_eq!(count(&ply), count(&quad));

    // A scene builds to its assembled mesh: the textured scene's quad and box.
    assert_eq!(count(&scene("textured.toml")), 2 + 12);

    // `render MESH.ply` draws the mesh on a ground plane.
    let png = dir.path("ply.png");
    lancer_ok(&[
        "render",
        s(&ply),
        "-o",
        s(&png),
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "1",
        "--device",
        "cpu",
    ]);
    assert_eq!(image::open(&png).unwrap().to_rgb8().dimensions(), (16, 12));
}

#[test]
fn adapters_lists_lavapipe_and_an_unmatched_adapter_name_is_an_error_with_auto_too() {
    let out = lancer_ok(&["adapters"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("llvmpipe"), "{text}");
    assert!(
        text.contains("subgroups") && text.contains("timestamps"),
        "{text}"
    );
    let d = Scratch::new();
    let (quad, rays) = quad_with_rays(&d);
    let hits = d.path("h.bin");
    let out = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(["trace", s(&quad), "--rays", s(&rays), "--out", s(&hits)])
        .env("WGPU_ADAPTER_NAME", "no-such-adapter")
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(1),
        "auto must not fall back to the CPU silently"
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("matches none of the adapters"));
    assert!(!hits.exists());
}

#[test]
fn bad_wgpu_environment_is_refused_under_auto_too() {
    // A misspelt WGPU_BACKEND or WGPU_POWER_PREF is the user's to fix: exit 2 naming it,
    // not a fallback to the CPU (exit 0) nor a silently ignored setting.
    let d = Scratch::new();
    let (quad, rays) = quad_with_rays(&d);
    for (var, value) in [("WGPU_BACKEND", "vulkn"), ("WGPU_POWER_PREF", "weird")] {
        let hits = d.path("h.bin");
        let out = Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(["trace", s(&quad), "--rays", s(&rays), "--out", s(&hits)])
            .env(var, value)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{var}={value}: {err}");
        assert!(err.contains(&format!("{var}={value}")), "{err}");
        assert!(!hits.exists());
    }
}

/// The quad mesh and a ray file of its default view, 4×4 (r.bin), in `d`.
fn quad_with_rays(d: &Scratch) -> (PathBuf, PathBuf) {
    let (quad, rays) = (d.quad(), d.path("r.bin"));
    view_rays(&quad, 4, 4, &rays);
    (quad, rays)
}

/// `trace --stats --json` on `quad` with `args` before and after the subcommand and
/// `env`: the JSON object and stderr.
fn trace_json(
    dir: &Scratch,
    global: &[&str],
    args: &[&str],
    env: &[(&str, &str)],
) -> (serde_json::Value, String) {
    let quad = dir.quad();
    let (rays, hits) = (dir.path("tj.rays"), dir.path("tj.hits"));
    view_rays(&quad, 8, 8, &rays);
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lancer"));
    cmd.args(global)
        .args(["trace", s(&quad), "--rays", s(&rays), "--out", s(&hits)])
        .args(["--stats", "--json"])
        .args(args)
        .env_remove("WGPU_ADAPTER_NAME");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON object ({e}): {:?}", out.stdout));
    (v, err)
}

#[test]
fn auto_runs_on_a_hardware_gpu_else_on_the_cpu_and_says_why() {
    let dir = Scratch::new();
    // What this machine has: the adapter wgpu prefers, and whether it is a software one.
    let preferred = lancer::gpu::GpuContext::new().ok().map(|c| c.adapter);
    let (auto, err) = trace_json(&dir, &[], &[], &[]);
    match &preferred {
        Some(a) if !a.software => assert_eq!(auto["device"], "gpu", "{auto}"),
        Some(a) => {
            assert_eq!(auto["device"], "cpu", "{auto}");
            // The CPU is a normal place to run: no warning. With -v, one info line says
            // what was chosen and why, and how to force the adapter.
            assert!(!err.lines().any(|l| l.starts_with("warning:")), "{err}");
            let (_, verbose) = trace_json(&dir, &["-v"], &[], &[]);
            let why: Vec<&str> = (verbose.lines())
                .filter(|l| l.contains("using the CPU"))
                .collect();
            assert_eq!(why.len(), 1, "{verbose}");
            assert!(
                why[0].starts_with("info:")
                    && why[0].contains(&a.name)
                    && why[0].contains("--device gpu"),
                "{verbose}"
            );
        }
        None => assert_eq!(auto["device"], "cpu", "{auto}"),
    }
    // The power preference orders hardware adapters (none: wgpu's order, software first or
    // not); it never makes auto take a software one.
    for pref in ["low", "none"] {
        let (v, _) = trace_json(&dir, &[], &[], &[("WGPU_POWER_PREF", pref)]);
        assert_eq!(v["device"], auto["device"], "WGPU_POWER_PREF={pref}: {v}");
    }
    // -q is errors only: no summary, no warning; the data is the same.
    assert!(err.contains("64 rays"), "{err}");
    let (quiet, err) = trace_json(&dir, &["-q"], &[], &[]);
    assert_eq!(quiet["device"], auto["device"]);
    assert!(!err.contains("warning"), "-q printed: {err}");
    assert!(!err.contains("64 rays"), "-q printed the summary: {err}");
    let Some(adapter) = preferred else {
        return;
    };
    // --device gpu forces the adapter, software or not; so does naming it with auto.
    let (gpu, _) = trace_json(&dir, &[], &["--device", "gpu"], &[]);
    assert_eq!(gpu["device"], "gpu", "{gpu}");
    let (named, _) = trace_json(&dir, &[], &[], &[("WGPU_ADAPTER_NAME", &adapter.name)]);
    assert_eq!(named["device"], "gpu", "{named}");
    assert!(
        named["adapter"].as_str().unwrap().contains(&adapter.name),
        "{named}"
    );
    // Same answers wherever they ran.
    assert_eq!(gpu["hits"], auto["hits"]);
}

#[test]
fn threads_sets_the_cpu_pool_and_is_validated() {
    let dir = Scratch::new();
    for n in ["1", "3"] {
        let (v, _) = trace_json(&dir, &["--threads", n], &["--device", "cpu"], &[]);
        assert_eq!(v["cpu_threads"].to_string(), n, "{v}");
    }
    // 0 is every core: rayon's default pool.
    let (all, _) = trace_json(&dir, &[], &["--device", "cpu", "--threads", "0"], &[]);
    let (default, _) = trace_json(&dir, &[], &["--device", "cpu"], &[]);
    assert_eq!(all["cpu_threads"], default["cpu_threads"]);
    for bad in ["-1", "many", "100000"] {
        let out = lancer(&["--threads", bad, "build", s(&dir.quad())]);
        assert_eq!(out.status.code(), Some(2), "--threads {bad}");
    }
}

#[test]
fn rays_pipe_into_trace_and_check_and_hits_come_out_on_stdout() {
    let dir = Scratch::new();
    let quad = dir.quad();
    let (rays, hits) = (dir.path("p.rays"), dir.path("p.hits"));
    let view = ["--width", "9", "--height", "7"];
    lancer_ok(&[&["rays", s(&quad), "-o", s(&rays)][..], &view].concat());
    let trace = ["--device", "cpu"];
    lancer_ok(
        &[
            &["trace", s(&quad), "--rays", s(&rays), "-o", s(&hits)][..],
            &trace,
        ]
        .concat(),
    );
    // lancer rays … -o - | lancer trace MESH --rays - --out - > hits
    let mut producer = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args([&["rays", s(&quad), "-o", "-"][..], &view].concat())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let consumer = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(
            [
                &["trace", s(&quad), "--rays", "-", "--out", "-"][..],
                &trace,
            ]
            .concat(),
        )
        .stdin(producer.stdout.take().unwrap())
        .output()
        .unwrap();
    let produced = producer.wait_with_output().unwrap();
    assert!(produced.status.success());
    assert!(
        consumer.status.success(),
        "{}",
        String::from_utf8_lossy(&consumer.stderr)
    );
    // stdout carries the data only, byte for byte what the files hold; the words go to stderr.
    assert_eq!(consumer.stdout, std::fs::read(&hits).unwrap());
    assert!(String::from_utf8_lossy(&consumer.stderr).contains("63 rays"));
    assert!(String::from_utf8_lossy(&produced.stderr).contains("63 rays written to -"));
    // rays -o - alone writes exactly the ray file.
    let out = lancer_ok(&[&["rays", s(&quad), "-o", "-"][..], &view].concat());
    assert_eq!(out.stdout, std::fs::read(&rays).unwrap());
    // A truncated stream on stdin is refused like a truncated file.
    let mut child = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args([
            "trace",
            s(&quad),
            "--rays",
            "-",
            "--out",
            "-",
            "--device",
            "cpu",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&[0u8; 40]).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).contains("<stdin>"));
    // check --rays - reads the same stream: every layout's rows name it.
    let mut child = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(["check", s(&quad), "--rays", "-", "--layout", "dfs-sign"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(&std::fs::read(&rays).unwrap())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("| dfs-sign | per-ray | <stdin> | Closest | 63 |"),
        "{text}"
    );
}

/// Runs lancer expecting `code`; stdout must be exactly one line holding one JSON object.
fn json_of(args: &[&str], code: i32) -> (serde_json::Value, String) {
    let out = lancer(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        text.lines().count(),
        1,
        "{args:?}: stdout is not one line:\n{text}"
    );
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v.is_object(), "{v}");
    (v, err)
}

/// Every key of `v`, of the objects in its arrays included.
fn keys(v: &serde_json::Value, into: &mut std::collections::BTreeSet<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                into.insert(k.clone());
                keys(x, into);
            }
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| keys(x, into)),
        _ => {}
    }
}

#[test]
fn json_is_one_object_on_stdout_the_text_on_stderr_and_every_key_is_documented() {
    let d = Scratch::new();
    let quad = d.quad();
    let (rays, ha, hb, png) = (
        d.path("r.bin"),
        d.path("a.hits"),
        d.path("b.hits"),
        d.path("h.png"),
    );
    let heat = d.path("heat.png");
    view_rays(&quad, 8, 8, &rays);
    lancer_ok(&[
        "heatmap",
        s(&quad),
        "-o",
        s(&png),
        "--width",
        "8",
        "--height",
        "8",
        "--device",
        "cpu",
    ]);
    let small = ["--width", "8", "--height", "8", "--repeat", "1"];
    let textured = scene("textured.toml");
    let chart = d.path("acc.png");
    let gpu = lancer::gpu::GpuContext::new().is_ok();
    let mut runs: Vec<(Vec<&str>, i32, &str)> = vec![
        (vec!["build", s(&quad), "--json"], 0, ""),
        (
            vec![
                "trace",
                s(&quad),
                "--rays",
                s(&rays),
                "-o",
                s(&ha),
                "--stats",
                "--json",
            ],
            0,
            "64 rays",
        ),
        (
            vec!["compare", s(&png), s(&png), "--json"],
            0,
            "bit-identical",
        ),
        (
            vec![
                "heatmap",
                s(&quad),
                "-o",
                s(&heat),
                "--width",
                "8",
                "--height",
                "8",
                "--device",
                "cpu",
                "--rays",
                "shadow",
                "--max",
                "4",
                "--json",
            ],
            0,
            "pixels saturated",
        ),
        (
            vec!["bench", "trace", s(&quad), "--device", "cpu", "--json"],
            0,
            "| primary",
        ),
        (
            vec![
                "bench",
                "render",
                s(&textured),
                "--spp",
                "3",
                "--device",
                "cpu",
                "--json",
            ],
            0,
            "| cpu | – | specialised",
        ),
        (
            vec![
                "bench",
                "structures",
                s(&quad),
                "--random",
                "10",
                "--device",
                "cpu",
                "--json",
                "-",
            ],
            0,
            "| octree |",
        ),
        (
            vec!["bench", "layouts", s(&quad), "--device", "cpu", "--json"],
            0,
            "| dfs-sign |",
        ),
        (
            vec!["bench", "scale", s(&quad), "--device", "cpu", "--json"],
            0,
            "| (flatten + device) ÷ build |",
        ),
        (
            vec![
                "bench",
                "accuracy",
                s(&textured),
                "--render-size",
                "4",
                "--reference-spp",
                "16",
                "--max-spp",
                "1",
                "--reference-bounces",
                "1",
                "--device",
                "cpu",
                "--chart",
                s(&chart),
                "--json",
            ],
            0,
            "| defaults |",
        ),
    ];
    // Small views and one timed run: bench render has neither option.
    for r in runs
        .iter_mut()
        .filter(|r| r.0[0] == "bench" && r.0[1] != "render")
    {
        r.0.splice(3..3, small);
    }
    if gpu {
        // check needs a GPU: auto takes any adapter there, lavapipe included.
        lancer_ok(&[
            "check",
            s(&quad),
            "--width",
            "4",
            "--height",
            "4",
            "--layout",
            "dfs-sign",
        ]);
        runs.push((
            vec![
                "check",
                s(&quad),
                "--width",
                "4",
                "--height",
                "4",
                "--device",
                "gpu",
                "--json",
            ],
            0,
            "every answer agrees",
        ));
    }
    let section = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/src/reference/json.md"
    ))
    .expect("the book's JSON reference page");
    for (args, code, text) in &runs {
        let (v, err) = json_of(args, *code);
        assert!(
            err.contains(text),
            "{args:?}: the text is not on stderr: {err}"
        );
        let mut all = Default::default();
        keys(&v, &mut all);
        for k in all {
            assert!(
                section.contains(&format!("`{k}`")),
                "{args:?}: key {k} is not in docs/src/reference/json.md"
            );
        }
    }
    // A difference still prints its object, then exits 1.
    let mut bytes = std::fs::read(&ha).unwrap();
    let k = bytes
        .chunks(16)
        .position(|h| h[4..8] != [0xff; 4])
        .expect("a hit")
        * 16;
    let t = f32::from_le_bytes(bytes[k..k + 4].try_into().unwrap()) * 1.5;
    bytes[k..k + 4].copy_from_slice(&t.to_le_bytes());
    std::fs::write(&hb, bytes).unwrap();
    let judged = ["--mesh", s(&quad), "--rays", s(&rays)];
    let (v, _) = json_of(
        &[&["compare", s(&ha), s(&hb), "--json"][..], &judged].concat(),
        1,
    );
    assert_eq!(
        (
            v["kind"].as_str(),
            v["disagree"].as_u64(),
            v["judged"].as_bool()
        ),
        (Some("hits"), Some(1), Some(true)),
        "{v}"
    );
    let (v, _) = json_of(&["compare", s(&ha), s(&hb), "--json"], 1);
    assert_eq!(
        (v["disagree"].as_u64(), v["genuine_ties"].is_null()),
        (Some(1), true),
        "{v}"
    );
    // --json FILE.json writes the file and keeps the tables on stdout; any other name
    // (a mesh given after --json, say) is refused before anything is written.
    let file = d.path("t.json");
    let out = lancer_ok(
        &[
            &[
                "bench",
                "trace",
                s(&quad),
                "--device",
                "cpu",
                "--json",
                s(&file),
            ][..],
            &small,
        ]
        .concat(),
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    assert_eq!(v["runs"].as_array().unwrap().len(), 2, "{v}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("| primary"));
    let before = std::fs::read(&quad).unwrap();
    lancer_refused(&["bench", "layouts", "--json", s(&quad)]);
    assert_eq!(std::fs::read(&quad).unwrap(), before);
    // Two writers of stdout at once is a usage error.
    lancer_refused(&[
        "trace",
        s(&quad),
        "--rays",
        s(&rays),
        "--out",
        "-",
        "--json",
    ]);
}

/// The names in the "Commands:" list of a help text (clap's own `help` left out).
fn commands_in(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}

#[test]
fn every_subcommand_has_help_and_every_option_says_what_it_does() {
    let top = String::from_utf8(lancer_ok(&["--help"]).stdout).unwrap();
    let mut commands: Vec<Vec<String>> = Vec::new();
    for c in commands_in(&top) {
        let help = String::from_utf8(lancer_ok(&[&c, "--help"]).stdout).unwrap();
        let subs = commands_in(&help);
        if subs.is_empty() {
            commands.push(vec![c]);
        } else {
            commands.extend(subs.into_iter().map(|s| vec![c.clone(), s]));
        }
    }
    assert!(commands.len() >= 12, "{commands:?}");
    for cmd in &commands {
        let mut args: Vec<&str> = cmd.iter().map(String::as_str).collect();
        args.push("--help");
        let text = String::from_utf8(lancer_ok(&args).stdout).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let mut options = 0;
        for (i, line) in lines.iter().enumerate() {
            let t = line.trim_start();
            // Option lines are indented 2 (with a short form) or 6; their words, 10 or more.
            if line.len() - t.len() > 6 || !t.starts_with('-') {
                continue;
            }
            options += 1;
            let same_line = t
                .find("  ")
                .map(|k| t[k..].trim())
                .filter(|d| !d.is_empty());
            let words = same_line.unwrap_or_else(|| lines.get(i + 1).map_or("", |n| n.trim()));
            assert!(
                words.len() > 3 && !words.starts_with('-') && !words.starts_with("[default"),
                "lancer {}: {t:?} does not say what it does",
                cmd.join(" ")
            );
        }
        assert!(
            options >= 3,
            "lancer {}: no options found in\n{text}",
            cmd.join(" ")
        );
        // Help is for people: no rustdoc links, no shader binding numbers.
        for internal in ["[`", "`]", "@binding", "binding("] {
            assert!(
                !text.contains(internal),
                "lancer {}: {internal} in\n{text}",
                cmd.join(" ")
            );
        }
    }
}

#[test]
fn compare_counts_nan_and_infinite_pixels_by_their_bits() {
    use lancer::render::{Crop, ExrImage, Tile};
    let d = Scratch::new();
    let exr = |name: &str, r: f32| {
        let (w, h) = (4u32, 3u32);
        let n = (w * h) as usize;
        let img = ExrImage {
            tile: Tile {
                bounds: Crop::full(w, h),
                full_width: w,
                full_height: h,
            },
            channels: vec![
                ("B".into(), vec![0.25; n]),
                ("G".into(), vec![0.5; n]),
                ("R".into(), vec![r; n]),
            ],
        };
        let p = d.path(name);
        img.write(&p).unwrap();
        p
    };
    let (clean, nan, inf) = (
        exr("clean.exr", 0.5),
        exr("nan.exr", f32::NAN),
        exr("inf.exr", f32::INFINITY),
    );
    // NaN everywhere in R is no match for a clean image (the max over channels dropped it).
    let out = lancer(&["compare", s(&clean), s(&nan)]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("12 pixels"), "{text}");
    // +∞ against itself is bit-identical (it was "100 % over").
    let out = lancer(&["compare", s(&inf), s(&inf)]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("bit-identical"), "{text}");
    assert_eq!(
        lancer(&["compare", s(&inf), s(&clean)]).status.code(),
        Some(1)
    );
}

#[test]
fn a_closed_stdout_ends_quietly_not_in_a_panic() {
    // `lancer build … | true`: the reader is gone before lancer prints.
    let d = Scratch::new();
    let quad = d.quad();
    for args in [vec!["build", s(&quad)], vec!["adapters"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "{args:?}: {:?} {err}",
            out.status
        );
    }
}

#[test]
fn bench_builders_counts_each_builds_peak_memory_and_takes_several_meshes() {
    let dir = Scratch::new();
    let q = dir.quad();
    let cornell = Path::new("scenes/cornell-box.obj");
    let json = dir.path("builders.json");
    let chart = dir.path("builders.png");
    let out = lancer_ok(&[
        "bench",
        "builders",
        "--chart",
        s(&chart),
        s(&q),
        s(cornell),
        "--builder",
        "median",
        "--optimize",
        "--width",
        "8",
        "--height",
        "8",
        "--repeat",
        "1",
        "--device",
        "cpu",
        "--json",
        s(&json),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("| cornell-box.obj | median+reinsert |"),
        "{text}"
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let builds = v["builds"].as_array().unwrap();
    let lancer_rows: Vec<_> = builds
        .iter()
        .filter(|b| b["builder"] != "embree-medium")
        .collect();
    assert_eq!(lancer_rows.len(), 4, "{v}");
    // The binary counts its heap: every build held some memory, and says how much.
    for b in lancer_rows {
        assert!(b["peak_mib"].as_f64().unwrap() > 0.0, "{b}");
    }
}

/// A glTF mesh drawn by four nodes (one mirrored) is traced in two levels, on the CPU and
/// on the GPU, numbering hits as `--flatten` does: the same triangle for (almost) every ray.
#[test]
fn a_gltf_mesh_drawn_by_several_nodes_is_traced_in_two_levels() {
    use common::writers::{data_uri, gltf_buffer, gltf_json, Indexed};
    let dir = Scratch::new();
    let n = 6u32;
    let verts = (0..=n)
        .flat_map(|j| {
            (0..=n).map(move |i| {
                [
                    i as f32 / n as f32,
                    j as f32 / n as f32,
                    0.1 * (i % 2) as f32,
                ]
            })
        })
        .collect();
    let faces = (0..n)
        .flat_map(|j| (0..n).map(move |i| (j * (n + 1) + i, n + 1)))
        .map(|(a, w)| vec![a, a + 1, a + w + 1, a + w])
        .collect();
    let grid = Indexed { verts, faces };
    let mut doc = gltf_json(&grid, Some(data_uri(&gltf_buffer(&grid))));
    doc["nodes"] = serde_json::json!([
        { "mesh": 0 },
        { "mesh": 0, "translation": [1.25, 0.0, 0.0] },
        { "mesh": 0, "translation": [0.0, 1.25, 0.5], "rotation": [0.0, 0.0, 0.3826834, 0.9238795] },
        { "mesh": 0, "scale": [-1.0, 1.0, 1.0], "translation": [2.5, 1.25, 0.0] }
    ]);
    doc["scenes"] = serde_json::json!([{ "nodes": [0, 1, 2, 3] }]);
    let scene = dir.path("four.gltf");
    std::fs::write(&scene, serde_json::to_vec(&doc).unwrap()).unwrap();
    let rays = dir.path("four.rays");
    view_rays(&scene, 40, 30, &rays);
    let trace = |device: &str, extra: &[&str]| {
        let hits = dir.path(&format!("{device}{}.hits", extra.len()));
        let mut args = vec![
            "-v",
            "trace",
            s(&scene),
            "--rays",
            s(&rays),
            "--out",
            s(&hits),
        ];
        args.extend(["--device", device]);
        args.extend(extra);
        let out = lancer_ok(&args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        (lancer::trace::files::read_hits(&hits).unwrap(), err)
    };
    let built = lancer_ok(&["build", s(&scene), "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&built.stdout).unwrap();
    assert_eq!(
        (j["instances"].as_u64(), j["instanced_triangles"].as_u64()),
        (Some(4), Some(288))
    );
    let (flat, flat_log) = trace("cpu", &["--flatten"]);
    assert!(!flat_log.contains("two levels"), "{flat_log}");
    let hit = flat.iter().filter(|h| h.is_hit()).count();
    assert!(hit > 150, "only {hit} of {} rays hit", flat.len());
    assert!(
        flat.iter().any(|h| h.is_hit() && h.prim >= 3 * 72),
        "the mirrored copy is hit"
    );
    for device in ["cpu", "gpu"] {
        let (two, log) = trace(device, &[]);
        // The mirrored node draws a copy of the mesh with two corners swapped.
        assert!(log.contains("2 meshes placed by 4 instances"), "{log}");
        let differ = two
            .iter()
            .zip(&flat)
            .filter(|(a, b)| a.prim != b.prim)
            .count();
        println!(
            "{device}: {differ} of {} rays hit another triangle",
            flat.len()
        );
        assert!(
            differ * 100 <= flat.len(),
            "{device}: {differ} rays hit another triangle"
        );
    }
    // Rendered in two levels too, with the file's materials, on both devices, as its
    // flattened copy renders (within 2 % of the pixels at the default threshold).
    let render = |device: &str, extra: &[&str]| {
        let img = dir.path(&format!("{device}{}.exr", extra.len()));
        let mut args = vec!["render", s(&scene), "--width", "48", "--height", "36"];
        args.extend([
            "--spp",
            "2",
            "--stats",
            "--json",
            "-o",
            s(&img),
            "--device",
            device,
        ]);
        args.extend(extra);
        let out = lancer_ok(&args);
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (img, j)
    };
    let (flat_img, j) = render("cpu", &["--flatten"]);
    assert!(j["instances"].is_null(), "{j}");
    for device in ["cpu", "gpu"] {
        let (img, j) = render(device, &[]);
        assert_eq!(
            j["instances"].as_u64(),
            Some(4 + 1),
            "the nodes and the ground: {j}"
        );
        lancer_ok(&["compare", s(&flat_img), s(&img), "--tolerance", "2"]);
    }
}

/// `render --frames A..B` writes one numbered image a frame of a scene whose objects move;
/// an empty range is refused as a usage error.
#[test]
fn render_frames_writes_a_numbered_sequence() {
    let dir = Scratch::new();
    let src = std::fs::read_to_string("scenes/copies.toml").unwrap();
    let moving = src.replacen("scale = 0.4\n", "scale = 0.4\nmove = [0.2, 0.0, 0.0]\n", 1);
    assert_ne!(moving, src);
    let scene = dir.path("moving.toml");
    std::fs::write(&scene, moving).unwrap();
    let out = dir.path("f.png");
    let args = [
        "render",
        s(&scene),
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "1",
    ];
    let mut ok = args.to_vec();
    ok.extend(["--frames", "3..5", "-o", s(&out)]);
    lancer_ok(&ok);
    let frames: Vec<Vec<u8>> = ["f-0003.png", "f-0004.png"]
        .iter()
        .map(|f| std::fs::read(dir.path(f)).unwrap())
        .collect();
    assert_ne!(frames[0], frames[1], "the spheres moved");
    assert!(!out.exists() && !dir.path("f-0005.png").exists());
    let mut empty = args.to_vec();
    empty.extend(["--frames", "5..5", "-o", s(&out)]);
    assert!(lancer_refused(&empty).contains("no frame in 5..5"));
    // The name given is never written itself, only its numbered names: a folder of that
    // name is no reason to refuse.
    let taken = dir.path("taken.png");
    std::fs::create_dir(&taken).unwrap();
    let mut beside = args.to_vec();
    beside.extend(["--frames", "3..4", "-o", s(&taken)]);
    lancer_ok(&beside);
    assert!(dir.path("taken-0003.png").is_file() && taken.is_dir());
}

/// `render FILE.gltf --frames A..` plays the file's animation to its last key at `--fps`;
/// `A..` is refused where nothing is animated, and a frame whose map scales to 0 is refused
/// naming the frame (exit 2).
#[test]
fn render_frames_plays_a_gltf_animation() {
    let dir = Scratch::new();
    let write = |name: &str, vanish: bool| {
        let path = dir.path(name);
        let doc = common::writers::animated_cube([1.5, 0.0, 0.0], vanish, false);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        path
    };
    let slide = write("slide.gltf", false);
    let out = dir.path("a.png");
    let args = |file: &Path, frames: &str| {
        let mut a: Vec<String> = ["render", s(file), "--width", "32", "--height", "24"]
            .map(String::from)
            .to_vec();
        a.extend(
            [
                "--spp",
                "1",
                "--fps",
                "2",
                "--frames",
                frames,
                "-o",
                s(&out),
            ]
            .map(String::from),
        );
        a
    };
    let run = |a: &[String]| lancer(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let done = run(&args(&slide, "0.."));
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let frames: Vec<Vec<u8>> = ["a-0000.png", "a-0001.png", "a-0002.png"]
        .iter()
        .map(|f| std::fs::read(dir.path(f)).unwrap())
        .collect();
    assert!(
        !dir.path("a-0003.png").exists(),
        "one second at 2 frames a second: 0, 1, 2"
    );
    assert!(
        frames[0] != frames[1] && frames[1] != frames[2],
        "the cube moves"
    );
    let still = dir.path("still.toml");
    std::fs::write(
        &still,
        std::fs::read_to_string("scenes/copies.toml").unwrap(),
    )
    .unwrap();
    let open_end = run(&args(&still, "0.."));
    assert_eq!(open_end.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&open_end.stderr).contains("plays no glTF animation"));
    // An animation's end far off at a high frame rate: refused, not rendered for ever.
    let far: Vec<String> = (args(&slide, "0..").into_iter())
        .map(|a| if a == "2" { "1e7".to_string() } else { a })
        .collect();
    let too_many = run(&far);
    assert_eq!(too_many.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&too_many.stderr).contains("split the range"));
    let vanish = write("vanish.gltf", true);
    let refused = run(&args(&vanish, "0..3"));
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("frame 2") && err.contains("singular"), "{err}");
}

#[test]
fn texture_coordinates_that_are_not_finite_are_read_as_zero_and_counted() {
    let dir = Scratch::new();
    let obj = dir.path("nan-uv.obj");
    std::fs::write(
        &obj,
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt nan 0\nvt 1 inf\nvt 0 1\n\
         f 1/1 2/2 3/3\nf 1/1 3/4 4/4\n",
    )
    .unwrap();
    let png = dir.path("nan-uv.png");
    let out = lancer_ok(&[
        "render",
        s(&obj),
        "-o",
        s(&png),
        "--device",
        "cpu",
        "--width",
        "8",
        "--height",
        "8",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("1 triangle(s) have texture coordinates that are not finite"),
        "{err}"
    );
    let scene = lancer::render::RenderScene::from_mesh(&obj, 8, 8).unwrap();
    assert!(scene.uvs.iter().flatten().all(|c| c.is_finite()));
    assert_eq!(scene.uvs[0][1], glam::Vec2::new(0.0, 0.0));
    assert_eq!(scene.uvs[0][2], glam::Vec2::new(1.0, 0.0));
}
