//! The check and compare library in process (`lancer::trace::check`,
//! `lancer::trace::compare`, `lancer::render::compare_images`): what `lancer check` and
//! `lancer compare` print, without the command line. Every row of a check agrees on the
//! Cornell box, the report's counts add up, its JSON has the book's keys, and a tampered
//! answer is counted as a disagreement.

mod common;

use std::path::Path;

use common::gpu_device;
use lancer::mesh::{load_obj, Mesh};
use lancer::trace::check::{self, CheckConfig, CheckProgress, CheckRays, CheckRow, TABLE_HEADER};
use lancer::trace::compare::{compare_hits, count_agreement, HitsReport, T_ULPS};
use lancer::trace::files::view_ray_sets;
use lancer::{Device, Error, Hit, LayoutKind, Query, Tracer, TracerOptions, TraversalMode};

fn cornell() -> Mesh {
    load_obj(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.obj"))
        .expect("the Cornell box loads")
}

/// The keys of a JSON object.
fn keys(v: &serde_json::Value) -> Vec<&str> {
    let mut k: Vec<&str> = v.as_object().unwrap().keys().map(|s| s.as_str()).collect();
    k.sort();
    k
}

/// A row's counts add up: identical answers agree, and every ray is counted once.
fn assert_adds_up(row: &CheckRow) {
    if !row.ran {
        assert_eq!(
            (
                row.count,
                row.identical,
                row.agree,
                row.genuine_ties,
                row.disagree
            ),
            (0, 0, 0, 0, 0)
        );
        return;
    }
    assert!(row.identical <= row.agree, "{row:?}");
    assert_eq!(
        row.agree + row.genuine_ties + row.disagree,
        row.count,
        "{row:?}"
    );
    assert_eq!(
        row.first_disagreements.len(),
        row.disagree.min(3),
        "{row:?}"
    );
}

#[test]
fn a_check_needs_a_gpu() {
    let mesh = cornell();
    let err = check::run(&Device::cpu(), &mesh, &CheckConfig::view(16, 16), |_| {})
        .expect_err("a CPU device cannot be checked against itself");
    assert!(matches!(err, Error::Gpu(_)), "{err}");
}

#[test]
fn every_layout_agrees_on_the_gpu_and_the_report_adds_up() {
    let mesh = cornell();
    let config = CheckConfig::view(16, 16);
    let (mut started, mut seen) = (0, 0);
    let report = check::run(gpu_device(), &mesh, &config, |p| match p {
        CheckProgress::Started { adapter } => {
            assert!(!adapter.is_empty());
            started += 1;
        }
        CheckProgress::Row(row) => {
            assert_eq!(started, 1, "rows come after the start");
            assert_adds_up(row);
            seen += 1;
        }
    })
    .unwrap();
    assert_eq!(seen, report.rows.len());
    assert_eq!(report.disagree, 0, "{:#?}", report.rows);
    assert!(report.not_run.is_empty());
    assert_eq!(
        report.disagree,
        report.rows.iter().map(|r| r.disagree).sum::<usize>()
    );
    // Every layout in every mode that ran, on the three ray sets of the view; primary rays
    // are one a pixel.
    for kind in LayoutKind::ALL {
        let rows: Vec<&CheckRow> = (report.rows.iter())
            .filter(|r| r.layout == kind.name())
            .collect();
        let modes = TraversalMode::ALL.len();
        let ran = rows.iter().filter(|r| r.ran).count();
        let not_ran = rows.len() - ran;
        assert_eq!(ran + 3 * not_ran, 3 * modes, "{kind}: {rows:#?}");
        assert!(ran >= 3, "{kind}: the per-ray mode runs everywhere");
        for r in rows.iter().filter(|r| r.ran) {
            assert!(["primary", "shadow", "bounce"].contains(&r.rays.as_str()));
            let want = if r.rays == "shadow" { "any" } else { "closest" };
            assert_eq!(r.query, want);
            if r.rays == "primary" {
                assert_eq!(r.count, 256);
            }
        }
    }
    let driver = report.rows.iter().filter(|r| r.layout == "driver").count();
    assert_eq!(driver, if report.driver { 3 } else { 0 });
    // The table: the header and one line a row.
    let table = report.table();
    assert_eq!(table[..2], TABLE_HEADER.map(String::from));
    assert_eq!(table.len(), 2 + report.rows.len());
    assert!(table[2].starts_with(&format!("| {} | ", report.rows[0].layout)));
    // The JSON: the book's keys, and no more.
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(keys(&json), ["adapter", "disagree", "not_run", "rows"]);
    assert_eq!(
        keys(&json["rows"][0]),
        [
            "agree",
            "count",
            "disagree",
            "genuine_ties",
            "identical",
            "layout",
            "mode",
            "query",
            "ran",
            "rays"
        ]
    );
}

#[test]
fn given_rays_are_traced_for_both_queries_in_the_mode_asked_for() {
    let mesh = cornell();
    let cpu = Device::cpu();
    let reference = Tracer::new(&cpu, &mesh, &TracerOptions::default()).unwrap();
    let layout = reference.layout().unwrap().as_ref();
    let sets = view_ray_sets(&mesh, layout, 16, 16, &Default::default()).unwrap();
    let rays = sets[0].2.clone();
    let config = CheckConfig {
        rays: CheckRays::Given {
            name: "mine.rays".into(),
            rays,
        },
        layouts: vec![LayoutKind::DfsSign],
        mode: Some(TraversalMode::PerRay),
        ..CheckConfig::view(1, 1)
    };
    let report = check::run(gpu_device(), &mesh, &config, |_| {}).unwrap();
    let ours: Vec<&CheckRow> = (report.rows.iter())
        .filter(|r| r.layout != "driver")
        .collect();
    assert_eq!(ours.len(), 2, "{ours:#?}");
    for (row, query) in ours.iter().zip(["closest", "any"]) {
        assert_eq!((row.layout, row.mode), ("dfs-sign", "per-ray"));
        assert_eq!((row.rays.as_str(), row.query), ("mine.rays", query));
        assert_eq!(row.count, 256);
        assert_eq!(row.disagree, 0);
        assert_adds_up(row);
    }
    assert_eq!(report.disagree, 0);
}

#[test]
fn a_tampered_answer_is_a_disagreement() {
    let mesh = cornell();
    let cpu = Device::cpu();
    let mut tracer = Tracer::new(&cpu, &mesh, &TracerOptions::default()).unwrap();
    let layout = tracer.layout().unwrap().clone();
    let sets = view_ray_sets(&mesh, layout.as_ref(), 16, 16, &Default::default()).unwrap();
    let rays = &sets[0].2;
    let hits = tracer.trace(rays, Query::Closest).unwrap().hits;
    let i = hits
        .iter()
        .position(Hit::is_hit)
        .expect("the view sees the box");
    let mut tampered = hits.clone();
    tampered[i].t *= 0.5;
    tampered[i].prim = (hits[i].prim + 1) % mesh.triangles.len() as u32;

    let cmp = compare_hits(&mesh, rays, Query::Closest, &hits, &tampered);
    let row = CheckRow::ran(
        "dfs-sign",
        "per-ray",
        "primary",
        Query::Closest,
        rays.len(),
        &cmp,
    );
    assert_adds_up(&row);
    assert_eq!(row.disagree, 1);
    assert_eq!(row.identical, rays.len() - 1);
    assert_eq!(row.first_disagreements[0].ray, i);
    let lines = row.disagreement_lines();
    assert_eq!(lines.len(), 1);
    assert!(
        lines[0].starts_with(&format!("  dfs-sign per-ray primary ray {i}: CPU ")),
        "{}",
        lines[0]
    );
    assert!(lines[0].contains(", GPU "), "{}", lines[0]);
    assert!(row.markdown().ends_with("| 1 |"), "{}", row.markdown());
    assert!(row.markdown().contains("| Closest |"), "{}", row.markdown());

    // Without the oracle: counted as differing, and the report says so.
    let c = count_agreement(&hits, &tampered, T_ULPS);
    assert_eq!(
        (c.rays, c.identical, c.agree, c.differ()),
        (256, 255, 255, 1)
    );
    let r = serde_json::to_value(HitsReport::unjudged(&c)).unwrap();
    assert_eq!(
        keys(&r),
        [
            "agree",
            "disagree",
            "genuine_ties",
            "identical",
            "judged",
            "kind",
            "rays"
        ]
    );
    assert_eq!(
        (r["disagree"].as_u64(), r["genuine_ties"].is_null()),
        (Some(1), true)
    );
    let judged = serde_json::to_value(HitsReport::judged(rays.len(), &cmp)).unwrap();
    assert_eq!(
        (judged["disagree"].as_u64(), judged["judged"].as_bool()),
        (Some(1), Some(true))
    );
}

#[test]
fn hit_counts_without_the_oracle() {
    let hit = Hit {
        t: 1.0,
        prim: 3,
        u: 0.25,
        v: 0.5,
    };
    let near = Hit {
        t: f32::from_bits(1.0f32.to_bits() + 2),
        ..hit
    };
    let far = Hit {
        t: f32::from_bits(1.0f32.to_bits() + 3),
        ..hit
    };
    let uv = Hit { u: 0.5, ..hit };
    let miss = Hit::miss(5.0);
    let other_miss = Hit::miss(7.0);
    let a = [hit, hit, hit, hit, miss];
    let b = [hit, near, far, uv, other_miss];
    let c = count_agreement(&a, &b, T_ULPS);
    // hit = hit (identical); near within 2 ulp; uv the same triangle and t; misses agree.
    assert_eq!((c.rays, c.identical, c.agree, c.differ()), (5, 1, 4, 1));
    let c = count_agreement(&a, &b, 3);
    assert_eq!(c.differ(), 0);
    // Different lengths compare up to the shorter.
    assert_eq!(count_agreement(&a[..2], &b, T_ULPS).rays, 2);
}

#[test]
fn an_image_difference_reports_the_book_keys() {
    use lancer::render::compare_images;
    use lancer::{Image, Vec3};
    let a = Image {
        width: 2,
        height: 2,
        pixels: vec![Vec3::ZERO; 4],
        tile: None,
    };
    let mut b = a.clone();
    b.pixels[1] = Vec3::new(0.5, 0.0, 0.0);
    let same = compare_images(&a, &a, 0.01).unwrap();
    assert_eq!(same.summary(), "2×2 pixels: bit-identical");
    assert!(!same.differ(0.0));
    let d = compare_images(&a, &b, 0.01).unwrap();
    assert!(d.differ(0.0) && !d.differ(25.0));
    assert!(
        d.summary().starts_with("2×2 pixels: 1 differ (25.000 %)"),
        "{}",
        d.summary()
    );
    let r = serde_json::to_value(d.report(10.0, Some(Path::new("d.png")))).unwrap();
    assert_eq!(
        keys(&r),
        [
            "differ",
            "differing",
            "height",
            "kind",
            "max",
            "mean",
            "out",
            "over",
            "over_percent",
            "rmse",
            "threshold",
            "tolerance",
            "width"
        ]
    );
    assert_eq!(
        (r["kind"].as_str(), r["differ"].as_bool()),
        (Some("images"), Some(true))
    );
    assert_eq!(r["out"].as_str(), Some("d.png"));
    // An image whose pixels do not fill its size is refused, not read past its end.
    let short = Image {
        pixels: Vec::new(),
        ..a.clone()
    };
    for (x, y) in [(&short, &a), (&a, &short)] {
        let e = compare_images(x, y, 0.01).unwrap_err().to_string();
        assert!(e.contains("0 pixels for a 2×2 image"), "{e}");
    }
}

#[test]
fn choices_by_name() {
    use lancer::trace::check::{layout_choice, mode_choice, LayoutChoice, ModeChoice};
    assert_eq!(
        layout_choice("all").unwrap().kinds(),
        LayoutKind::ALL.to_vec()
    );
    for &k in LayoutKind::ALL {
        assert!(matches!(layout_choice(k.name()), Ok(LayoutChoice::One(x)) if x == k));
    }
    let err = layout_choice("bvh2").unwrap_err();
    assert!(
        err.starts_with("unknown layout \"bvh2\": use all or one of dfs-sign, "),
        "{err}"
    );
    assert_eq!(mode_choice("all").unwrap().mode(), None);
    assert!(matches!(
        mode_choice("subgroup"),
        Ok(ModeChoice::One(TraversalMode::Subgroup))
    ));
    assert_eq!(
        mode_choice("x").unwrap_err(),
        "unknown mode \"x\": use all or one of per-ray, subgroup"
    );
}
