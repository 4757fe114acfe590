//! The tie rule — equal t goes to the smaller original triangle index, also when the
//! equal-t triangle sits in a node visited later — on the CPU twin of every layout and on
//! the GPU in both BVH memories, with coincident triangles: the case where traversal order
//! would otherwise decide. CPU ≡ GPU ≡ the f64 oracle.

mod common;

use common::{gpu_device, soup, Rng};
use glam::Vec3;
use lancer::camera::Camera;
use lancer::geometry::{
    intersect_watertight, prune_bound, Hit, Ray, Triangle, WatertightRay, FAR_WIDEN,
};
use lancer::gpu::BvhMemory;
use lancer::mesh::Mesh;
use lancer::trace::oracle::{self, judge_any, Verdict};
use lancer::{Device, LayoutKind, Query, Tracer, TracerOptions};
use proptest::prelude::*;

/// `copies` copies of one triangle spanning [0, size]² in the plane z = `z`, appended.
fn stack(tris: &mut Vec<Triangle>, copies: usize, z: f32, size: f32) {
    let t = Triangle::new(
        Vec3::new(0.0, 0.0, z),
        Vec3::new(size, 0.0, z),
        Vec3::new(0.0, size, z),
    );
    tris.extend(std::iter::repeat_n(t, copies));
}

/// Traces on the CPU twin of every layout and on the GPU in both memories; returns every
/// device's hits, labelled.
fn everywhere(mesh: &Mesh, rays: &[Ray], query: Query) -> Vec<(String, Vec<Hit>)> {
    let mut out = Vec::new();
    let cpu = Device::cpu();
    for &layout in LayoutKind::ALL {
        let o = TracerOptions {
            layout: Some(layout),
            ..TracerOptions::default()
        };
        let hits = Tracer::new(&cpu, mesh, &o)
            .unwrap()
            .trace(rays, query)
            .unwrap();
        out.push((format!("cpu {layout}"), hits.hits));
        for memory in [BvhMemory::Buffers, BvhMemory::Textures] {
            let o = TracerOptions { memory, ..o };
            let g = Tracer::new(gpu_device(), mesh, &o).unwrap();
            let hits = { g }.trace(rays, query).unwrap();
            out.push((format!("gpu {layout} {memory:?}"), hits.hits));
        }
    }
    out
}

/// Every device returns the smallest index at the nearest t (the oracle's answer) for every
/// ray whose answer is not an edge case, and all devices agree bit for bit.
fn check_closest(name: &str, mesh: &Mesh, rays: &[Ray]) {
    let all = everywhere(mesh, rays, Query::Closest);
    let (first_name, first) = &all[0];
    let mut judged = 0;
    let truths = oracle::Truths::new(mesh, rays);
    for (i, h) in first.iter().enumerate() {
        let want = truths.closest(i);
        if let Some((_, prim)) = want {
            // The oracle's prim is the smallest index among the hits at the nearest t; the
            // tracer must return exactly it unless the ray grazes an edge.
            if h.prim != prim {
                let v = truths.judge(i, h);
                assert!(
                    matches!(v, Verdict::Tie(_)) && !matches!(v, Verdict::Tie("two hits at equal t")),
                    "{name}: ray {i}: {first_name} reports {} but the oracle's smallest index at the nearest t is {prim} ({v:?})",
                    h.prim
                );
            } else {
                judged += 1;
            }
        }
    }
    for (dev, hits) in &all[1..] {
        let differ = (hits.iter().zip(first))
            .filter(|(a, b)| bytemuck::bytes_of(*a) != bytemuck::bytes_of(*b))
            .count();
        if let Some((a, b)) = hits
            .iter()
            .zip(first)
            .find(|(a, b)| bytemuck::bytes_of(*a) != bytemuck::bytes_of(*b))
        {
            eprintln!("{dev}: {a:?} vs {b:?}");
        }
        assert_eq!(
            differ, 0,
            "{name}: {dev} differs from {first_name} on {differ} rays"
        );
    }
    println!(
        "{name}: {judged} rays give the oracle's triangle on {} devices",
        all.len()
    );
}

#[test]
fn a_hundred_copies_report_the_first() {
    // The report: 100 copies of one triangle, the default view at 32×24; 21 rays said 87.
    let mut tris = Vec::new();
    stack(&mut tris, 100, 0.0, 1.0);
    let mesh = Mesh::from_triangles(tris);
    let rays = Camera::default_view(&mesh.bounds(), 32, 24).primary_rays();
    for (dev, hits) in everywhere(&mesh, &rays, Query::Closest) {
        let wrong: Vec<u32> = hits
            .iter()
            .filter(|h| h.is_hit() && h.prim != 0)
            .map(|h| h.prim)
            .collect();
        let n = hits.iter().filter(|h| h.is_hit()).count();
        assert!(n > 100, "{dev}: only {n} hits");
        assert!(
            wrong.is_empty(),
            "{dev}: {} of {n} hits report {:?}, not 0",
            wrong.len(),
            &wrong[..wrong.len().min(5)]
        );
    }
    check_closest("100 copies", &mesh, &rays);
}

#[test]
fn fifty_thousand_copies_agree_bit_for_bit() {
    let mut tris = Vec::new();
    stack(&mut tris, 50_000, 0.0, 1.0);
    let mesh = Mesh::from_triangles(tris);
    let rays = Camera::default_view(&mesh.bounds(), 64, 48).primary_rays();
    check_closest("50,000 copies", &mesh, &rays);
    // Any hit: the first hit in the layout's traversal order, the same on every device (the
    // CPU twin, both GPU memories), and a real one. Layouts order children differently, so
    // two layouts may return different copies.
    let all = everywhere(&mesh, &rays, Query::Any);
    for (dev, hits) in &all {
        let layout = dev.split(' ').nth(1).unwrap_or_default();
        let twin = format!("cpu {layout}");
        let (_, want) = all.iter().find(|(d, _)| *d == twin).unwrap();
        assert_eq!(hits, want, "{dev} any-hit differs from {twin}");
        if *dev == twin {
            for (r, h) in rays.iter().zip(hits) {
                assert!(
                    !matches!(judge_any(&mesh, r, h), Verdict::Wrong(_)),
                    "{dev}"
                );
            }
        }
    }
}

#[test]
fn cutting_boxes_at_exactly_the_best_t_would_lose_ties() {
    // Why the traversals cut boxes against prune_bound(best t) and not best t itself: the
    // box entry and the triangle's t round differently, so the box holding an equal-t
    // triangle can compute an entry beyond the best t. Shown here on the copies' own box.
    let mut tris = Vec::new();
    stack(&mut tris, 1, 0.0, 1.0);
    let mesh = Mesh::from_triangles(tris);
    let tri = mesh.triangles[0];
    let bbox = tri.bbox();
    let rays = Camera::default_view(&mesh.bounds(), 64, 48).primary_rays();
    let (mut exact_cuts, mut slack_cuts, mut hits) = (0, 0, 0);
    for r in &rays {
        let wr = WatertightRay::new(r.dir);
        let Some((t, _, _)) = intersect_watertight(&tri, r.origin, &wr, r.tmin, r.tmax) else {
            continue;
        };
        hits += 1;
        let inv = r.inv_dir();
        exact_cuts += !bbox.slab_hit(r.origin, inv, r.tmin, t, FAR_WIDEN) as usize;
        slack_cuts += !bbox.slab_hit(r.origin, inv, r.tmin, prune_bound(t), FAR_WIDEN) as usize;
    }
    println!(
        "{hits} hits: the box is cut at the exact t for {exact_cuts}, with slack for {slack_cuts}"
    );
    assert!(exact_cuts > 0, "no ray shows the rounding the slack is for");
    assert_eq!(slack_cuts, 0);
    // And the oracle agrees on what the answer is: 100 hits, the first copy wins.
    let mut tris = Vec::new();
    stack(&mut tris, 100, 0.0, 1.0);
    let mesh = Mesh::from_triangles(tris);
    let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, 0.0, 10.0);
    assert_eq!(oracle::closest(&mesh, &r).map(|h| h.1), Some(0));
    assert_eq!(oracle::all_hits(&mesh, &r).len(), 100);
}

/// Meshes of coincident stacks at several depths, mixed with a random soup.
fn stacks_mesh(seed: u64, copies: &[usize], soup_n: usize) -> Mesh {
    let mut rng = Rng::new(seed);
    let mut tris = soup(&mut rng, soup_n, 0.2).triangles;
    for (i, &k) in copies.iter().enumerate() {
        stack(&mut tris, k, -0.5 + 0.3 * i as f32, 0.8 + 0.1 * i as f32);
    }
    Mesh::from_triangles(tris)
}

fn rays_for(mesh: &Mesh, seed: u64) -> Vec<Ray> {
    let mut rays = Camera::default_view(&mesh.bounds(), 40, 30).primary_rays();
    rays.extend(common::random_rays(&mut Rng::new(seed), 800, mesh));
    // Straight through every stack, from both sides.
    for i in 0..20 {
        let p = Vec3::new(0.03 + 0.02 * i as f32, 0.05 + 0.01 * i as f32, 0.0);
        rays.push(Ray::new(p + Vec3::Z * 3.0, Vec3::NEG_Z, 0.0, 100.0));
        rays.push(Ray::new(p - Vec3::Z * 3.0, Vec3::Z, 0.0, 100.0));
    }
    rays
}

proptest! {
    #![proptest_config(common::proptest_config("ties", 6))]
    #[test]
    fn coincident_stacks_at_several_depths(seed in any::<u64>(),
                                           copies in proptest::collection::vec(2usize..3000, 1..4),
                                           soup_n in 0usize..400) {
        let mesh = stacks_mesh(seed, &copies, soup_n);
        check_closest(&format!("stacks {copies:?} + {soup_n}"), &mesh, &rays_for(&mesh, seed));
    }
}

#[test]
fn two_hundred_thousand_copies() {
    let mesh = stacks_mesh(9, &[200_000, 7], 100);
    check_closest("200,000 copies", &mesh, &rays_for(&mesh, 9));
}
