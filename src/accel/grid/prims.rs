//! The triangles a grid holds, in a compact local order: cells reference local indices, and
//! each local triangle keeps its original (file-order) index for hits and the tie rule. The
//! local order is the Morton (Z-curve) order of the centroids, so the triangles of one cell
//! and of its neighbours lie close together in memory.

use glam::DVec3;

use crate::geometry::{Aabb, Triangle};
use crate::mesh::Mesh;

/// The included triangles of a mesh, in index order.
#[derive(Clone, Debug, Default)]
pub(crate) struct Prims {
    /// The triangles, by local index.
    pub tris: Vec<Triangle>,
    /// Original index of each local triangle.
    pub prims: Vec<u32>,
    /// Bounds of the triangles.
    pub bounds: Aabb,
}

impl Prims {
    /// The mesh's included triangles, in Morton order.
    pub fn new(mesh: &Mesh) -> Prims {
        let mut prims = mesh.included();
        let bounds = prims.iter().fold(Aabb::EMPTY, |b, &i| {
            b.union(mesh.triangles[i as usize].bbox())
        });
        if !prims.is_empty() {
            let (lo, ext) = (
                bounds.lo,
                bounds.extent().max(glam::Vec3::splat(f32::MIN_POSITIVE)),
            );
            let code = |i: u32| {
                let t = &mesh.triangles[i as usize];
                let c = ((t.v[0] + t.v[1] + t.v[2]) / 3.0 - lo) / ext;
                let q = |x: f32| ((x.clamp(0.0, 1.0) * 1023.0) as u32).min(1023);
                morton(q(c.x), q(c.y), q(c.z))
            };
            // Stable on equal codes: the index order.
            prims.sort_by_cached_key(|&i| code(i));
        }
        let tris: Vec<Triangle> = prims.iter().map(|&i| mesh.triangles[i as usize]).collect();
        Prims {
            tris,
            prims,
            bounds,
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// The triangles in f64, for binning.
    pub fn to_f64(&self) -> Vec<[DVec3; 3]> {
        self.tris
            .iter()
            .map(|t| t.v.map(|p| p.as_dvec3()))
            .collect()
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        (self.tris.len() * (std::mem::size_of::<Triangle>() + 4)) as u64
    }

    /// The box grids are laid over: the triangles' bounds in f64, grown on every side by
    /// twice the scene margin (so a hit the f32 test finds just outside the bounds still lies
    /// in a cell), and that margin. None when there are no triangles.
    pub fn grid_box(&self) -> Option<(DVec3, DVec3, f64)> {
        if self.tris.is_empty() {
            return None;
        }
        let (lo, hi) = (self.bounds.lo.as_dvec3(), self.bounds.hi.as_dvec3());
        let diag = (hi - lo).length();
        // Never zero: a flat or tiny mesh still gets a box with volume (f64 has the range).
        let scale = diag.max(lo.abs().max(hi.abs()).max_element() * 1e-12);
        let m = (scale * super::frame::MARGIN_SCENE).max(1e-300);
        Some((lo - 2.0 * m, hi + 2.0 * m, m))
    }
}

/// The 30-bit Morton code of three 10-bit coordinates.
fn morton(x: u32, y: u32, z: u32) -> u32 {
    let spread = |mut v: u32| {
        v &= 0x3ff;
        v = (v | (v << 16)) & 0x0300_00ff;
        v = (v | (v << 8)) & 0x0300_f00f;
        v = (v | (v << 4)) & 0x030c_30c3;
        (v | (v << 2)) & 0x0924_9249
    };
    spread(x) | (spread(y) << 1) | (spread(z) << 2)
}
