//! Meshes: triangles in file order from OBJ/MTL (tobj), PLY (ply-rs-bw) or glTF 2.0
//! (gltf), or from an application's own arrays ([`Mesh::from_indexed`]), each classified
//! (usable or why not).

mod format;
mod gltf;
mod gltf_animation;
mod gltf_check;
mod indexed;
mod instanced;
mod load;
mod mtl;
mod obj;
mod obj_bulk;
mod ply;
mod ply_binary;
mod ply_layout;

pub use format::{FileKind, KNOWN_EXTENSIONS};
pub use gltf::{
    load_gltf, load_gltf_instances, load_gltf_placed, read_gltf, GltfCamera, GltfImage, GltfLight,
    GltfLightKind, GltfLoaded, GltfMaterial, GltfPlaced, GltfScene, GltfTexture,
};
pub use gltf_animation::GltfAnimation;
pub use instanced::{Instance, InstanceSet, MAX_INSTANCED_TRIANGLES};
pub use load::{check_traceable, check_usable, load_mesh, warn_exclusions};
pub use obj::{load_obj, load_obj_scene, ObjScene};
pub use ply::{load_ply, load_ply_scene, PlyScene};

use glam::Vec3;

use crate::geometry::{Aabb, Triangle};

/// Why a triangle is (not) in the BVH.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TriStatus {
    /// Usable: it goes into the BVH.
    Ok,
    /// A vertex is NaN or infinite.
    NonFinite,
    /// Zero area in f32.
    Degenerate,
    /// A face index points at no vertex (placeholder keeps later indices in file order).
    OutOfRange,
    /// A vertex coordinate beyond ±[`MAX_COORD`](crate::limits::MAX_COORD), where f32
    /// intersection arithmetic overflows.
    TooFar,
}

/// Triangles in file order (index = the triangle index every API and file reports), with
/// the reason each excluded one stays out of the BVH.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// The triangles, by triangle index (NaN placeholders for faces with bad indices).
    pub triangles: Vec<Triangle>,
    /// Whether each triangle goes into the BVH, and why not; by triangle index.
    pub status: Vec<TriStatus>,
    /// Faces with fewer than 3 vertices: they have no triangle index.
    pub short_faces: usize,
    /// The files the mesh was read from (the OBJ and the MTL libraries it names); outputs
    /// may not overwrite them. Empty for meshes made in memory.
    pub sources: Vec<std::path::PathBuf>,
}

impl Mesh {
    /// A mesh from triangles, classifying each one.
    pub fn from_triangles(triangles: Vec<Triangle>) -> Mesh {
        let status = triangles.iter().map(classify).collect();
        Mesh {
            triangles,
            status,
            short_faces: 0,
            sources: Vec::new(),
        }
    }

    /// Number of triangles, excluded ones included.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the mesh has no triangles at all (not even excluded ones).
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Original indices of the triangles that go into the BVH (a triangle without a
    /// status, in a mesh whose arrays [`Mesh::check_arrays`] refuses, stays out).
    pub fn included(&self) -> Vec<u32> {
        (0..self.triangles.len().min(self.status.len()) as u32)
            .filter(|&i| self.status[i as usize] == TriStatus::Ok)
            .collect()
    }

    /// Refuses a mesh made in code whose arrays disagree: one status per triangle.
    pub fn check_arrays(&self) -> crate::Result<()> {
        if self.status.len() != self.triangles.len() {
            return Err(crate::Error::Usage(format!(
                "a mesh of {} triangles with {} statuses: give one status per triangle \
                 (Mesh::from_triangles classifies them)",
                self.triangles.len(),
                self.status.len()
            )));
        }
        Ok(())
    }

    /// Number of triangles with status `s`.
    pub fn count(&self, s: TriStatus) -> usize {
        use rayon::prelude::*;
        self.status.par_iter().filter(|&&x| x == s).count()
    }

    /// One line naming what was left out, or None when nothing was.
    pub fn exclusion_summary(&self) -> Option<String> {
        exclusion_summary(self.exclusions())
    }

    /// What was left out, by cause, in [`EXCLUSION_CAUSES`]' order.
    pub fn exclusions(&self) -> [u64; 5] {
        [
            self.count(TriStatus::NonFinite) as u64,
            self.count(TriStatus::Degenerate) as u64,
            self.count(TriStatus::OutOfRange) as u64,
            self.short_faces as u64,
            self.count(TriStatus::TooFar) as u64,
        ]
    }

    /// Bounds of the included triangles.
    pub fn bounds(&self) -> Aabb {
        use rayon::prelude::*;
        (self.triangles.par_iter().zip(&self.status))
            .filter(|(_, s)| **s == TriStatus::Ok)
            .fold(|| Aabb::EMPTY, |b, (t, _)| b.union(t.bbox()))
            .reduce(|| Aabb::EMPTY, Aabb::union)
    }
}

pub(crate) fn classify(t: &Triangle) -> TriStatus {
    if !t.is_finite() {
        TriStatus::NonFinite
    } else if t
        .v
        .iter()
        .any(|p| p.abs().max_element() > crate::limits::MAX_COORD)
    {
        TriStatus::TooFar
    } else if t.is_degenerate() {
        TriStatus::Degenerate
    } else {
        TriStatus::Ok
    }
}

/// A triangle's corner normals packed ([`pack_unit`](crate::geometry::pack_unit)), or
/// [`NO_NORMAL`](crate::geometry::NO_NORMAL) on every corner where one of them has no
/// direction (zero, NaN or infinite): such a triangle shades flat.
pub fn pack_corners(n: [Vec3; 3]) -> [u32; 3] {
    use crate::geometry::{pack_unit, NO_NORMAL};
    match n.map(pack_unit) {
        [Some(a), Some(b), Some(c)] => [a, b, c],
        _ => [NO_NORMAL; 3],
    }
}

/// Placeholder for a face that could not be resolved: keeps the numbering.
pub(crate) fn placeholder() -> Triangle {
    Triangle::new(Vec3::NAN, Vec3::NAN, Vec3::NAN)
}

/// Bytes a triangle costs from reading through the BVH build, for the memory checks up front.
pub(crate) const BYTES_PER_TRIANGLE: u128 = 256;

/// Refuses more triangles than lancer indexes or memory holds, before they are made.
pub(crate) fn check_triangle_count(path: &std::path::Path, tris: u128) -> crate::Result<()> {
    if tris >= u32::MAX as u128 / 2 {
        return Err(crate::Error::input(
            path,
            None,
            format!("{tris} triangles, more than lancer indexes: split the mesh"),
        ));
    }
    crate::limits::check_memory(
        &format!("{} ({tris} triangles)", path.display()),
        tris * BYTES_PER_TRIANGLE,
        "use a smaller mesh",
    )
}

/// The causes [`Mesh::exclusions`] counts, as [`exclusion_summary`] names them.
pub const EXCLUSION_CAUSES: [&str; 5] = [
    "with NaN/Inf vertices",
    "with zero area",
    "with out-of-range indices",
    "faces with fewer than 3 vertices",
    "with a coordinate beyond ±1e11 (the supported range)",
];

/// One line naming what was left out (counts by [`EXCLUSION_CAUSES`]), or None when
/// nothing was.
pub fn exclusion_summary(counts: [u64; 5]) -> Option<String> {
    let parts: Vec<String> = (counts.iter().zip(EXCLUSION_CAUSES))
        .filter(|(n, _)| **n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
    (!parts.is_empty()).then(|| format!("left out of the BVH: {}", parts.join(", ")))
}
