//! The triangle array every layout shares: triangles in leaf order, each with its original
//! index (WGSL `Tri` and `load_tri` in `shaders/lib/traversal.wgsl`).

use rayon::prelude::*;

use crate::accel::bvh::Bvh;
use crate::geometry::Triangle;
use crate::mesh::Mesh;

/// One triangle, 48 bytes: three vertices, the original index in v0's slot w.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LeafTri {
    /// Vertex 0.
    pub v0: [f32; 3],
    /// Original (file-order) triangle index.
    pub prim: u32,
    /// Vertex 1.
    pub v1: [f32; 3],
    /// Padding (zero).
    pub pad1: u32,
    /// Vertex 2.
    pub v2: [f32; 3],
    /// Padding (zero).
    pub pad2: u32,
}

impl LeafTri {
    /// Triangle `prim` with vertices `v`.
    pub fn new(v: [glam::Vec3; 3], prim: u32) -> LeafTri {
        LeafTri {
            v0: v[0].into(),
            prim,
            v1: v[1].into(),
            pad1: 0,
            v2: v[2].into(),
            pad2: 0,
        }
    }

    /// The triangle's vertices.
    #[inline(always)]
    pub fn triangle(&self) -> Triangle {
        Triangle::new(self.v0.into(), self.v1.into(), self.v2.into())
    }

    /// The triangles of `bvh`'s leaves, in leaf order (in parallel).
    pub fn gather(bvh: &Bvh, mesh: &Mesh) -> Vec<LeafTri> {
        bvh.order
            .par_iter()
            .map(|&id| LeafTri::new(mesh.triangles[id as usize].v, id))
            .collect()
    }
}
