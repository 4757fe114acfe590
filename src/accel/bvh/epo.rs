//! End-point overlap (EPO; Aila, Karras & Laine 2013, "On quality metrics of bounding volume
//! hierarchies"): the SAH assumes a ray visiting a node's box is equally likely anywhere in
//! it, but rays end on surfaces, so a node is mostly visited by rays ending on the geometry
//! inside its box — including geometry that belongs to other subtrees. EPO charges each node
//! for the area of the surfaces inside its box that are not in its subtree:
//!
//! EPO = Σ_n c(n) · Σ_{t ∉ n} A(t ∩ box(n)) / Σ_t A(t),
//!
//! with c(n) the SAH's own node costs (2·T_cube for an inner node, N·T_obj for a leaf of N
//! triangles), so that SAH and EPO are in the same units.

use rayon::prelude::*;

use super::{BuildOptions, Bvh, Node};
use crate::geometry::{clipped_area, Aabb};
use crate::mesh::Mesh;

/// A node of the flattened walk: its box, cost, leaf-order range and children.
struct Flat {
    bbox: Aabb,
    cost: f64,
    range: (u32, u32),
    children: Option<[usize; 2]>,
}

fn flatten(node: &Node, opts: &BuildOptions, out: &mut Vec<Flat>) -> (usize, (u32, u32)) {
    let at = out.len();
    out.push(Flat {
        bbox: *node.bbox(),
        cost: 0.0,
        range: (0, 0),
        children: None,
    });
    let (cost, range, children) = match node {
        Node::Leaf { start, count, .. } => (
            *count as f64 * opts.t_obj as f64,
            (*start, start + count),
            None,
        ),
        Node::Inner { children, .. } => {
            let (l, lr) = flatten(&children[0], opts, out);
            let (r, rr) = flatten(&children[1], opts, out);
            (2.0 * opts.t_cube as f64, (lr.0, rr.1), Some([l, r]))
        }
    };
    out[at].cost = cost;
    out[at].range = range;
    out[at].children = children;
    (at, range)
}

/// The tree's EPO cost over `mesh`'s triangles (the ones it was built from; a mesh smaller
/// than the tree's is refused). 0 for a tree without surface area. Each leaf-order position
/// is one reference: a triangle that several leaves reference is in the subtree of each of
/// their ancestors.
pub fn epo_cost(bvh: &Bvh, mesh: &Mesh, opts: &BuildOptions) -> crate::Result<f64> {
    bvh.check_mesh(mesh, "measure it over")?;
    let mut nodes = Vec::with_capacity(bvh.root.nodes() as usize);
    flatten(&bvh.root, opts, &mut nodes);
    // Every position of each triangle in the leaf order, sorted, to tell which nodes hold it.
    let mut positions: Vec<(u32, u32)> = (bvh.order.iter().enumerate())
        .map(|(p, &t)| (t, p as u32))
        .collect();
    positions.par_sort_unstable();
    let groups: Vec<&[(u32, u32)]> = positions.chunk_by(|a, b| a.0 == b.0).collect();
    let (overlap, total) = groups
        .par_iter()
        .map(|group| {
            let tri = &mesh.triangles[group[0].0 as usize];
            let holds = |range: (u32, u32)| group.iter().any(|&(_, p)| p >= range.0 && p < range.1);
            let tb = tri.bbox();
            let mut sum = 0.0;
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                let n = &nodes[i];
                if !overlaps(&n.bbox, &tb) {
                    continue;
                }
                if !holds(n.range) {
                    sum += n.cost * clipped_area(tri, &n.bbox);
                }
                stack.extend(n.children.iter().flatten());
            }
            (sum, tri.area() as f64)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(if total > 0.0 { overlap / total } else { 0.0 })
}

fn overlaps(a: &Aabb, b: &Aabb) -> bool {
    a.lo.cmple(b.hi).all() && b.lo.cmple(a.hi).all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh::build;
    use crate::geometry::Triangle;
    use glam::Vec3;

    fn quad(x: f32) -> [Triangle; 2] {
        let p = |dx: f32, y: f32| Vec3::new(x + dx, y, 0.0);
        [
            Triangle::new(p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)),
            Triangle::new(p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)),
        ]
    }

    #[test]
    fn disjoint_clusters_have_no_overlap_and_interleaved_ones_do() {
        let opts = BuildOptions::default();
        // Two unit squares far apart: no node's box holds a triangle of another subtree.
        let apart: Vec<Triangle> = quad(0.0).into_iter().chain(quad(10.0)).collect();
        let mesh = Mesh::from_triangles(apart);
        assert_eq!(epo_cost(&build(&mesh, &opts), &mesh, &opts).unwrap(), 0.0);
        // A big triangle over a grid of small ones: whichever subtree holds it, the other's
        // box lies on its surface.
        let mut tris: Vec<Triangle> = (0..8).flat_map(|i| quad(i as f32)).collect();
        tris.push(Triangle::new(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(20.0, -1.0, 0.0),
            Vec3::new(-1.0, 20.0, 0.0),
        ));
        let mesh = Mesh::from_triangles(tris);
        assert!(epo_cost(&build(&mesh, &opts), &mesh, &opts).unwrap() > 0.1);
    }
}
