//! `lancer::bench::heatmap::run` in process, on the CPU at 16×16: its counts are the
//! library tracer's own statistics (primary and shadow rays), every pixel is the heat ramp
//! of its count (or the no-ray grey), and the report serialises to `heatmap --json`'s keys.

mod common;

use lancer::bench::heatmap::{run, Count, HeatmapConfig, Rays, NO_RAY};
use lancer::camera::Camera;
use lancer::render::heat_ramp;
use lancer::trace::defaults::CPU_LAYOUT;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{Device, Mesh, Query, RayStats, Tracer, TracerOptions};

const W: u32 = 16;
const H: u32 = 16;

/// A random soup: some rays miss, the rest do varied work.
fn soup() -> Mesh {
    common::soup(&mut common::Rng::new(7), 120, 0.3)
}

/// The tracer's per-pixel statistics, primary or shadow (None where the primary missed).
fn library_stats(mesh: &Mesh, shadow: bool) -> Vec<Option<RayStats>> {
    let options = TracerOptions {
        layout: Some(CPU_LAYOUT),
        stats: true,
        ..TracerOptions::default()
    };
    let device = Device::cpu();
    let mut tracer = Tracer::new(&device, mesh, &options).unwrap();
    let primary = Camera::default_view(&mesh.bounds(), W, H).primary_rays();
    let result = tracer.trace(&primary, Query::Closest).unwrap();
    if !shadow {
        return result.stats.unwrap().into_iter().map(Some).collect();
    }
    let rays = shadow_rays(&primary, &result.hits, default_light(&mesh.bounds()));
    let mut stats = (tracer.trace(&rays, Query::Any).unwrap().stats.unwrap()).into_iter();
    (result.hits.iter())
        .map(|h| if h.is_hit() { stats.next() } else { None })
        .collect()
}

fn config(count: Count, rays: Rays, max: Option<u32>) -> HeatmapConfig {
    HeatmapConfig {
        count,
        rays,
        max,
        ..HeatmapConfig::new(W, H, CPU_LAYOUT, "map.png")
    }
}

#[test]
fn counts_are_the_tracers_and_pixels_their_ramp() {
    let mesh = soup();
    let device = Device::cpu();
    for rays in [Rays::Primary, Rays::Shadow] {
        let stats = library_stats(&mesh, rays == Rays::Shadow);
        for count in [Count::Nodes, Count::Triangles] {
            let want: Vec<Option<u32>> = stats
                .iter()
                .map(|s| s.as_ref().map(|s| count.of(s)))
                .collect();
            let top = want.iter().flatten().copied().max().unwrap();
            for max in [None, Some((top / 2).max(1))] {
                let map = run(&device, &mesh, &config(count, rays, max)).unwrap();
                assert_eq!(map.counts, want, "{rays:?} {count:?}");
                let scale = max.unwrap_or(top);
                assert_eq!(map.report.scale, scale);
                assert_eq!(map.report.max, top);
                assert_eq!(map.report.traced, want.iter().flatten().count());
                let saturated = want.iter().flatten().filter(|&&c| c >= scale).count();
                assert_eq!(map.report.saturated, max.map(|_| saturated));
                assert_eq!((map.image.width(), map.image.height()), (W, H), "no bar");
                for (p, c) in map.image.pixels().zip(&want) {
                    let colour =
                        c.map_or(NO_RAY, |c| heat_ramp(c.min(scale) as f32 / scale as f32));
                    assert_eq!(p.0, colour, "{rays:?} {count:?} count {c:?} scale {scale}");
                }
            }
        }
    }
    // The soup leaves misses: shadow maps have grey pixels, and say so.
    let map = run(&device, &mesh, &config(Count::Nodes, Rays::Shadow, None)).unwrap();
    assert!(map.counts.iter().any(Option::is_none));
    assert!(map.text().iter().any(|l| l.contains("no shadow ray")));
}

#[test]
fn the_colour_bar_keeps_the_map_in_the_corner() {
    let mesh = soup();
    let device = Device::cpu();
    let plain = run(&device, &mesh, &config(Count::Nodes, Rays::Primary, None)).unwrap();
    let barred = HeatmapConfig {
        bar: true,
        ..config(Count::Nodes, Rays::Primary, None)
    };
    let barred = run(&device, &mesh, &barred).unwrap();
    assert!(barred.image.height() > H && barred.image.width() >= W);
    for (x, y, p) in plain.image.enumerate_pixels() {
        assert_eq!(barred.image.get_pixel(x, y), p);
    }
}

#[test]
fn the_report_has_the_json_keys() {
    let map = run(
        &Device::cpu(),
        &soup(),
        &config(Count::Triangles, Rays::Shadow, Some(3)),
    )
    .unwrap();
    let json = serde_json::to_value(&map.report).unwrap();
    let keys: Vec<&str> = json
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let mut want = vec![
        "structure",
        "layout",
        "mode",
        "rays",
        "counted",
        "width",
        "height",
        "traced",
        "mean",
        "max",
        "scale",
        "saturated",
        "out",
    ];
    let mut got = keys.clone();
    got.sort();
    want.sort();
    assert_eq!(got, want);
    assert_eq!(json["rays"], "shadow");
    assert_eq!(json["counted"], "triangles");
    assert_eq!(json["scale"], 3);
    assert_eq!(json["out"], "map.png");
    assert_eq!(json["layout"], CPU_LAYOUT.name());
    assert_eq!(
        (json["width"].as_u64(), json["height"].as_u64()),
        (Some(16), Some(16))
    );
    assert!(json["saturated"].is_u64());
}
