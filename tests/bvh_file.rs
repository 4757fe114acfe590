//! BVH files (`lancer::accel::bvh::layouts::bvh_file`, `build --out`, `--bvh`): every layout survives a
//! round trip byte for byte and traces bit for bit as the freshly flattened layout, on the
//! CPU twin and on the GPU; every corruption is refused with its own message, never a
//! panic, boxes moved off their triangles and leaves sharing a triangle included (with the
//! checksum recomputed); `check` judges a file's answers by the f64 oracle; the CLI traces
//! a file as it traces the mesh.

mod common;

use std::path::Path;
use std::process::Command;
use std::sync::Arc;

use common::{gpu_device, random_rays, soup, Rng};
use lancer::accel::bvh;
use lancer::accel::bvh::layouts::bvh_file::{self, HEADER_BYTES};
use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::GpuForm;
use lancer::mesh::Mesh;
use lancer::trace::check::{self, CheckConfig, CheckRays, ORACLE_MODE};
use lancer::{Device, Hit, Query, Ray, Tracer, TracerOptions, Vec3};

fn bits(hits: &[Hit]) -> Vec<[u32; 4]> {
    hits.iter()
        .map(|h| [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()])
        .collect()
}

/// Hits of `layout` on `device`, closest then any.
fn hits(device: &Device, layout: Arc<dyn GpuForm>, rays: &[Ray]) -> Vec<Vec<[u32; 4]>> {
    let mut t = Tracer::with_layout(device, layout, &TracerOptions::default()).unwrap();
    [Query::Closest, Query::Any]
        .into_iter()
        .map(|q| bits(&t.trace(rays, q).unwrap().hits))
        .collect()
}

fn scene() -> (Mesh, Vec<Ray>) {
    let mut rng = Rng::new(71);
    let mesh = soup(&mut rng, 2000, 0.1);
    let rays = random_rays(&mut rng, 1500, &mesh);
    (mesh, rays)
}

#[test]
fn every_layout_round_trips_and_traces_bit_for_bit_on_the_cpu_and_the_gpu() {
    let (mesh, rays) = scene();
    let tree = bvh::build(&mesh, &Default::default());
    let gpu = gpu_device();
    let dir = tempfile::tempdir().unwrap();
    for &kind in LayoutKind::ALL {
        let fresh: Arc<dyn GpuForm> = flatten(kind, &tree, &mesh).into();
        let bytes = bvh_file::encode(fresh.as_ref(), mesh.len()).unwrap();
        let path = dir.path().join(format!("{kind}.bvh"));
        bvh_file::write(&path, fresh.as_ref(), mesh.len()).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            bytes,
            "{kind}: write = encode"
        );
        let file = bvh_file::read(&path).unwrap();
        assert_eq!(file.kind, kind);
        assert_eq!(file.mesh_triangles, mesh.len() as u64);
        file.check_mesh(&path, &mesh).unwrap();
        let again = bvh_file::encode(file.layout.as_ref(), mesh.len()).unwrap();
        assert!(again == bytes, "{kind}: the round trip changed the bytes");
        assert_eq!(file.layout.bounds(), fresh.bounds(), "{kind}");
        assert_eq!(file.layout.name(), kind.name());
        for device in [&Device::cpu(), gpu] {
            let want = hits(device, fresh.clone(), &rays);
            let got = hits(device, file.layout.clone(), &rays);
            assert!(want[0].iter().any(|h| h[1] != u32::MAX), "{kind}: no hits");
            assert!(
                want == got,
                "{kind} on {device}: the file traces differently"
            );
        }
    }
}

/// Recomputes the checksum after an edit, so the edit reaches the check it targets.
fn reseal(bytes: &mut [u8]) {
    let mut h = crc32fast::Hasher::new();
    h.update(&bytes[..80]);
    h.update(&bytes[HEADER_BYTES..]);
    let crc = h.finalize();
    bytes[80..84].copy_from_slice(&crc.to_le_bytes());
}

/// The error decoding `bytes` gives; it must name the file, contain `want` and be exit
/// code 2.
fn refused(what: &str, bytes: &[u8], want: &str) {
    let name = Path::new("corrupt.bvh");
    let e = match bvh_file::decode(name, bytes) {
        Ok(_) => panic!("{what}: accepted"),
        Err(e) => e,
    };
    let msg = e.to_string();
    assert!(msg.starts_with("corrupt.bvh: "), "{what}: {msg}");
    assert!(msg.contains(want), "{what}: {msg}");
    assert_eq!(e.exit_code(), 2, "{what}");
    println!("{what}: {msg}");
}

/// Offset in the payload of a child index of the root node, per layout (dfs-sign: the
/// second child; threaded: the root's skip index; bvh2-wide-node: the header's root
/// reference; cwbvh: child_base; bvh4 and bvh8: slot 0's child, after six planes of W
/// floats).
fn root_child_index(kind: LayoutKind) -> usize {
    match kind {
        LayoutKind::DfsSign
        | LayoutKind::DfsDistance
        | LayoutKind::Bvh2WideNode
        | LayoutKind::Threaded => 12,
        LayoutKind::Cwbvh => 16,
        LayoutKind::Bvh4 => 6 * 4 * 4,
        LayoutKind::Bvh8 => 6 * 8 * 4,
    }
}

#[test]
fn every_corruption_is_refused_with_its_own_message() {
    let (mesh, _) = scene();
    let tree = bvh::build(&mesh, &Default::default());
    for &kind in LayoutKind::ALL {
        let layout = flatten(kind, &tree, &mesh);
        let good = bvh_file::encode(layout.as_ref(), mesh.len()).unwrap();
        bvh_file::decode(Path::new("good.bvh"), &good).unwrap();
        let len = good.len();
        let nodes = layout.arrays().nodes.len();
        let edit = |f: &dyn Fn(&mut Vec<u8>), seal: bool| {
            let mut b = good.clone();
            f(&mut b);
            if seal {
                reseal(&mut b);
            }
            b
        };
        for cut in [
            0,
            7,
            40,
            HEADER_BYTES - 1,
            HEADER_BYTES,
            HEADER_BYTES + nodes,
            len - 1,
        ] {
            refused(&format!("{kind} cut at {cut}"), &good[..cut], "truncated");
        }
        refused(
            &format!("{kind} one byte more"),
            &[&good[..], &[0]].concat(),
            "1 bytes follow",
        );
        for at in [HEADER_BYTES, HEADER_BYTES + nodes / 2, len - 1] {
            let b = edit(&|b| b[at] ^= 0x10, false);
            refused(&format!("{kind} byte {at} flipped"), &b, "checksum");
        }
        refused(
            &format!("{kind} a count flipped"),
            &edit(&|b| b[40] ^= 1, false),
            "its header says",
        );
        refused(
            &format!("{kind} magic"),
            &edit(&|b| b[0] = b'X', false),
            "not a lancer BVH file",
        );
        refused(
            &format!("{kind} version"),
            &edit(&|b| b[8] = 2, false),
            "version 2",
        );
        refused(
            &format!("{kind} layout"),
            &edit(
                &|b| b[16..32].copy_from_slice(b"bvh16\0\0\0\0\0\0\0\0\0\0\0"),
                true,
            ),
            "unknown layout \"bvh16\"",
        );
        refused(
            &format!("{kind} counts that overflow"),
            &edit(
                &|b| b[32..40].copy_from_slice(&u64::MAX.to_le_bytes()),
                true,
            ),
            "overflow",
        );
        // Counts that agree with the length but split the arrays elsewhere.
        let shifted = edit(
            &|b| {
                let n = (nodes + 48) as u64;
                b[32..40].copy_from_slice(&n.to_le_bytes());
                let t = (len - HEADER_BYTES - nodes - 48) as u64 / 48;
                b[40..48].copy_from_slice(&t.to_le_bytes());
            },
            true,
        );
        refused(
            &format!("{kind} arrays split elsewhere"),
            &shifted,
            "invalid",
        );
        let at = HEADER_BYTES + root_child_index(kind);
        let bad_index = edit(
            &|b| b[at..at + 4].copy_from_slice(&0x7fff_0000u32.to_le_bytes()),
            true,
        );
        refused(
            &format!("{kind} a node index out of range"),
            &bad_index,
            &format!("invalid {kind} arrays"),
        );
        let bad_prim = edit(
            &|b| {
                let p = HEADER_BYTES + nodes + 12;
                b[p..p + 4].copy_from_slice(&(mesh.len() as u32).to_le_bytes());
            },
            true,
        );
        refused(&format!("{kind} a triangle index"), &bad_prim, "index 2000");
        refused(
            &format!("{kind} record size"),
            &edit(&|b| b[12] ^= 0x40, true),
            "nodes are",
        );
        refused(
            &format!("{kind} root box"),
            &edit(
                &|b| b[56..60].copy_from_slice(&(-1e9f32).to_le_bytes()),
                true,
            ),
            "root box",
        );
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

fn put_f32(b: &mut [u8], at: usize, v: f32) {
    put_u32(b, at, v.to_bits());
}

/// Where a box of an inner node lies in the node array, per layout: (offset of its low x,
/// of its high x, what the error names). dfs-sign, dfs-distance and threaded: node 1 (the
/// root's first child; in threaded, copy 0's); bvh2-wide-node: record 1 (the root's) slot
/// 0; bvh4 and bvh8: node 0 slot 0 (planes of W floats). cwbvh has no stored box: see
/// `move_box`.
fn a_box(kind: LayoutKind) -> (usize, usize, &'static str) {
    match kind {
        LayoutKind::DfsSign | LayoutKind::DfsDistance | LayoutKind::Threaded => {
            (32, 48, "node 1: ")
        }
        LayoutKind::Bvh2WideNode => (64, 80, "node 1 slot 0: "),
        LayoutKind::Cwbvh => (0, 0, "node 0 slot "),
        LayoutKind::Bvh4 => (0, 3 * 4 * 4, "node 0 slot 0: "),
        LayoutKind::Bvh8 => (0, 3 * 8 * 4, "node 0 slot 0: "),
    }
}

/// Moves a box of `kind`'s node array (`nodes`, at the start of `b`) 1000 away along x;
/// for cwbvh, node 0's frame origin (all its children's boxes move).
fn move_box(kind: LayoutKind, b: &mut [u8]) {
    let (lo, hi, _) = a_box(kind);
    put_f32(b, lo, f32_at(b, lo) + 1000.0);
    if kind != LayoutKind::Cwbvh {
        put_f32(b, hi, f32_at(b, hi) + 1000.0);
    }
}

/// Shrinks the same box by the least there is: its high x one f32 step down (the box is
/// its triangles' exact bounds, so one vertex falls out); for cwbvh, whose boxes are
/// rounded outwards by up to a step, node 0's first occupied slot's x planes collapsed onto
/// its low plane.
fn shrink_box(kind: LayoutKind, b: &mut [u8]) {
    let (_, hi, _) = a_box(kind);
    if kind == LayoutKind::Cwbvh {
        // child_meta at 24, q_lo at 32 and q_hi at 56, 8 slots per axis.
        let s = (0..8).find(|&s| b[24 + s] != 0).unwrap();
        b[56 + s] = b[32 + s];
    } else {
        put_f32(b, hi, f32_at(b, hi).next_down());
    }
}

/// Makes two leaves of `kind`'s node array (`nodes`, at the start of `b`; `tris` triangles)
/// share triangles: a node whose first two children are leaves gets its second leaf's first
/// triangle set to the first leaf's (the walk meets the first leaf first).
fn share_triangles(kind: LayoutKind, b: &mut [u8], tris: u32) {
    // A leaf of `count` triangles may start at `first`.
    let fits = |first: u32, count: u32| count > 0 && first + count <= tris;
    match kind {
        LayoutKind::DfsSign | LayoutKind::DfsDistance | LayoutKind::Threaded => {
            // 32-byte nodes: a at 12, b at 28 (a leaf: b & 3 == 3, count b >> 2). An inner
            // node i whose first child i + 1 is a leaf has its second child at i + 2.
            let leaf = |b: &[u8], i: usize| u32_at(b, 32 * i + 28) & 3 == 3;
            let i = (0..b.len() / 32 - 2)
                .find(|&i| {
                    !leaf(b, i)
                        && leaf(b, i + 1)
                        && leaf(b, i + 2)
                        && fits(u32_at(b, 32 * i + 44), u32_at(b, 32 * i + 92) >> 2)
                })
                .unwrap();
            let first = u32_at(b, 32 * (i + 1) + 12);
            put_u32(b, 32 * (i + 2) + 12, first);
        }
        LayoutKind::Bvh2WideNode => {
            // 64-byte records: (a0 at 12, b0 at 28), (a1 at 44, b1 at 60); a leaf: b & 1.
            let r = (1..b.len() / 64)
                .find(|&r| {
                    let o = 64 * r;
                    u32_at(b, o + 28) & 1 == 1
                        && u32_at(b, o + 60) & 1 == 1
                        && fits(u32_at(b, o + 12), u32_at(b, o + 60) >> 1)
                })
                .unwrap();
            let first = u32_at(b, 64 * r + 12);
            put_u32(b, 64 * r + 44, first);
        }
        LayoutKind::Cwbvh => {
            // 80-byte nodes: tri_base at 20, imask at 15, child_meta at 24..32 (a leaf: the
            // imask bit clear, meta ≠ 0; offset in the low 5 bits, unary count above).
            let leaves = |b: &[u8], n: usize| -> Vec<usize> {
                (0..8)
                    .filter(|&s| b[80 * n + 15] >> s & 1 == 0 && b[80 * n + 24 + s] != 0)
                    .collect()
            };
            let (n, s1, s2) = (0..b.len() / 80)
                .find_map(|n| match leaves(b, n)[..] {
                    [s1, s2, ..] => Some((n, s1, s2)),
                    _ => None,
                })
                .unwrap();
            let (m1, m2) = (b[80 * n + 24 + s1], b[80 * n + 24 + s2]);
            b[80 * n + 24 + s2] = (m2 & !0x1f) | (m1 & 0x1f);
        }
        LayoutKind::Bvh4 | LayoutKind::Bvh8 => {
            // 32·W-byte nodes: child[k] at 24W + 4k, kind[k] at 28W + 4k (0: unused;
            // u32::MAX: inner; else a leaf's count).
            let w = if kind == LayoutKind::Bvh4 { 4 } else { 8 };
            let kind_of = |b: &[u8], n: usize, k: usize| u32_at(b, 32 * w * n + 28 * w + 4 * k);
            let child = |b: &[u8], n: usize, k: usize| u32_at(b, 32 * w * n + 24 * w + 4 * k);
            let (n, k1, k2) = (0..b.len() / (32 * w))
                .find_map(|n| {
                    let l: Vec<usize> = (0..w)
                        .filter(|&k| kind_of(b, n, k) != 0 && kind_of(b, n, k) != u32::MAX)
                        .collect();
                    match l[..] {
                        [k1, k2, ..] if fits(child(b, n, k1), kind_of(b, n, k2)) => {
                            Some((n, k1, k2))
                        }
                        _ => None,
                    }
                })
                .unwrap();
            let first = child(b, n, k1);
            put_u32(b, 32 * w * n + 24 * w + 4 * k2, first);
        }
    }
}

#[test]
fn boxes_moved_or_shrunk_and_shared_triangles_are_refused_though_the_checksum_is_valid() {
    let (mesh, _) = scene();
    let tree = bvh::build(&mesh, &Default::default());
    for &kind in LayoutKind::ALL {
        let layout = flatten(kind, &tree, &mesh);
        let good = bvh_file::encode(layout.as_ref(), mesh.len()).unwrap();
        let nodes = layout.arrays().nodes.len();
        let tampered = |f: &dyn Fn(&mut [u8])| {
            let mut b = good.clone();
            f(&mut b[HEADER_BYTES..HEADER_BYTES + nodes]);
            assert_ne!(b, good, "{kind}: the edit changed nothing");
            reseal(&mut b);
            b
        };
        let (_, _, names) = a_box(kind);
        let moved = tampered(&|b| move_box(kind, b));
        refused(&format!("{kind} a box moved"), &moved, names);
        refused(
            &format!("{kind} a box moved"),
            &moved,
            &format!("invalid {kind} arrays: "),
        );
        refused(&format!("{kind} a box moved"), &moved, "outside the box");
        let shrunk = tampered(&|b| shrink_box(kind, b));
        refused(&format!("{kind} a box shrunk"), &shrunk, names);
        refused(&format!("{kind} a box shrunk"), &shrunk, "outside the box");
        let shared = tampered(&|b| share_triangles(kind, b, mesh.len() as u32));
        refused(
            &format!("{kind} shared triangles"),
            &shared,
            "in two leaves",
        );
    }
}

/// A file whose arrays pass every check but whose triangles are not the mesh's (each
/// shrunk to half its size about its centroid, the tree built over them, so every box holds
/// its triangles), given to `check` as the mesh's file without `check_mesh`: its CPU twin
/// and GPU kernel agree on every answer, and the oracle rows find the answers the shrinking
/// changed wrong. The mesh's own file passes them.
#[test]
fn check_judges_a_files_answers_by_the_oracle_though_twin_and_kernel_agree() {
    let (mesh, rays) = scene();
    let shrunk = Mesh::from_triangles(
        (mesh.triangles.iter())
            .map(|t| {
                let c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
                let v = t.v.map(|v: Vec3| c + (v - c) * 0.5);
                lancer::geometry::Triangle::new(v[0], v[1], v[2])
            })
            .collect(),
    );
    for &kind in LayoutKind::ALL {
        for (what, built_from, good) in [
            ("the mesh's file", &mesh, true),
            ("a shrunk file", &shrunk, false),
        ] {
            let tree = bvh::build(built_from, &Default::default());
            let file = bvh_file::BvhFile {
                kind,
                layout: flatten(kind, &tree, built_from).into(),
                mesh_triangles: mesh.len() as u64,
            };
            let config = CheckConfig {
                rays: CheckRays::Given {
                    name: "random".into(),
                    rays: rays.clone(),
                },
                layouts: Vec::new(),
                mode: Some(lancer::TraversalMode::PerRay),
                build: Default::default(),
                bvh: Some(file),
                memory: Default::default(),
                robustness: Default::default(),
            };
            let report = check::run(gpu_device(), &mesh, &config, |_| {}).unwrap();
            let oracle: Vec<_> = (report.rows.iter())
                .filter(|r| r.mode == ORACLE_MODE)
                .collect();
            let queries: Vec<&str> = oracle.iter().map(|r| r.query).collect();
            assert_eq!(queries, ["closest", "any"], "{kind} {what}");
            for r in &report.rows {
                assert_eq!(
                    r.layout,
                    if r.layout == "driver" {
                        "driver"
                    } else {
                        kind.name()
                    }
                );
                assert_eq!(
                    r.agree + r.genuine_ties + r.disagree,
                    r.count,
                    "{kind} {what}: {r:?}"
                );
                if r.mode != ORACLE_MODE && r.layout != "driver" {
                    assert_eq!(
                        r.disagree, 0,
                        "{kind} {what}: twin and kernel differ: {r:?}"
                    );
                }
            }
            let wrong: usize = oracle.iter().map(|r| r.disagree).sum();
            if good {
                assert_eq!(report.disagree, 0, "{kind} {what}");
                assert_eq!(oracle[0].identical, rays.len(), "{kind} {what}");
            } else {
                // Rays that hit the mesh near a triangle's edge miss the shrunk one.
                let closest = oracle[0];
                assert!(closest.disagree > 50, "{kind} {what}: {closest:?}");
                assert!(report.disagree >= wrong, "{kind} {what}");
                let lines = closest.disagreement_lines();
                assert!(
                    lines[0].contains(&format!("{kind} oracle random ray"))
                        && lines[0].contains("built here")
                        && lines[0].contains(", file "),
                    "{}",
                    lines[0]
                );
                println!("{kind} {what}: {wrong} wrong answers, e.g.\n{}", lines[0]);
            }
        }
    }
}

#[test]
fn check_mesh_refuses_a_file_that_leaves_out_a_mesh_triangle() {
    let (mesh, _) = scene();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.bvh");
    // Built from the mesh with triangle 7 collapsed (so out of its BVH): every leaf
    // triangle is the mesh's, vertex for vertex, but triangle 7 is in no leaf.
    let mut tris = mesh.triangles.clone();
    tris[7].v[2] = tris[7].v[0];
    let without = Mesh::from_triangles(tris);
    let tree = bvh::build(&without, &Default::default());
    for &kind in LayoutKind::ALL {
        let layout = flatten(kind, &tree, &without);
        bvh_file::write(&path, layout.as_ref(), mesh.len()).unwrap();
        let file = bvh_file::read(&path).unwrap();
        let e = file.check_mesh(&path, &mesh).unwrap_err().to_string();
        assert!(
            e.contains("the mesh's triangle 7 is in none of its leaves"),
            "{e}"
        );
        file.check_mesh(&path, &without).unwrap();
    }
    // A triangle record overwritten with its neighbour in the same leaf (checksum
    // recomputed): the layout is valid (its boxes hold their triangles, every record is in
    // one leaf; a triangle may be in two, as spatial splits make), but another triangle is
    // in none.
    let layout = flatten(
        LayoutKind::DfsSign,
        &bvh::build(&mesh, &Default::default()),
        &mesh,
    );
    let mut b = bvh_file::encode(layout.as_ref(), mesh.len()).unwrap();
    let nodes = layout.arrays().nodes;
    // 32-byte nodes: a leaf has b & 3 == 3, first triangle a (at 12), count b >> 2.
    let first = (0..nodes.len() / 32)
        .map(|i| (u32_at(nodes, 32 * i + 12), u32_at(nodes, 32 * i + 28)))
        .find(|&(_, b)| b & 3 == 3 && b >> 2 >= 2)
        .map(|(a, _)| a as usize)
        .unwrap();
    let at = HEADER_BYTES + nodes.len() + 48 * first;
    let (record, next) = (&b[at..at + 48], &b[at + 48..at + 96]);
    let (lost, twice) = (u32_at(record, 12), u32_at(next, 12));
    b.copy_within(at + 48..at + 96, at);
    reseal(&mut b);
    let file = bvh_file::decode(&path, &b).unwrap();
    let e = file.check_mesh(&path, &mesh).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "the mesh's triangle {lost} is in none of its leaves"
        )),
        "{e} (triangle {twice} is in two)"
    );
}

#[test]
fn mutated_files_with_valid_checksums_are_refused_or_trace_without_a_panic() {
    let (mesh, rays) = scene();
    let rays = &rays[..200];
    let tree = bvh::build(&mesh, &Default::default());
    let mut rng = Rng::new(5);
    let (mut accepted, mut refused) = (0, 0);
    for &kind in LayoutKind::ALL {
        let good = bvh_file::encode(flatten(kind, &tree, &mesh).as_ref(), mesh.len()).unwrap();
        let mut on_gpu = 0;
        for _ in 0..300 {
            let mut b = good.clone();
            // One to three words of the payload (nodes mostly: they come first) set to a
            // random value, or a small one (indices, counts, tags).
            for _ in 0..1 + rng.u64() % 3 {
                let words = (b.len() - HEADER_BYTES) / 4;
                let at = HEADER_BYTES + 4 * (rng.u64() as usize % (words / 2 + 1));
                let v = match rng.u64() % 3 {
                    0 => rng.u64() as u32,
                    1 => (rng.u64() % 64) as u32,
                    _ => {
                        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
                            ^ 1 << (rng.u64() % 32)
                    }
                };
                b[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
            reseal(&mut b);
            let Ok(file) = bvh_file::decode(Path::new("m.bvh"), &b) else {
                refused += 1;
                continue;
            };
            accepted += 1;
            hits(&Device::cpu(), file.layout.clone(), rays);
            if on_gpu < 3 {
                on_gpu += 1;
                hits(gpu_device(), file.layout, rays);
            }
        }
    }
    println!("{accepted} mutated files accepted and traced, {refused} refused");
    assert!(accepted > 0 && refused > 0);
}

#[test]
fn a_file_is_refused_with_a_mesh_it_was_not_built_from_and_on_disk_before_reading() {
    let (mesh, _) = scene();
    let layout = flatten(
        LayoutKind::DfsSign,
        &bvh::build(&mesh, &Default::default()),
        &mesh,
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.bvh");
    bvh_file::write(&path, layout.as_ref(), mesh.len()).unwrap();
    let file = bvh_file::read(&path).unwrap();
    let mut other = mesh.clone();
    other.triangles[5].v[1].x += 0.25;
    let e = file.check_mesh(&path, &other).unwrap_err().to_string();
    assert!(e.contains("not the mesh's triangle 5"), "{e}");
    other.triangles.pop();
    let e = file.check_mesh(&path, &other).unwrap_err().to_string();
    assert!(e.contains("built from a mesh of 2000 triangles"), "{e}");
    // A file whose header claims more than is there: refused from its length, unread.
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let e = bvh_file::read(&path).err().unwrap().to_string();
    assert!(e.contains("truncated"), "{e}");
    std::fs::write(&path, &bytes[..20]).unwrap();
    let e = bvh_file::read(&path).err().unwrap().to_string();
    assert!(e.contains("truncated: 20 bytes"), "{e}");
}

fn lancer(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = lancer(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {err}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn the_cli_traces_a_bvh_file_as_it_traces_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let (rays, bvh, hits) = (p("r.rays"), p("m.bvh"), p("c.hits"));
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-box.obj");
    ok(&["rays", mesh, "-o", &rays, "--width", "24", "--height", "24"]);
    let trace = |extra: &[&str]| {
        let args = [
            "trace", mesh, "--rays", &rays, "-o", &hits, "--device", "cpu",
        ];
        lancer(&[&args[..], extra].concat())
    };
    for layout in ["dfs-sign", "cwbvh"] {
        let json = ok(&[
            "build",
            mesh,
            "--layout",
            layout,
            "--max-leaf",
            "2",
            "--out",
            &bvh,
            "--json",
        ]);
        assert!(json.contains(&format!("\"out\":{bvh:?}")), "{json}");
        let built = trace(&["--layout", layout, "--max-leaf", "2"]);
        assert!(built.status.success(), "{built:?}");
        let a = std::fs::read(&hits).unwrap();
        let read = trace(&["--bvh", &bvh, "--stats"]);
        assert!(read.status.success(), "{read:?}");
        let b = std::fs::read(&hits).unwrap();
        let said = String::from_utf8_lossy(&read.stdout);
        assert!(said.contains(&format!("layout    {layout}")), "{said}");
        assert!(
            a.len() == 24 * 24 * 16 && a == b,
            "{layout}: the hits differ"
        );
    }
    // Options the file contradicts.
    for extra in [
        ["--layout", "cwbvh"],
        ["--accel", "kdtree"],
        ["--max-leaf", "4"],
    ] {
        let out = trace(&[&["--bvh", &bvh][..], &extra].concat());
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
    }
    // A truncated file, and a file of another mesh.
    let bytes = std::fs::read(&bvh).unwrap();
    let cut = p("t.bvh");
    std::fs::write(&cut, &bytes[..bytes.len() - 1]).unwrap();
    let out = trace(&["--bvh", &cut]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("truncated"));
    let one = p("one.obj");
    std::fs::write(&one, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out = lancer(&["heatmap", &one, "-o", &p("h.png"), "--bvh", &bvh]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("built from a mesh of"));
    // heatmap and check take the file too (check on the GPU: lavapipe or any adapter).
    let small = ["--width", "8", "--height", "8", "--bvh", &bvh];
    ok(&[
        &["heatmap", mesh, "-o", &p("h.png"), "--device", "cpu"][..],
        &small,
    ]
    .concat());
    let check = ok(&[&["check", mesh, "--device", "gpu"][..], &small].concat());
    assert!(
        check.contains("| cwbvh |") && !check.contains("| dfs-sign |"),
        "{check}"
    );
}
