//! `lancer heatmap` end to end: each map pixel is the heat ramp of the count the library
//! reports for its ray (nodes or triangles, primary or shadow rays), on a fixed `--max`
//! scale shared across layouts; pixels without a shadow ray are grey; the colour bar sits
//! below the map.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lancer::camera::Camera;
use lancer::render::heat_ramp;
use lancer::trace::defaults::CPU_LAYOUT;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{Device, LayoutKind, Query, RayStats, Tracer, TracerOptions};

/// Map size: small, so the suite stays fast.
const W: u32 = 24;
const H: u32 = 18;
/// The colour of a pixel without a shadow ray (README: heatmap).
const NO_RAY: [u8; 3] = [128, 128, 128];

fn lancer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(args)
        .output()
        .unwrap()
}

/// A random triangle soup as an OBJ: rays of the default view miss between the triangles
/// and do varied work where they hit.
fn soup_obj(dir: &Path) -> PathBuf {
    let mesh = common::soup(&mut common::Rng::new(13), 300, 0.25);
    let mut text = String::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        for v in t.v {
            text += &format!("v {} {} {}\n", v.x, v.y, v.z);
        }
        text += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    let p = dir.join("soup.obj");
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `heatmap` on the CPU at W×H with `extra` options; returns the PNG and the JSON.
fn heatmap(mesh: &Path, out: &Path, extra: &[&str]) -> (image::RgbImage, serde_json::Value) {
    let mut args = vec![
        "heatmap",
        mesh.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "24",
        "--height",
        "18",
        "--device",
        "cpu",
        "--json",
    ];
    args.extend_from_slice(extra);
    let run = lancer(&args);
    assert!(
        run.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json = serde_json::from_slice(&run.stdout).unwrap();
    (image::open(out).unwrap().to_rgb8(), json)
}

/// Per-pixel statistics from the library, as the heatmap should count them: the primary
/// rays' own, or their shadow rays' (None where the primary ray missed).
fn library_stats(mesh: &Path, layout: LayoutKind, shadow: bool) -> Vec<Option<RayStats>> {
    let mesh = lancer::mesh::load_mesh(mesh).unwrap();
    let device = Device::cpu();
    let options = TracerOptions {
        layout: Some(layout),
        stats: true,
        ..TracerOptions::default()
    };
    let mut tracer = Tracer::new(&device, &mesh, &options).unwrap();
    let primary = Camera::default_view(&mesh.bounds(), W, H).primary_rays();
    let result = tracer.trace(&primary, Query::Closest).unwrap();
    if !shadow {
        return result.stats.unwrap().into_iter().map(Some).collect();
    }
    let rays = shadow_rays(&primary, &result.hits, default_light(&mesh.bounds()));
    let mut stats = tracer
        .trace(&rays, Query::Any)
        .unwrap()
        .stats
        .unwrap()
        .into_iter();
    let per_pixel: Vec<_> = (result.hits.iter())
        .map(|h| if h.is_hit() { stats.next() } else { None })
        .collect();
    assert!(stats.next().is_none(), "one shadow ray a hit");
    per_pixel
}

/// The map's pixels (the top-left W×H of the PNG), row by row.
fn map_pixels(img: &image::RgbImage) -> Vec<[u8; 3]> {
    assert!(img.width() >= W && img.height() >= H);
    (0..H)
        .flat_map(|y| (0..W).map(move |x| img.get_pixel(x, y).0))
        .collect()
}

/// The colour the map must give `count` on a scale of `max`.
fn ramp(count: u32, max: u32) -> [u8; 3] {
    heat_ramp(count.min(max) as f32 / max as f32)
}

/// Checks every map pixel against the ramp of its library count (or the no-ray grey), and
/// the saturated pixels the JSON reports.
fn check_map(img: &image::RgbImage, json: &serde_json::Value, counts: &[Option<u32>], max: u32) {
    let pixels = map_pixels(img);
    assert_eq!(pixels.len(), counts.len());
    for (i, (p, c)) in pixels.iter().zip(counts).enumerate() {
        let want = c.map_or(NO_RAY, |c| ramp(c, max));
        assert_eq!(*p, want, "pixel {i}: count {c:?}, scale {max}");
    }
    let saturated = counts.iter().flatten().filter(|&&c| c >= max).count();
    assert_eq!(json["saturated"].as_u64(), Some(saturated as u64), "{json}");
    assert_eq!(json["scale"].as_u64(), Some(max as u64), "{json}");
}

#[test]
fn fixed_scale_pixels_are_the_ramp_of_the_library_counts_nodes_and_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let obj = soup_obj(dir.path());
    let stats = library_stats(&obj, CPU_LAYOUT, false);
    let mut maps = Vec::new();
    for (name, field) in [
        ("nodes", (|s: &RayStats| s.nodes) as fn(&RayStats) -> u32),
        ("triangles", |s: &RayStats| s.tris),
    ] {
        let counts: Vec<Option<u32>> = stats.iter().map(|s| s.as_ref().map(field)).collect();
        let top = counts.iter().flatten().copied().max().unwrap();
        // Half the largest count: some pixels saturate, others do not.
        let max = (top / 2).max(1);
        let out = dir.path().join(format!("{name}.png"));
        let (img, json) = heatmap(&obj, &out, &["--count", name, "--max", &max.to_string()]);
        check_map(&img, &json, &counts, max);
        assert!(json["saturated"].as_u64().unwrap() > 0, "{json}");
        assert!(counts.iter().flatten().any(|&c| c > 0 && c < max));
        assert_eq!(json["max"].as_u64(), Some(top as u64));
        maps.push(map_pixels(&img));
    }
    assert_ne!(maps[0], maps[1], "triangle and node maps are the same");
}

#[test]
fn two_layouts_drawn_with_one_max_share_the_scale() {
    let dir = tempfile::tempdir().unwrap();
    let obj = soup_obj(dir.path());
    let layouts = [LayoutKind::DfsSign, LayoutKind::Bvh4];
    let counts: Vec<Vec<Option<u32>>> = layouts
        .iter()
        .map(|&l| {
            let s = library_stats(&obj, l, false);
            s.iter().map(|s| s.map(|s| s.nodes)).collect()
        })
        .collect();
    let tops: Vec<u32> = (counts.iter())
        .map(|c| c.iter().flatten().copied().max().unwrap())
        .collect();
    assert_ne!(
        tops[0], tops[1],
        "the layouts' own scales would be the same"
    );
    let max = tops[0].max(tops[1]);
    let maps: Vec<Vec<[u8; 3]>> = layouts
        .iter()
        .zip(&counts)
        .map(|(l, c)| {
            let out = dir.path().join(format!("{}.png", l.name()));
            let args = ["--layout", l.name(), "--max", &max.to_string()];
            let (img, json) = heatmap(&obj, &out, &args);
            check_map(&img, &json, c, max);
            map_pixels(&img)
        })
        .collect();
    let mut equal = 0;
    for i in 0..maps[0].len() {
        if counts[0][i] == counts[1][i] {
            assert_eq!(
                maps[0][i], maps[1][i],
                "pixel {i}: equal counts, other colours"
            );
            equal += 1;
        }
    }
    assert!(equal > 0, "no pixel with equal counts to compare");
}

#[test]
fn shadow_maps_count_shadow_rays_and_grey_out_primary_misses() {
    let dir = tempfile::tempdir().unwrap();
    let obj = soup_obj(dir.path());
    let shadow = library_stats(&obj, CPU_LAYOUT, true);
    let counts: Vec<Option<u32>> = shadow.iter().map(|s| s.map(|s| s.nodes)).collect();
    let misses = counts.iter().filter(|c| c.is_none()).count();
    assert!(misses > 0 && misses < counts.len(), "{misses} misses");
    let max = counts.iter().flatten().copied().max().unwrap();
    let arg = max.to_string();
    let (img, json) = heatmap(
        &obj,
        &dir.path().join("s.png"),
        &["--rays", "shadow", "--max", &arg],
    );
    check_map(&img, &json, &counts, max);
    assert_eq!(
        json["traced"].as_u64(),
        Some((counts.len() - misses) as u64)
    );
    assert_eq!(json["rays"], "shadow");
    let (primary, _) = heatmap(&obj, &dir.path().join("p.png"), &["--max", &arg]);
    assert_ne!(
        map_pixels(&primary),
        map_pixels(&img),
        "shadow map = primary map"
    );
    // The no-ray grey is never a count's colour.
    assert!((0..=max).all(|c| ramp(c, max) != NO_RAY));
}

#[test]
fn the_colour_bar_is_below_the_map_and_no_bar_leaves_the_map_alone() {
    let dir = tempfile::tempdir().unwrap();
    let obj = soup_obj(dir.path());
    let (bar, _) = heatmap(&obj, &dir.path().join("bar.png"), &["--rays", "shadow"]);
    let (raw, _) = heatmap(
        &obj,
        &dir.path().join("raw.png"),
        &["--rays", "shadow", "--no-bar"],
    );
    assert_eq!((raw.width(), raw.height()), (W, H));
    assert!(
        bar.width() >= W && bar.height() > H,
        "{}×{}",
        bar.width(),
        bar.height()
    );
    assert_eq!(map_pixels(&bar), map_pixels(&raw));
    // Below the map: the ramp's ends, the grey swatch and dark text.
    let below: Vec<[u8; 3]> = (H..bar.height())
        .flat_map(|y| (0..bar.width()).map(move |x| (x, y)))
        .map(|(x, y)| bar.get_pixel(x, y).0)
        .collect();
    for c in [heat_ramp(0.0), heat_ramp(1.0), NO_RAY] {
        assert!(below.contains(&c), "{c:?} is not in the bar");
    }
    let ink = below.iter().filter(|p| p.iter().all(|&v| v < 60)).count();
    assert!(ink > 100, "{ink} dark pixels: no text?");
}

#[test]
fn a_zero_max_is_refused_and_subgroup_mode_falls_back_on_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let obj = soup_obj(dir.path());
    let out = dir.path().join("zero.png");
    let run = lancer(&[
        "heatmap",
        obj.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--max",
        "0",
    ]);
    assert_eq!(
        run.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(!out.exists());
    let (_, json) = heatmap(&obj, &dir.path().join("sg.png"), &["--mode", "subgroup"]);
    assert_eq!(json["mode"], "per-ray", "{json}");
}
