//! A real mesh made closed: its vertices welded where bit-identical and every hole (a loop of
//! edges used by one triangle) closed by a fan from the loop's centroid, oriented like its
//! neighbours. Scanned models have holes (the Stanford bunny's base); closed, they join the
//! watertightness tests beside the icospheres.

use std::collections::{BTreeMap, HashMap, HashSet};

use glam::Vec3;

use super::closed::Indexed;
use crate::mesh::Mesh;

/// The mesh's usable triangles, indexed and with every hole closed. Returns the closed mesh
/// and the number of holes filled. A boundary that does not form loops (a non-manifold
/// mesh) may stay open: [`open_edges`] counts what is left.
pub fn close_holes(mesh: &Mesh) -> (Indexed, usize) {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut verts: Vec<Vec3> = Vec::new();
    let mut id = |p: Vec3| {
        *ids.entry(p.to_array().map(f32::to_bits))
            .or_insert_with(|| {
                verts.push(p);
                verts.len() as u32 - 1
            })
    };
    let mut faces: Vec<[u32; 3]> = Vec::new();
    for i in mesh.included() {
        let v = mesh.triangles[i as usize].v;
        faces.push([id(v[0]), id(v[1]), id(v[2])]);
    }
    let directed: HashSet<(u32, u32)> = faces
        .iter()
        .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
        .collect();
    // Boundary edges, by their start vertex (sorted: the result does not depend on hashing).
    let mut outgoing: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
    for &(a, b) in &directed {
        if !directed.contains(&(b, a)) {
            outgoing.entry(a).or_default().push(b);
        }
    }
    for ends in outgoing.values_mut() {
        ends.sort_unstable();
    }
    let mut holes = 0;
    while let Some((&start, _)) = outgoing.iter().find(|(_, ends)| !ends.is_empty()) {
        // Walk boundary edges from `start` until the walk returns to it (or gets stuck).
        let mut hole = Vec::new();
        let mut at = start;
        while let Some(next) = outgoing.get_mut(&at).and_then(|ends| ends.pop()) {
            hole.push((at, next));
            at = next;
            if at == start {
                break;
            }
        }
        let centre = hole.iter().map(|&(a, _)| verts[a as usize]).sum::<Vec3>() / hole.len() as f32;
        verts.push(centre);
        let c = verts.len() as u32 - 1;
        // The triangle beside the hole runs a → b; its fan neighbour runs b → a.
        faces.extend(hole.iter().map(|&(a, b)| [b, a, c]));
        holes += 1;
    }
    ((verts, faces), holes)
}

/// Edges not shared by exactly two triangles in opposite directions: 0 for a closed,
/// consistently oriented mesh.
pub fn open_edges(shape: &Indexed) -> usize {
    // Per undirected edge: its uses, and its directions' balance (+1 a → b, −1 b → a).
    let mut uses: HashMap<(u32, u32), (usize, i32)> = HashMap::new();
    for f in &shape.1 {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            let e = uses.entry((a.min(b), a.max(b))).or_default();
            e.0 += 1;
            e.1 += if a < b { 1 } else { -1 };
        }
    }
    uses.values()
        .filter(|&&(n, balance)| n != 2 || balance != 0)
        .count()
}
