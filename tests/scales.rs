//! Every finite input is traced correctly or refused / left out with a count and the
//! supported range named: one triangle at scales from 1e-30 to 1e30 and translated far out,
//! from its default view, on the CPU twin and the GPU, judged by the f64 oracle.

mod common;

use std::path::Path;

use common::gpu_device;
use glam::Vec3;
use lancer::camera::Camera;
use lancer::geometry::Triangle;
use lancer::mesh::{check_usable, Mesh, TriStatus};
use lancer::trace::oracle::{judge, Verdict};
use lancer::{Device, Query, Tracer, TracerOptions};

/// What happened to one scale: traced (with its hit count) or refused (with the message).
fn trace_at(scale: f32, offset: f32) -> Result<usize, String> {
    let o = Vec3::splat(offset);
    let t = Triangle::new(o, o + Vec3::X * scale, o + Vec3::Y * scale);
    let mesh = Mesh::from_triangles(vec![t]);
    if let Some(s) = mesh.exclusion_summary() {
        if mesh.count(TriStatus::TooFar) > 0 {
            assert!(s.contains("1e11"), "{s}");
        }
    }
    check_usable(Path::new("tri.obj"), &mesh).map_err(|e| e.to_string())?;
    let rays = Camera::default_view(&mesh.bounds(), 24, 18).primary_rays();
    assert!(
        rays.iter().all(|r| r.is_valid()),
        "scale {scale:e} offset {offset:e}: the default view makes invalid rays"
    );
    let mut hits = 0;
    for device in [&Device::cpu(), gpu_device()] {
        let mut tracer = Tracer::new(device, &mesh, &TracerOptions::default()).unwrap();
        let result = tracer.trace(&rays, Query::Closest).unwrap();
        for (r, h) in rays.iter().zip(&result.hits) {
            if let Verdict::Wrong(w) = judge(&mesh, r, h) {
                panic!("scale {scale:e} offset {offset:e} on {device}: {w}");
            }
        }
        hits = result.hits.iter().filter(|h| h.is_hit()).count();
        assert!(
            hits > 0,
            "scale {scale:e} offset {offset:e} on {device}: no ray hits"
        );
    }
    Ok(hits)
}

#[test]
fn every_scale_is_traced_or_refused_with_the_range() {
    let mut traced = 0;
    for e in -30..=30 {
        let scale = 10f32.powi(e);
        for offset in [0.0, scale * 1e5, 1e5, 1e6] {
            match trace_at(scale, offset) {
                Ok(hits) => {
                    traced += 1;
                    println!("scale 1e{e} offset {offset:e}: {hits} hits, all judged right");
                }
                Err(msg) => {
                    println!("scale 1e{e} offset {offset:e}: refused: {msg}");
                    assert!(
                        msg.contains("1e-12") || msg.contains("no usable triangle"),
                        "scale 1e{e}: refusal names no range: {msg}"
                    );
                }
            }
        }
    }
    println!("{traced} cases traced, the rest refused with a reason");
    // The supported band (1e-12 … 1e11) is traced, not refused, near the origin and (for
    // triangles that f32 can still tell apart out there) far from it.
    for e in -12..=11 {
        assert!(trace_at(10f32.powi(e), 0.0).is_ok(), "scale 1e{e} refused");
    }
    for e in -1..=10 {
        assert!(
            trace_at(10f32.powi(e), 1e6).is_ok(),
            "scale 1e{e} at 1e6 refused"
        );
    }
}
