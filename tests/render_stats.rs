//! `render --stats`: the GPU pipeline's compilation is timed apart from the first sample
//! (compiled once per renderer and effect set), and `--stats --json` prints one JSON object
//! with the documented keys on stdout, the human summary on stderr.

mod common;

use std::path::PathBuf;
use std::process::Command;

use common::gpu_device;
use lancer::render::{RenderOptions, RenderScene, Renderer};
use lancer::Device;

fn cornell() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml")
}

#[test]
fn compilation_is_timed_before_the_first_sample_and_once() {
    let mut s = RenderScene::from_file(&cornell()).unwrap();
    (s.camera.width, s.camera.height) = (16, 12);
    let options = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    let mut gpu = Renderer::new(&s, gpu_device(), &options).unwrap();
    let first = gpu.render(&options).unwrap();
    let again = gpu.render(&options).unwrap();
    println!(
        "gpu: upload {:.1} ms, compile {:.1} ms, first sample {:.1} ms; again: compile {:.1} ms",
        gpu.upload_ms(),
        first.compile_ms,
        first.first_sample_ms,
        again.compile_ms
    );
    assert!(first.compile_ms > 0.0 && first.first_sample_ms > 0.0);
    // The pipeline is kept: the second render compiles nothing.
    assert_eq!(again.compile_ms, 0.0, "compiled twice");
    assert!(first.seconds * 1e3 >= first.first_sample_ms);
    let cpu = lancer::render::render(&s, &Device::cpu(), &options).unwrap();
    assert_eq!(cpu.compile_ms, 0.0, "nothing to compile on the CPU");
    assert!(cpu.first_sample_ms > 0.0);
}

const KEYS: [&str; 26] = [
    "output",
    "width",
    "height",
    "full_width",
    "full_height",
    "crop",
    "samples",
    "requested",
    "stop",
    "device",
    "structure",
    "layout",
    "mode",
    "bvh",
    "instances",
    "instanced_triangles",
    "effects",
    "bvh_memory",
    "build_ms",
    "upload_ms",
    "compile_ms",
    "first_sample_ms",
    "ms_per_spp",
    "seconds",
    "camera_rays_per_s",
    "cpu_pixels",
];

#[test]
fn stats_json_is_one_object_on_stdout() {
    let dir = tempfile::tempdir().unwrap();
    for (device, accel) in [("cpu", "octree"), ("gpu", "bvh")] {
        let out = dir.path().join(format!("{device}.exr"));
        let run = Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args([
                "render",
                cornell().to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ])
            .args([
                "--width", "16", "--height", "12", "--spp", "2", "--crop", "2", "3", "10", "12",
            ])
            .args(["--device", device, "--accel", accel, "--stats", "--json"])
            .output();
        let run = run.unwrap();
        let (stdout, stderr) = (
            String::from_utf8(run.stdout).unwrap(),
            String::from_utf8_lossy(&run.stderr).to_string(),
        );
        assert!(run.status.success(), "{device}: {stderr}");
        assert_eq!(
            stdout.lines().count(),
            1,
            "{device}: stdout is one line: {stdout}"
        );
        let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let obj = j.as_object().unwrap();
        let mut want: Vec<&str> = KEYS.to_vec();
        want.sort();
        let mut got: Vec<&str> = obj.keys().map(String::as_str).collect();
        got.sort();
        assert_eq!(got, want, "{device}: keys");
        assert_eq!(j["structure"], accel);
        assert_eq!(
            (j["width"].as_u64(), j["height"].as_u64()),
            (Some(8), Some(9))
        );
        assert_eq!(j["crop"], serde_json::json!([2, 3, 10, 12]));
        assert_eq!(j["samples"], 2);
        assert_eq!(j["stop"], "complete");
        let bvh = accel == "bvh";
        assert_eq!(
            j["bvh"].is_object(),
            bvh,
            "{device}: BVH statistics only for a BVH"
        );
        assert_eq!(j["layout"].is_string(), bvh);
        assert_eq!(j["bvh_memory"].is_string(), device == "gpu");
        // The mode that ran: per-ray, the default, on the GPU; none on the CPU.
        let mode = (device == "gpu").then_some("per-ray");
        assert_eq!(j["mode"].as_str(), mode, "{device}: mode");
        let compile = j["compile_ms"].as_f64().unwrap();
        assert_eq!(
            compile > 0.0,
            device == "gpu",
            "{device}: compile_ms {compile}"
        );
        assert!(j["first_sample_ms"].as_f64().unwrap() > 0.0);
        // The human summary went to stderr.
        assert!(
            stderr.contains("spp ->") && stderr.contains("first sample"),
            "{stderr}"
        );
        if device == "gpu" {
            assert!(stderr.contains("pipeline compile"), "{stderr}");
        }
    }
}

#[test]
fn stats_say_which_traversal_mode_ran() {
    // dfs-sign runs in subgroup mode on lavapipe; bvh4 has no subgroup traversal, so the
    // render falls back to per-ray and says so, on stderr and in the JSON.
    let dir = tempfile::tempdir().unwrap();
    for (layout, ran, note) in [
        ("dfs-sign", "subgroup", "mode: subgroup\n"),
        (
            "bvh4",
            "per-ray",
            "mode: per-ray (subgroup asked for, see the warning)",
        ),
    ] {
        let out = dir.path().join(format!("{layout}.png"));
        let run = Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(["render", cornell().to_str().unwrap(), "-o"])
            .arg(&out)
            .args([
                "--width", "8", "--height", "8", "--spp", "1", "--device", "gpu",
            ])
            .args([
                "--layout", layout, "--mode", "subgroup", "--stats", "--json",
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{layout}: {stderr}");
        let j: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(j["mode"], ran, "{layout}");
        assert!(stderr.contains(note), "{layout}: {stderr}");
        if ran == "per-ray" {
            assert!(stderr.contains("no subgroup traversal"), "{stderr}");
        }
    }
}
