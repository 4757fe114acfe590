//! A tree made outside lancer's builders, checked before anything relies on it: the shape
//! that flattening, refitting and the statistics take for granted (depths within the
//! traversal stacks, subtree counts, leaves holding the order's positions left to right,
//! the order's triangles within the mesh). Boxes are not checked here: every layout's
//! `validate`, run before an upload, checks that they hold the triangles.

use crate::error::{Error, Result};
use crate::mesh::Mesh;

use super::{Bvh, Node, MAX_DEPTH};

impl Bvh {
    /// A BVH from a tree made elsewhere (your own builder's) over `mesh`: `root`'s leaves
    /// hold positions of `order` (original triangle indices), left to right, each position
    /// once. Refused, naming the first fault, unless every leaf is at depth ≤ [`MAX_DEPTH`]
    /// (the root's is 0), every inner node's `axis` is 0, 1 or 2 and its `nodes` counts its
    /// subtree, the leaves' ranges follow one another from 0 to `order`'s end (a leaf of no
    /// triangle only as the root of an empty tree), and every entry of `order` is a
    /// triangle of `mesh`. The boxes are not checked: a layout's
    /// [`validate`](crate::GpuForm::validate), run before every upload, refuses boxes that do
    /// not hold their triangles.
    pub fn new(root: Node, order: Vec<u32>, mesh: &Mesh) -> Result<Bvh> {
        let mut walk = Walk {
            visited: 0,
            next: 0,
            order_len: order.len() as u64,
        };
        let fault = match walk.node(&root, 0) {
            Err(e) => Some(e),
            Ok(_) if walk.next != walk.order_len => Some(format!(
                "its leaves hold positions 0..{} of an order of {}: every position must be in a \
                 leaf",
                walk.next, walk.order_len
            )),
            Ok(_) => (order.iter().enumerate())
                .find(|&(_, &t)| t as usize >= mesh.len())
                .map(|(p, t)| {
                    format!(
                        "position {p} of its order is triangle {t}, but the mesh has {}",
                        mesh.len()
                    )
                }),
        };
        match fault {
            None => Ok(Bvh {
                root,
                order,
                mesh_len: mesh.len(),
            }),
            Some(e) => {
                free(root);
                Err(Error::Usage(format!(
                    "refusing the BVH: {e} (Bvh::new's documentation lists the shape a tree \
                     must have)"
                )))
            }
        }
    }
}

/// The walk's place: nodes visited (a node is named by its depth-first number, the root's
/// 0), the next leaf-order position a leaf must start at, the order's length.
struct Walk {
    visited: u64,
    next: u64,
    order_len: u64,
}

impl Walk {
    /// Checks the subtree of `node` at `depth`; returns its node count. Recursion stops at
    /// the first node too deep, so it never goes past MAX_DEPTH + 1 frames.
    fn node(&mut self, node: &Node, depth: usize) -> std::result::Result<u64, String> {
        let i = self.visited;
        self.visited += 1;
        if depth > MAX_DEPTH {
            return Err(format!(
                "node {i} (depth first) is at depth {depth}, deeper than {MAX_DEPTH} (the \
                 traversal stacks' size)"
            ));
        }
        match node {
            &Node::Leaf { start, count, .. } => {
                let (start, end) = (start as u64, start as u64 + count as u64);
                if start != self.next {
                    return Err(format!(
                        "leaf {i} (depth first) holds positions {start}..{end} of the order, \
                         but the leaves before it end at {}: leaves hold the order's \
                         positions left to right, each once",
                        self.next
                    ));
                }
                if end > self.order_len {
                    return Err(format!(
                        "leaf {i} (depth first) holds positions {start}..{end} of an order of {}",
                        self.order_len
                    ));
                }
                if count == 0 && depth > 0 {
                    return Err(format!("leaf {i} (depth first) holds no triangle"));
                }
                self.next = end;
                Ok(1)
            }
            Node::Inner {
                axis,
                nodes,
                children,
                ..
            } => {
                if *axis > 2 {
                    return Err(format!(
                        "inner node {i} (depth first) splits on axis {axis} (0, 1 or 2)"
                    ));
                }
                let below =
                    self.node(&children[0], depth + 1)? + self.node(&children[1], depth + 1)?;
                if *nodes as u64 != 1 + below {
                    return Err(format!(
                        "inner node {i} (depth first) counts {nodes} nodes in its subtree, \
                         which holds {}",
                        1 + below
                    ));
                }
                Ok(1 + below)
            }
        }
    }
}

/// Frees a tree refused for its depth without recursing (a chain of a million nodes would
/// overflow the stack as Rust's own drop recurses).
fn free(root: Node) {
    let mut stack = vec![root];
    while let Some(node) = stack.pop() {
        if let Node::Inner { children, .. } = node {
            let [a, b] = *children;
            stack.extend([a, b]);
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::bvh::layouts::{try_flatten, LayoutKind};
    use crate::geometry::{Aabb, Triangle};

    /// Four unit triangles along x.
    fn mesh() -> Mesh {
        Mesh::from_triangles(
            (0..4)
                .map(|i| {
                    let p = Vec3::new(i as f32, 0.0, 0.0);
                    Triangle::new(p, p + Vec3::X, p + Vec3::Y)
                })
                .collect(),
        )
    }

    fn leaf(start: u32, count: u32) -> Node {
        let bbox = Aabb {
            lo: Vec3::ZERO,
            hi: Vec3::new(5.0, 1.0, 0.0),
        };
        Node::Leaf { bbox, start, count }
    }

    fn inner(a: Node, b: Node) -> Node {
        Node::parent(0, [a, b])
    }

    #[test]
    fn a_tree_made_elsewhere_is_refused_where_flattening_would_fail() {
        let mesh = mesh();
        let refused = |root: Node, order: Vec<u32>, want: &str| {
            let e = Bvh::new(root, order, &mesh).unwrap_err().to_string();
            assert!(e.contains(want), "{want}: {e}");
        };
        // Each of these made a flatten index past an array (a panic) before Bvh::new.
        refused(
            leaf(2, 5),
            vec![0, 1, 2, 3],
            "leaf 0 (depth first) holds positions 2..7",
        );
        refused(
            inner(leaf(0, 2), leaf(2, 5)),
            vec![0, 1, 2, 3],
            "positions 2..7 of an order of 4",
        );
        refused(
            leaf(0, 4),
            vec![0, 1, 2, 9],
            "position 3 of its order is triangle 9",
        );
        refused(
            leaf(0, 2),
            vec![0, 1, 2, 3],
            "positions 0..2 of an order of 4",
        );
        refused(
            inner(leaf(2, 2), leaf(0, 2)),
            vec![0, 1, 2, 3],
            "the leaves before it end at 0",
        );
        refused(
            inner(leaf(0, 4), leaf(4, 0)),
            vec![0, 1, 2, 3],
            "leaf 2 (depth first) holds no triangle",
        );
        let mut miscounted = inner(leaf(0, 2), leaf(2, 2));
        if let Node::Inner { nodes, .. } = &mut miscounted {
            *nodes = 7;
        }
        refused(
            miscounted,
            vec![0, 1, 2, 3],
            "counts 7 nodes in its subtree, which holds 3",
        );
        let mut axis = inner(leaf(0, 2), leaf(2, 2));
        if let Node::Inner { axis, .. } = &mut axis {
            *axis = 3;
        }
        refused(axis, vec![0, 1, 2, 3], "splits on axis 3");
        // A chain far deeper than the stacks (the walk goes down it first): refused, and
        // freed without recursing (a chain this long overflows a test thread's stack where
        // drop recurses).
        let mut chain = leaf(0, 1);
        for _ in 0..200_000 {
            chain = Node::Inner {
                bbox: *chain.bbox(),
                axis: 0,
                nodes: 0,
                children: Box::new([chain, leaf(1, 3)]),
            };
        }
        refused(chain, vec![0, 1, 2, 3], &format!("deeper than {MAX_DEPTH}"));
        // The good tree, and the empty one, pass and flatten into every layout.
        let good = Bvh::new(inner(leaf(0, 1), leaf(1, 3)), vec![3, 1, 0, 2], &mesh).unwrap();
        let empty = Bvh::new(leaf(0, 0), Vec::new(), &mesh).unwrap();
        for &kind in LayoutKind::ALL {
            try_flatten(kind, &good, &mesh).unwrap().validate().unwrap();
            try_flatten(kind, &empty, &mesh)
                .unwrap()
                .validate()
                .unwrap();
            // A mesh smaller than the tree's is refused, not indexed past.
            let small = Mesh::from_triangles(mesh.triangles[..2].to_vec());
            let e = try_flatten(kind, &good, &small).map(|_| ()).unwrap_err();
            assert!(e.to_string().contains("built over 4 triangles"), "{e}");
        }
    }
}
