//! Meshes from an application's own arrays: vertex positions and index triples, validated
//! exactly as the file readers validate theirs.

use std::path::Path;

use glam::Vec3;

use super::{classify, placeholder, Mesh, TriStatus, BYTES_PER_TRIANGLE};
use crate::error::{Error, Result};
use crate::geometry::Triangle;

/// What errors and warnings about a mesh from arrays name in place of a file.
const SOURCE: &str = "Mesh::from_indexed";

impl Mesh {
    /// A mesh from an application's own arrays: vertex `positions` and one `[a, b, c]`
    /// index triple per triangle (indices into `positions`, counted from 0). Triangle `i`
    /// is `indices[i]`: hits report that index.
    ///
    /// `positions` may be `glam::Vec3`s ([`lancer::Vec3`](crate::Vec3)) or `[f32; 3]`s.
    /// Indices stored flat, three per triangle, become triples without a copy with
    /// `let (triples, _) = flat.as_chunks::<3>();` (or `bytemuck::cast_slice`).
    ///
    /// Each triangle is validated as the OBJ, PLY and glTF readers validate theirs: one
    /// whose index names no position keeps its place (and its index) as an
    /// [`OutOfRange`](TriStatus::OutOfRange) placeholder; NaN or infinite vertices, zero
    /// area and coordinates beyond ±[`MAX_COORD`](crate::limits::MAX_COORD) are
    /// classified too ([`Mesh::status`]). Those triangles stay out of the BVH, are never
    /// hit, and are counted in a `log` warning ([`Mesh::exclusion_summary`]).
    ///
    /// Like [`load_mesh`](super::load_mesh), it refuses a mesh with no usable triangle or
    /// one too small to trace ([`MIN_EXTENT`](crate::limits::MIN_EXTENT) across), and more
    /// triangles than lancer indexes or memory holds; it never panics on bad indices.
    ///
    /// ```
    /// use lancer::{Mesh, Vec3};
    /// // A unit square in the z = 0 plane, as two triangles, and a third whose index 9
    /// // names no vertex: it keeps triangle index 2 and stays out of the BVH.
    /// let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    /// let mesh = Mesh::from_indexed(&positions, &[[0, 1, 2], [0, 2, 3], [0, 2, 9]])?;
    /// assert_eq!(mesh.included(), vec![0, 1]);
    /// # Ok::<(), lancer::Error>(())
    /// ```
    pub fn from_indexed<P: Copy + Into<Vec3>>(
        positions: &[P],
        indices: &[[u32; 3]],
    ) -> Result<Mesh> {
        let tris = indices.len() as u128;
        if tris >= u32::MAX as u128 / 2 {
            return Err(Error::Usage(format!(
                "{SOURCE}: {tris} triangles, more than lancer indexes: split the mesh"
            )));
        }
        crate::limits::check_memory(
            &format!("{SOURCE} ({tris} triangles)"),
            tris * BYTES_PER_TRIANGLE,
            "use a smaller mesh",
        )?;
        let vertex = |i: u32| {
            let p = *positions.get(usize::try_from(i).ok()?)?;
            Some(p.into())
        };
        let (triangles, status) = indices.iter().map(|c| resolve(c.map(vertex))).unzip();
        let mesh = Mesh {
            triangles,
            status,
            short_faces: 0,
            sources: Vec::new(),
        };
        super::check_usable(Path::new(SOURCE), &mesh)?;
        Ok(mesh)
    }
}

/// A triangle from its three corners, classified; a placeholder where a corner names no
/// vertex (what every reader does with a face whose index points nowhere).
pub(crate) fn resolve(corners: [Option<Vec3>; 3]) -> (Triangle, TriStatus) {
    match corners {
        [Some(a), Some(b), Some(c)] => {
            let t = Triangle::new(a, b, c);
            (t, classify(&t))
        }
        _ => (placeholder(), TriStatus::OutOfRange),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    const SQUARE: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    #[test]
    fn keeps_order_and_counts_drops() {
        let mut positions: Vec<Vec3> = SQUARE.iter().map(|&p| p.into()).collect();
        positions.push(Vec3::new(f32::NAN, 0.0, 0.0)); // 4
        positions.push(Vec3::new(2e11, 0.0, 0.0)); // 5
        let indices = [
            [0, 1, 2],        // 0: ok
            [0, 0, 1],        // 1: zero area
            [0, 2, u32::MAX], // 2: out of range
            [0, 1, 4],        // 3: NaN
            [0, 2, 3],        // 4: ok
            [0, 1, 5],        // 5: too far
            [4, 7, 0],        // 6: out of range beats NaN (a placeholder)
        ];
        let mesh = Mesh::from_indexed(&positions, &indices).unwrap();
        assert_eq!(mesh.len(), 7);
        assert_eq!(
            mesh.status,
            [
                TriStatus::Ok,
                TriStatus::Degenerate,
                TriStatus::OutOfRange,
                TriStatus::NonFinite,
                TriStatus::Ok,
                TriStatus::TooFar,
                TriStatus::OutOfRange,
            ]
        );
        assert_eq!(mesh.included(), vec![0, 4]);
        assert_eq!(
            mesh.triangles[4].v,
            [positions[0], positions[2], positions[3]]
        );
        assert!(mesh.triangles[2].v.iter().all(|p| p.is_nan()));
        assert!(mesh.sources.is_empty());
        let summary = mesh.exclusion_summary().unwrap();
        assert!(summary.contains("2 with out-of-range indices"), "{summary}");
    }

    #[test]
    fn same_mesh_as_the_obj_reader() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        // The same triangles as an OBJ file (indices from 1), a bad index included.
        std::fs::write(
            &path,
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\nf 1 3 9\nf 1 3 4\n",
        )
        .unwrap();
        let file = super::super::load_mesh(&path).unwrap();
        let arrays =
            Mesh::from_indexed(&SQUARE, &[[0, 1, 2], [0, 0, 1], [0, 2, 8], [0, 2, 3]]).unwrap();
        assert_eq!(file.status, arrays.status);
        for (a, b) in file.triangles.iter().zip(&arrays.triangles) {
            let bits = |t: &Triangle| t.v.map(|p| p.to_array().map(f32::to_bits));
            assert_eq!(bits(a), bits(b));
        }
    }

    #[test]
    fn refuses_what_load_mesh_refuses() {
        assert!(matches!(
            Mesh::from_indexed::<[f32; 3]>(&[], &[]),
            Err(Error::Input { .. })
        ));
        let e = Mesh::from_indexed(&SQUARE, &[[0, 0, 1], [5, 6, 7]]).unwrap_err();
        assert!(e.to_string().contains("no usable triangle"), "{e}");
        let tiny = SQUARE.map(|p| p.map(|x| x * 1e-14));
        let e = Mesh::from_indexed(&tiny, &[[0, 1, 2]]).unwrap_err();
        assert!(e.to_string().contains("across"), "{e}");
    }
}
