//! Refitting: a BVH's bounds recomputed bottom-up for a mesh whose triangles moved (a
//! deforming mesh: the same triangles, new positions), its shape kept — no new splits, the
//! same leaves. Much faster than a build; the tree's quality decays as the mesh deforms
//! away from the one it was built for (`lancer bench refit` measures both).

use crate::geometry::Aabb;
use crate::mesh::Mesh;

use super::{Bvh, Node};

/// Subtrees refit on their own rayon task above this many nodes.
const PARALLEL_NODES: u32 = 4096;

impl Bvh {
    /// Recomputes every node's bounds from `mesh`'s triangles, leaves first. `mesh` is the
    /// mesh the tree was built for, moved: a triangle the tree holds keeps its place
    /// whatever its new shape (one that became degenerate is never hit), and a triangle the
    /// build left out stays out. Refused (nothing changed) when the tree refers to a
    /// triangle `mesh` does not have, or one moved beyond the supported range
    /// ([`MAX_COORD`](crate::limits::MAX_COORD), infinities included), which a load would
    /// have left out and a refit cannot (a NaN corner only makes its triangle never hit).
    pub fn refit(&mut self, mesh: &Mesh) -> crate::Result<()> {
        if let Some(&i) = self.order.iter().find(|&&i| i as usize >= mesh.len()) {
            return Err(crate::Error::Usage(format!(
                "the BVH holds triangle {i}, but the mesh to refit it to has {}: refit to \
                 the mesh it was built for, moved",
                mesh.len()
            )));
        }
        let max = crate::limits::MAX_COORD;
        let beyond = |&i: &u32| {
            let t = &mesh.triangles[i as usize];
            t.v.iter().any(|v| v.abs().max_element() > max)
        };
        if let Some(&i) = self.order.iter().find(|i| beyond(i)) {
            return Err(crate::Error::Usage(format!(
                "triangle {i} moved to {:?}, beyond ±{max:e} (the supported range), which a \
                 refit cannot leave out: keep the mesh within it, or build it again",
                mesh.triangles[i as usize].v.map(|v| v.to_array())
            )));
        }
        refit_node(&mut self.root, &self.order, mesh);
        Ok(())
    }
}

/// Refits a subtree and returns its new bounds.
fn refit_node(node: &mut Node, order: &[u32], mesh: &Mesh) -> Aabb {
    match node {
        Node::Leaf { bbox, start, count } => {
            let range = *start as usize..(*start + *count) as usize;
            *bbox = (order[range].iter()).fold(Aabb::EMPTY, |b, &i| {
                b.union(mesh.triangles[i as usize].bbox())
            });
            *bbox
        }
        Node::Inner {
            bbox,
            nodes,
            children,
            ..
        } => {
            let [a, b] = &mut **children;
            let (ba, bb) = if *nodes > PARALLEL_NODES {
                rayon::join(|| refit_node(a, order, mesh), || refit_node(b, order, mesh))
            } else {
                (refit_node(a, order, mesh), refit_node(b, order, mesh))
            };
            *bbox = ba.union(bb);
            *bbox
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::bvh::{build, BuildOptions, Builder};
    use crate::geometry::Triangle;

    /// A bumpy sheet of 2·n² triangles, its height scaled by `amp`.
    fn sheet(n: usize, amp: f32) -> Mesh {
        let p = |i: usize, j: usize| {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            Vec3::new(x, amp * (9.0 * x).sin() * (7.0 * z).cos(), z)
        };
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
                tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
            }
        }
        Mesh::from_triangles(tris)
    }

    fn check_bounds(node: &Node, order: &[u32], mesh: &Mesh) -> Aabb {
        let got = match node {
            Node::Leaf { start, count, .. } => (order[*start as usize..(*start + *count) as usize]
                .iter())
            .fold(Aabb::EMPTY, |b, &i| {
                b.union(mesh.triangles[i as usize].bbox())
            }),
            Node::Inner { children, .. } => check_bounds(&children[0], order, mesh)
                .union(check_bounds(&children[1], order, mesh)),
        };
        assert_eq!(
            *node.bbox(),
            got,
            "a node's bounds are its triangles' union"
        );
        got
    }

    #[test]
    fn refit_bounds_are_the_moved_triangles_bounds_and_the_shape_is_kept() {
        for builder in [Builder::Sweep, Builder::Binned, Builder::Median] {
            let opts = BuildOptions {
                builder,
                ..BuildOptions::default()
            };
            let built = build(&sheet(40, 0.05), &opts);
            // Unmoved: the builder's own bounds.
            let mut same = built.clone();
            same.refit(&sheet(40, 0.05)).unwrap();
            assert_eq!(same, built, "{builder:?}");
            // Moved: every node holds exactly its triangles' new bounds; the shape is kept.
            let moved = sheet(40, 0.4);
            let mut refit = built.clone();
            refit.refit(&moved).unwrap();
            check_bounds(&refit.root, &refit.order, &moved);
            assert_eq!(refit.order, built.order);
            assert_eq!(refit.root.nodes(), built.root.nodes());
            assert_ne!(refit.root.bbox(), built.root.bbox());
        }
    }

    #[test]
    fn a_mesh_with_fewer_triangles_is_refused() {
        let mut tree = build(&sheet(8, 0.1), &BuildOptions::default());
        let before = tree.clone();
        assert!(tree.refit(&sheet(4, 0.1)).is_err());
        assert_eq!(tree, before);
    }
}
