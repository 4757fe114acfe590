//! Hard cases for the spatial structures' tests (kd-tree, BIH, octree; CPU and GPU), the
//! layouts' and the kernels': shared edges and vertices, coincident triangles, trees as deep as the stack,
//! needles every split duplicates, invalid and extreme rays.

use glam::Vec3;
use lancer::accel::kdtree::{KdOptions, KdTree, MAX_KD_DEPTH};
use lancer::geometry::{Ray, Triangle};
use lancer::mesh::Mesh;

use super::{random_rays, soup, Rng};

/// An n×n grid of quads (two triangles each) in the plane z = 0 over [0, n·step]², with
/// irregular f32 coordinates, and its interior vertices and interior edge midpoints (on
/// shared edges, diagonals included): the plane whose shared edges and vertices rays
/// ([`edge_rays`]) must not leak through.
pub fn grid(n: usize, step: f32) -> (Mesh, Vec<Vec3>) {
    let p = |i: usize, j: usize| Vec3::new(i as f32 * step, j as f32 * step * 1.1, 0.0);
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            tris.push(Triangle::new(a, b, c));
            tris.push(Triangle::new(a, c, d));
        }
    }
    let mut targets = Vec::new();
    for i in 1..n {
        for j in 1..n {
            targets.push(p(i, j));
            targets.push(0.5 * (p(i, j) + p(i + 1, j + 1)));
            targets.push(0.5 * (p(i, j) + p(i + 1, j)));
            targets.push(0.5 * (p(i, j) + p(i, j + 1)));
        }
    }
    (Mesh::from_triangles(tris), targets)
}

/// Copies of one triangle (in z = const, over about [-0.9, 0.9]²) at four depths, 3 to 6
/// copies each, inserted at random indices among 400 random triangles: the nearest t is
/// shared by several indices, in leaves on both sides of split planes.
pub fn coincident_stacks(rng: &mut Rng) -> Mesh {
    let mut tris = soup(rng, 400, 0.1).triangles;
    let shape = [
        Vec3::new(-0.9, -0.9, 0.0),
        Vec3::new(0.9, -0.7, 0.0),
        Vec3::new(-0.6, 0.9, 0.0),
    ];
    let depths = [0.3f32, -0.2, 0.05, 0.7];
    for copy in 0..6 {
        for (s, &z) in depths.iter().enumerate() {
            if copy < 3 + s {
                let dz = Vec3::new(0.0, 0.0, z);
                tris.insert(
                    (rng.u64() as usize) % tris.len(),
                    Triangle::new(shape[0] + dz, shape[1] + dz, shape[2] + dz),
                );
            }
        }
    }
    Mesh::from_triangles(tris)
}

/// Triangles shrinking geometrically (to 1e-7) towards the origin along the diagonal, with
/// clutter: an SAH kd-tree with a high K_I keeps splitting towards the corner down to the
/// depth cap. [`shrinking_corner_by`] with ratio 0.85.
pub fn shrinking_corner(rng: &mut Rng) -> Mesh {
    shrinking_corner_by(rng, 0.85)
}

/// 300 random triangles and 300 triangles shrinking by `ratio` every third one towards the
/// origin along the diagonal (0.85: to 1e-7; the octree's 0.9: to 3e-5), which a structure
/// splitting small cells keeps splitting towards the corner down to its depth cap.
pub fn shrinking_corner_by(rng: &mut Rng, ratio: f32) -> Mesh {
    let mut tris = soup(rng, 300, 0.05).triangles;
    for i in 0..300 {
        let s = ratio.powi(i / 3);
        let c = Vec3::splat(s) + rng.vec3(-0.1, 0.1) * s;
        tris.push(Triangle::new(
            c,
            c + Vec3::new(0.3 * s, 0.0, 0.0),
            c + Vec3::new(0.0, 0.3 * s, 0.1 * s),
        ));
    }
    Mesh::from_triangles(tris)
}

/// Invalid rays (NaN, zero or infinite direction, empty interval, origin beyond
/// `limits::MAX_ORIGIN`): misses that visit nothing.
pub fn invalid_rays() -> Vec<Ray> {
    vec![
        Ray::new(Vec3::NAN, Vec3::X, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0), 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        Ray::new(Vec3::ZERO, Vec3::X, 0.0, f32::NAN),
        Ray::new(Vec3::splat(1e13), -Vec3::ONE, 0.0, 1e30),
        Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0), 0.0, 1.0),
        // Every component below limits::MIN_DIR.
        Ray::new(Vec3::ZERO, Vec3::new(1e-21, -1e-25, 1e-30), 0.0, f32::MAX),
    ]
}

/// Seven invalid rays at the origin, interval [0, 10] unless named: a NaN origin, a NaN,
/// zero or infinite direction, a NaN tmin or tmax, an empty interval [5, 1]. Every kernel
/// answers them as misses without traversing (tests/gpu_vs_cpu.rs, tests/subgroup.rs).
pub fn nan_zero_and_empty_rays() -> [Ray; 7] {
    let o = Vec3::ZERO;
    [
        Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X, 0.0, 10.0),
        Ray::new(o, Vec3::new(f32::NAN, 1.0, 0.0), 0.0, 10.0),
        Ray::new(o, Vec3::ZERO, 0.0, 10.0),
        Ray::new(o, Vec3::X, f32::NAN, 10.0),
        Ray::new(o, Vec3::X, 0.0, f32::NAN),
        Ray::new(o, Vec3::new(f32::INFINITY, 0.0, 0.0), 0.0, 10.0),
        Ray::new(o, Vec3::X, 5.0, 1.0),
    ]
}

/// `n` valid but extreme rays: origins up to 1e12 or down to 1e-30, directions of length
/// 1e-19 (just above `limits::MIN_DIR`) or 1e30, zero and tiny components, intervals from −3.4e38 or up to +∞.
pub fn extreme_rays(rng: &mut Rng, n: usize) -> Vec<Ray> {
    extreme_rays_up_to(rng, n, f32::INFINITY)
}

/// [`extreme_rays`] whose open intervals (every fifth ray, from 0) end at `far` (+∞ there;
/// f32::MAX in tests/layout_wide_bvh.rs) instead of 3.4e38.
pub fn extreme_rays_up_to(rng: &mut Rng, n: usize, far: f32) -> Vec<Ray> {
    let mut rays = Vec::new();
    for i in 0..n {
        let o = match i % 3 {
            0 => rng.vec3(-1e12, 1e12),
            1 => rng.vec3(-2.0, 2.0),
            _ => rng.vec3(-1.0, 1.0) * 1e-30,
        };
        let mut d = match i % 4 {
            0 => rng.dir() * 1e-19,
            1 => rng.dir() * 1e30,
            _ => rng.dir(),
        };
        if i % 7 == 0 {
            d.x = 0.0;
        }
        if i % 11 == 0 {
            d.y = -1e-35;
        }
        let (tmin, tmax) = match i % 5 {
            0 => (-3.4e38, 3.4e38),
            1 => (0.0, far),
            _ => (0.0, 3.4e38),
        };
        rays.push(Ray::new(o, d, tmin, tmax));
    }
    rays
}

/// 1500 random triangles and an 8×8 [`grid`] of quads at z = 0: split planes through
/// shared edges.
pub fn soup_on_a_grid(rng: &mut Rng) -> Mesh {
    let mut tris = soup(rng, 1500, 0.25).triangles;
    tris.extend(grid(8, 0.25).0.triangles);
    Mesh::from_triangles(tris)
}

/// `n` rays whose origins lie on split planes (`planes`: axis, position), inside or outside
/// the mesh's bounds: along an axis in the plane or across it, within the plane with the
/// axis component ±0, or axis-parallel from the crossing of two planes; a fifth with tmin
/// = −1.
pub fn split_plane_rays(rng: &mut Rng, mesh: &Mesh, planes: &[(usize, f32)], n: usize) -> Vec<Ray> {
    let b = mesh.bounds();
    let mut rays = Vec::new();
    for i in 0..n {
        let (axis, pos) = planes[rng.u64() as usize % planes.len()];
        // An origin on the plane, inside or outside the bounds.
        let mut o = b.lo + (b.hi - b.lo) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
        o += rng.vec3(-0.3, 0.3) * (i % 2) as f32;
        o[axis] = pos;
        let mut d = Vec3::ZERO;
        match i % 4 {
            // Along an axis in the plane, or across it.
            0 => d[(axis + 1 + (i / 4) % 2) % 3] = if rng.f32() < 0.5 { 1.0 } else { -1.0 },
            1 => d[axis] = if rng.f32() < 0.5 { 2.0 } else { -0.5 },
            // Within the plane, any direction; the axis component ±0.
            2 => {
                d = rng.dir();
                d[axis] = if i % 8 == 2 { 0.0 } else { -0.0 };
            }
            // Another axis-parallel direction, an origin on a second plane too.
            _ => {
                let (a2, p2) = planes[rng.u64() as usize % planes.len()];
                o[a2] = p2;
                d[rng.u64() as usize % 3] = 1.0;
            }
        }
        let tmin = if i % 5 == 0 { -1.0 } else { 0.0 };
        rays.push(Ray::new(o, d, tmin, 3.4e38));
    }
    rays
}

/// `n` rays at the [`coincident_stacks`], from straight above or from random points below.
pub fn stack_rays(rng: &mut Rng, n: usize) -> Vec<Ray> {
    (0..n)
        .map(|i| {
            let target = Vec3::new(rng.range(-0.6, 0.4), rng.range(-0.6, 0.4), 0.0);
            let o = if i % 3 == 0 {
                Vec3::new(target.x, target.y, 2.0)
            } else {
                Vec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), -2.0)
            };
            Ray::new(o, (target - o).normalize(), 0.0, 3.4e38)
        })
        .collect()
}

/// [`shrinking_corner`] (from `rng`) and its kd-tree at the depth cap: a high K_I (20) and
/// 200 levels asked for, more than [`MAX_KD_DEPTH`] allows; checks that the tree is deeper
/// than 40 levels and within the cap (what the CPU's and the GPU's stacks must hold).
pub fn kd_tree_at_the_depth_cap(rng: &mut Rng) -> (Mesh, KdTree) {
    let mesh = shrinking_corner(rng);
    let opts = KdOptions {
        max_depth: Some(200),
        intersection_cost: 20.0,
        ..KdOptions::default()
    };
    let tree = KdTree::build(&mesh, &opts).unwrap();
    let s = tree.stats();
    assert!(s.max_depth > 40 && s.max_depth <= MAX_KD_DEPTH, "{s:?}");
    (mesh, tree)
}

/// 1000 random rays through [`shrinking_corner`]'s mesh and 1000 at its small triangles
/// from every side, from nearby (at a distance like their size: from afar, f32 cannot aim
/// at a triangle 1e-15 across). [`corner_rays_by`] with ratio 0.85.
pub fn corner_rays(rng: &mut Rng, mesh: &Mesh) -> Vec<Ray> {
    corner_rays_by(rng, mesh, 0.85)
}

/// [`corner_rays`] at the triangles of [`shrinking_corner_by`] with the same `ratio`.
pub fn corner_rays_by(rng: &mut Rng, mesh: &Mesh, ratio: f32) -> Vec<Ray> {
    let mut rays = random_rays(rng, 1000, mesh);
    for i in 0..1000 {
        let s = ratio.powi((i % 300) / 3);
        let target = Vec3::splat(s * 1.05);
        let o = target + rng.dir() * 4.0 * s;
        rays.push(Ray::new(o, (target - o).normalize(), 0.0, 3.4e38));
    }
    rays
}

/// A triangle of size `0.1·a` centred near `c`.
pub fn small_at(c: Vec3, a: f32) -> Triangle {
    let s = 0.1 * a;
    Triangle::new(
        c - Vec3::new(s, s, 0.0),
        c + Vec3::new(s, 0.0, 0.3 * s),
        c + Vec3::new(0.0, s, -0.3 * s),
    )
}

/// The chain: per scale a = 2⁰ … 2⁻³³, three small triangles in [0, a]³, one beyond a/2 on
/// x, one on y, one on z, and nothing else there: the global heuristic halves its candidate
/// box on x, y, then z and splits off one triangle per halving, about 100 levels deep.
/// Their centres (for rays to aim at).
pub fn chain_centres() -> Vec<(Vec3, f32)> {
    let mut v = Vec::new();
    for m in 0..34 {
        let a = 0.5f32.powi(m);
        for k in 0..3 {
            let mut c = Vec3::splat(0.2 * a);
            c[k] = 0.75 * a;
            v.push((c, a));
        }
    }
    v
}

/// Clutter in [0, 1]³ (as many triangles again shrinking geometrically towards the origin,
/// to about 1e-7, as in tests/kdtree.rs) and the chain (the BIH's deep case,
/// tests/bih.rs and tests/bih_gpu.rs). The scene box starts at the origin,
/// so the global grid's lines close in on the chain.
pub fn corner_cascade(rng: &mut Rng) -> Mesh {
    let mut tris: Vec<Triangle> = soup(rng, 300, 0.05)
        .triangles
        .into_iter()
        .map(|t| Triangle {
            v: t.v.map(|p| p.abs()),
        })
        .collect();
    for i in 0..300 {
        let s = 0.85f32.powi(i / 3);
        tris.push(small_at(
            Vec3::splat(s) * (Vec3::ONE + rng.vec3(0.0, 0.2)),
            3.0 * s,
        ));
    }
    tris.extend(chain_centres().into_iter().map(|(c, a)| small_at(c, a)));
    Mesh::from_triangles(tris)
}

/// Rays at `targets` (the shared edges and vertices of a plane of triangles in z = 0 around
/// `centre`): two from above or below at random angles, and one straight down and one
/// straight up the z axis, each.
pub fn edge_rays(rng: &mut Rng, centre: Vec3, targets: &[Vec3]) -> Vec<Ray> {
    let mut rays = Vec::new();
    for &t in targets {
        for _ in 0..2 {
            let mut o = centre + rng.dir() * 20.0;
            o.z = if rng.f32() < 0.5 {
                -o.z.abs() - 1.0
            } else {
                o.z.abs() + 1.0
            };
            rays.push(Ray::new(o, (t - o).normalize(), 0.0, 3.4e38));
        }
        rays.push(Ray::new(t + Vec3::Z * 5.0, -Vec3::Z, 0.0, 3.4e38));
        rays.push(Ray::new(t - Vec3::Z * 5.0, Vec3::Z, 0.0, f32::INFINITY));
    }
    rays
}

/// `n` needles: thin triangles across the whole scene in random directions, which every
/// split duplicates (the spatial structures' duplicated references and memory caps).
pub fn needles(rng: &mut Rng, n: usize) -> Mesh {
    let tris = (0..n)
        .map(|_| {
            let a = rng.vec3(-1.0, 1.0);
            let b = -a + rng.vec3(-0.1, 0.1);
            Triangle::new(a, b, b + rng.vec3(-0.06, 0.06))
        })
        .collect();
    Mesh::from_triangles(tris)
}

/// An n×n height field of quads (two triangles each) over [0, 1]², z = 0.3·sin(0.37·i) along
/// x: many shared edges and vertices, not in one plane.
pub fn height_field(n: usize) -> Mesh {
    let p = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
        Vec3::new(x, y, 0.3 * (i as f32 * 0.37).sin())
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    Mesh::from_triangles(tris)
}
