//! Per-vertex tangents for normal maps, MikkTSpace-style: a file's own (glTF `TANGENT`)
//! where it gives them, else each triangle's texture-space tangent averaged over the
//! corners that share a vertex — the same position, normal and texture coordinates, and the
//! same handedness — weighted by the corner's angle, as MikkTSpace welds and averages. A
//! smooth surface then bends its normal map's frame smoothly across its edges.
//!
//! Left out of MikkTSpace: its splitting of a vertex's corners whose tangents differ by
//! more than an angle threshold (all corners of one weld group are averaged), and its
//! separate bitangent magnitudes (lancer's bitangent is n × t, turned by the handedness).

use std::collections::HashMap;

use glam::{Vec2, Vec3};

use super::assemble::{Material, TextureSlot};
use crate::geometry::{cross, dot, normalize, pack_tangent, unpack_tangent, unpack_unit};
use crate::geometry::{NO_NORMAL, NO_TANGENT};
use crate::mesh::Mesh;

/// What a corner is welded by: its mesh, position, normal (the vertex's, else the
/// face's) and texture coordinates, as bits, and the face's handedness.
type Weld = ([u32; 9], bool);

/// What [`tangents_of`] reads: a scene's triangles by number and what it knows of them.
pub(super) struct TangentInputs<'a> {
    pub mesh: &'a Mesh,
    /// Each triangle's corners' texture coordinates.
    pub uvs: &'a [[Vec2; 3]],
    /// Each triangle's corners' packed normals (empty: none).
    pub normals: &'a [[u32; 3]],
    /// A file's own packed corner tangents (empty, or [`NO_TANGENT`]: none).
    pub given: &'a [[u32; 3]],
    pub material_of: &'a [u32],
    pub materials: &'a [Material],
    /// Where each placed mesh starts (empty: one mesh); corners of different meshes are
    /// not welded.
    pub mesh_starts: &'a [usize],
}

/// Each triangle's corner tangents where its material has a normal map, packed with the
/// handedness relative to its winding ([`pack_tangent`]): `given`'s where it holds a
/// tangent for the triangle, else generated (see the module comment) in the frame of the
/// coordinates the normal map is read at (moved by its texture's transform);
/// [`NO_TANGENT`] three times elsewhere, and where no tangent can be made (texture
/// coordinates that do not span the triangle, and no welded neighbour that has one).
/// Empty where no material has a normal map.
pub(super) fn tangents_of(x: &TangentInputs) -> Vec<[u32; 3]> {
    if !x.materials.iter().any(|m| m.normal_texture.is_some()) {
        return Vec::new();
    }
    let map_of = |i: usize| x.materials[x.material_of[i] as usize].normal_texture;
    let own = |i: usize| x.given.get(i).filter(|g| g[0] != NO_TANGENT);
    let n = x.mesh.triangles.len();
    // Each triangle's mesh number, counted along (triangles are in mesh order).
    let mesh_numbers = || {
        let mut m = 0usize;
        (0..n).map(move |i| {
            while m + 1 < x.mesh_starts.len() && x.mesh_starts[m + 1] <= i {
                m += 1;
            }
            m as u32
        })
    };
    // The frame of a generated triangle (None: mapped by the file, or not at all).
    let frame = |i: usize, mesh: u32| {
        map_of(i).filter(|_| own(i).is_none())?;
        let material = &x.materials[x.material_of[i] as usize];
        let uv_map = material.uv_transforms[TextureSlot::Normal as usize];
        FaceFrame::of(
            mesh,
            x.mesh.triangles[i].v,
            x.uvs.get(i),
            x.normals.get(i),
            uv_map,
        )
    };
    // First pass: every generated corner's face tangent, summed per weld.
    let mut sums: HashMap<Weld, Vec3> = HashMap::new();
    for (i, mesh) in mesh_numbers().enumerate() {
        let Some(f) = frame(i, mesh) else {
            continue;
        };
        for k in 0..3 {
            if let Some((t, weight)) = f.projected[k] {
                *sums.entry((f.welds[k], f.flipped)).or_insert(Vec3::ZERO) += t * weight;
            }
        }
    }
    // Second pass (the frames made again rather than kept): each corner's tangent is its
    // weld's sum.
    mesh_numbers()
        .enumerate()
        .map(|(i, mesh)| {
            if let Some(g) = own(i).filter(|_| map_of(i).is_some()) {
                return *g;
            }
            let Some(f) = frame(i, mesh) else {
                return [NO_TANGENT; 3];
            };
            let corner = |k: usize| {
                let summed = |flipped: bool| {
                    let s = *sums.get(&(f.welds[k], flipped))?;
                    pack_tangent(s, flipped)
                };
                match f.spans {
                    true => summed(f.flipped),
                    // A face without a tangent of its own takes its vertices'.
                    false => summed(false).or_else(|| summed(true)),
                }
            };
            let corners = [corner(0), corner(1), corner(2)];
            // Corners welded to no tangent take another corner's of the same face (as
            // MikkTSpace finishes degenerate faces).
            let Some(any) = corners.iter().flatten().next().copied() else {
                return [NO_TANGENT; 3];
            };
            corners.map(|c| c.unwrap_or(any))
        })
        .collect()
}

/// A triangle's corners as [`tangents_of`] welds and sums them.
struct FaceFrame {
    welds: [[u32; 9]; 3],
    /// Whether its texture coordinates span it (else no tangent of its own).
    spans: bool,
    /// Its bitangent is −(n × t) for n the winding's normal.
    flipped: bool,
    /// At each corner: the face's tangent made perpendicular to the corner's normal and
    /// normalised, and the corner's angle (its weight); None where the face has none.
    projected: [Option<(Vec3, f32)>; 3],
}

impl FaceFrame {
    /// The corners of triangle `v` of mesh `mesh`, its tangent the direction in which
    /// its coordinates `uv` grow once moved by `uv_map` (the normal texture's transform);
    /// None for a triangle with no area (no normal to weld by).
    fn of(
        mesh: u32,
        v: [Vec3; 3],
        uv: Option<&[Vec2; 3]>,
        normals: Option<&[u32; 3]>,
        uv_map: Option<[[f32; 3]; 2]>,
    ) -> Option<Self> {
        let uv = uv.copied().unwrap_or([Vec2::ZERO; 3]);
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let wn = cross(e1, e2);
        let face_n = normalize(wn);
        if !face_n.is_finite() {
            return None;
        }
        let moved = |d: Vec2| match uv_map {
            Some([a, b]) => Vec2::new(a[0] * d.x + a[1] * d.y, b[0] * d.x + b[1] * d.y),
            None => d,
        };
        let (d1, d2) = (moved(uv[1] - uv[0]), moved(uv[2] - uv[0]));
        let det = d1.x * d2.y - d2.x * d1.y;
        let tangent = (e1 * d2.y - e2 * d1.y) / det;
        let bitangent = (e2 * d1.x - e1 * d2.x) / det;
        let spans = det != 0.0 && tangent.is_finite() && bitangent.is_finite();
        let flipped = spans && dot(cross(wn, tangent), bitangent) < 0.0;
        let corner_normal = |k: usize| match normals.map(|n| n[k]) {
            Some(w) if w != NO_NORMAL => {
                let n = normalize(unpack_unit(w));
                if n.is_finite() {
                    n
                } else {
                    face_n
                }
            }
            _ => face_n,
        };
        let mut welds = [[0; 9]; 3];
        let mut projected = [None; 3];
        for k in 0..3 {
            let n = corner_normal(k);
            let (p, t) = (v[k], uv[k]);
            // + 0 makes −0 the same as 0.
            let w = [p.x, p.y, p.z, n.x, n.y, n.z, t.x, t.y].map(|c| (c + 0.0).to_bits());
            welds[k] = [mesh, w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7]];
            if !spans {
                continue;
            }
            let along = tangent - n * dot(n, tangent);
            let along = normalize(along);
            let (a, b) = (v[(k + 1) % 3] - v[k], v[(k + 2) % 3] - v[k]);
            let cos = dot(normalize(a), normalize(b)).clamp(-1.0, 1.0);
            let angle = cos.acos();
            if along.is_finite() && angle.is_finite() {
                projected[k] = Some((along, angle));
            }
        }
        Some(FaceFrame {
            welds,
            spans,
            flipped,
            projected,
        })
    }
}

/// A triangle's corner tangents moved by a map's linear part `m` (as directions), their
/// handedness kept: relative to the winding, which the map moves with them.
pub(super) fn move_tangents(m: impl Fn(Vec3) -> Vec3, t: &[u32; 3]) -> [u32; 3] {
    let moved = t.map(|w| unpack_tangent(w).and_then(|(v, flipped)| pack_tangent(m(v), flipped)));
    match moved {
        [Some(a), Some(b), Some(c)] => [a, b, c],
        _ => [NO_TANGENT; 3],
    }
}

/// The tangent at barycentric weights (w, u, v) of a triangle's corner tangents `t` (not
/// normalised) and its handedness, the majority of the corners' (one for the whole
/// triangle); None where it has none. WGSL `interpolated_tangent`.
pub(super) fn interpolated(t: &[u32; 3], w: f32, u: f32, v: f32) -> Option<(Vec3, bool)> {
    let [(a, fa), (b, fb), (c, fc)] = [
        unpack_tangent(t[0])?,
        unpack_tangent(t[1])?,
        unpack_tangent(t[2])?,
    ];
    let flipped = u8::from(fa) + u8::from(fb) + u8::from(fc) >= 2;
    Some((a * w + b * u + c * v, flipped))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;

    /// [`tangents_of`] of one mesh whose normal maps read no transform.
    fn tangents(
        mesh: &Mesh,
        uvs: &[[Vec2; 3]],
        normals: &[[u32; 3]],
        given: &[[u32; 3]],
        material_of: &[u32],
        materials: &[Material],
    ) -> Vec<[u32; 3]> {
        tangents_of(&TangentInputs {
            mesh,
            uvs,
            normals,
            given,
            material_of,
            materials,
            mesh_starts: &[],
        })
    }

    fn diffuse_mapped() -> Material {
        let mut m = Material::diffuse(Vec3::ONE);
        m.normal_texture = Some(0);
        m
    }

    /// Two triangles folded along a shared edge, texture coordinates unrolled across it,
    /// one normal at every corner: the tangents at the shared corners are the same on both
    /// faces; with flat shading (each face its own normal) they are not welded.
    #[test]
    fn welded_corners_share_one_tangent() {
        let p = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.5),
        ];
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
        ];
        let mesh = Mesh::from_triangles(vec![
            Triangle::new(p[0], p[1], p[2]),
            Triangle::new(p[1], p[3], p[2]),
        ]);
        let uvs = [[uv[0], uv[1], uv[2]], [uv[1], uv[3], uv[2]]];
        // One normal between the two faces' at every corner.
        let n = (Vec3::Z + Vec3::new(-0.5, -0.5, 1.0).normalize()).normalize();
        let smooth = [crate::mesh::pack_corners([n; 3]); 2];
        let t = tangents(&mesh, &uvs, &smooth, &[], &[0, 0], &[diffuse_mapped()]);
        // Corner 1 of face 0 is corner 0 of face 1; corner 2 of face 0 is corner 2 of face 1.
        assert_eq!(t[0][1], t[1][0]);
        assert_eq!(t[0][2], t[1][2]);
        let flat = tangents(&mesh, &uvs, &[], &[], &[0, 0], &[diffuse_mapped()]);
        assert_ne!(flat[0][1], flat[1][0]);
        // Nor are corners of two placed meshes.
        let two_meshes = tangents_of(&TangentInputs {
            mesh: &mesh,
            uvs: &uvs,
            normals: &smooth,
            given: &[],
            material_of: &[0, 0],
            materials: &[diffuse_mapped()],
            mesh_starts: &[0, 1],
        });
        assert_ne!(two_meshes[0][1], two_meshes[1][0]);
        // Each face's own tangent differs (the fold), so the shared one is an average.
        let face = |i: usize| {
            let f = FaceFrame::of(0, mesh.triangles[i].v, Some(&uvs[i]), None, None).unwrap();
            f.projected[0].unwrap().0
        };
        assert!(dot(face(0), face(1)) < 0.999);
    }

    /// A face whose texture coordinates are all one point takes the tangent of the corner
    /// welded to a neighbour at every corner; alone it has none.
    #[test]
    fn a_face_without_texture_extent_borrows_its_neighbours_tangent() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let mesh = Mesh::from_triangles(vec![
            Triangle::new(p[0], p[1], p[2]),
            Triangle::new(p[1], p[3], p[2]),
        ]);
        let good = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        // Its corner 0 (p1) has the good face's coordinates there: welded to it.
        let collapsed = [good[1]; 3];
        let uvs = [good, collapsed];
        let t = tangents(&mesh, &uvs, &[], &[], &[0, 0], &[diffuse_mapped()]);
        assert_ne!(t[0][1], NO_TANGENT);
        assert_eq!(t[1], [t[0][1]; 3]);
        let alone = tangents(
            &Mesh::from_triangles(vec![mesh.triangles[1]]),
            &[collapsed],
            &[],
            &[],
            &[0],
            &[diffuse_mapped()],
        );
        assert_eq!(alone, vec![[NO_TANGENT; 3]]);
    }

    /// A normal map read at turned coordinates (its slot's transform) turns the frame
    /// with them: u' = 1 − v grows along −y where u grows along +x.
    #[test]
    fn a_moved_normal_map_moves_its_frame() {
        let mesh = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)]);
        let uvs = [[Vec2::ZERO, Vec2::X, Vec2::Y]];
        let direction = |uv_map: Option<[[f32; 3]; 2]>| {
            let mut material = diffuse_mapped();
            material.uv_transforms[TextureSlot::Normal as usize] = uv_map;
            let t = tangents_of(&TangentInputs {
                mesh: &mesh,
                uvs: &uvs,
                normals: &[],
                given: &[],
                material_of: &[0],
                materials: &[material],
                mesh_starts: &[],
            });
            interpolated(&t[0], 1.0, 0.0, 0.0).unwrap().0.normalize()
        };
        assert!((direction(None) - Vec3::X).length() < 1e-3);
        let turned = Some([[0.0, -1.0, 1.0], [1.0, 0.0, 1.0]]);
        assert!((direction(turned) + Vec3::Y).length() < 1e-3);
    }

    /// A file's tangents are kept as given, and a material without a map gets none.
    #[test]
    fn given_tangents_are_kept_and_unmapped_faces_get_none() {
        let mesh = Mesh::from_triangles(vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y); 2]);
        let uvs = [[Vec2::ZERO, Vec2::X, Vec2::Y]; 2];
        let given = [pack_tangent(Vec3::Y, true).unwrap(); 3];
        let mats = [diffuse_mapped(), Material::diffuse(Vec3::ONE)];
        let t = tangents(&mesh, &uvs, &[], &[given, given], &[0, 1], &mats);
        assert_eq!(t, vec![given, [NO_TANGENT; 3]]);
        let (dir, flipped) = interpolated(&t[0], 0.2, 0.3, 0.5).unwrap();
        assert!(flipped && (dir - Vec3::Y).length() < 1e-3);
    }
}
