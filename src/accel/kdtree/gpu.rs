//! The kd-tree on the GPU: the tree's own arrays, uploaded as they are — 8-byte nodes two to
//! a 16-byte word, the leaves' [`LeafTri`](crate::accel::LeafTri)s — walked by
//! `kdtree.wgsl`, whose CPU twin is the tree's [`Accel`](crate::accel::Accel)
//! (`traverse.rs`).

use super::traverse::MAILBOX;
use super::{KdTree, ABOVE_EMPTY, ABOVE_SHIFT, BELOW_EMPTY, COUNT_SHIFT, LEAF_TAG, MAX_KD_DEPTH};
use crate::accel::plane_ray::{root_box_overrides, traversal_wgsl};
use crate::accel::AccelKind;
use crate::accel::{GpuArrays, GpuForm};

impl GpuForm for KdTree {
    fn name(&self) -> &'static str {
        AccelKind::KdTree.name()
    }

    fn node_bytes(&self) -> usize {
        std::mem::size_of::<super::Node>()
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        let u32s = [
            ("KD_LEAF_TAG", LEAF_TAG),
            ("KD_BELOW_EMPTY", BELOW_EMPTY),
            ("KD_ABOVE_EMPTY", ABOVE_EMPTY),
            ("KD_ABOVE_SHIFT", ABOVE_SHIFT),
            ("KD_COUNT_SHIFT", COUNT_SHIFT),
            ("KD_MAILBOX", MAILBOX as u32),
        ];
        traversal_wgsl(&u32s, MAX_KD_DEPTH, include_str!("kdtree.wgsl"))
    }

    /// The root cell, which the traversal clips the ray to first (`PLANE_LO_X` …
    /// `PLANE_HI_Z`).
    fn overrides(&self) -> Vec<(&'static str, f64)> {
        root_box_overrides(&self.bounds)
    }

    /// Whole words of nodes; every node of the tree reachable from the root, the child above
    /// the split after the one below and inside its parent's subtree; depth ≤
    /// [`MAX_KD_DEPTH`] (the stack holds one entry per level); the empty-child flags true;
    /// leaf ranges inside the triangle array; a finite root cell.
    fn validate(&self) -> Result<(), String> {
        let n = self.stats.nodes;
        if n == 0 || self.nodes.len() != n.next_multiple_of(2) {
            return Err(format!(
                "{} nodes stored for a tree of {n} (padded to whole 16-byte words)",
                self.nodes.len()
            ));
        }
        let b = self.bounds;
        if !(b.lo.is_finite() && b.hi.is_finite()) {
            return Err(format!("the root cell {b:?} is not finite"));
        }
        // (node, depth, end of its subtree)
        let mut stack = vec![(0usize, 0usize, n)];
        let mut seen = 0usize;
        while let Some((i, depth, end)) = stack.pop() {
            seen += 1;
            if depth > MAX_KD_DEPTH {
                return Err(format!("node {i} is at depth {depth} > {MAX_KD_DEPTH}"));
            }
            let node = self.nodes[i];
            if node.is_leaf() {
                let (first, count) = (node.first(), node.count());
                if first + count > self.tris.len() {
                    return Err(format!(
                        "leaf {i} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
                continue;
            }
            let above = node.above();
            if i + 1 >= above || above >= end {
                return Err(format!(
                    "inner node {i} has its child above the split at {above}, outside {}..{end}",
                    i + 2
                ));
            }
            let flags = node.empty_children();
            let truth = (
                self.nodes[i + 1].is_empty_leaf(),
                self.nodes[above].is_empty_leaf(),
            );
            if flags != truth {
                return Err(format!(
                    "inner node {i} flags its children empty {flags:?}, they are {truth:?}"
                ));
            }
            stack.push((i + 1, depth + 1, above));
            stack.push((above, depth + 1, end));
        }
        if seen != n {
            return Err(format!("{} of {n} nodes are unreachable", n - seen));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use glam::Vec3;

    use super::super::{KdOptions, Node};
    use super::*;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;
    use crate::mesh::Mesh;

    /// Small triangles in a row along x, at varying heights: the SAH splits them.
    fn row() -> KdTree {
        let tris = (0..64)
            .map(|i| {
                let c = Vec3::new(i as f32, (i % 7) as f32 * 0.3, (i % 5) as f32 * 0.2);
                Triangle::new(
                    c,
                    c + Vec3::new(0.4, 0.0, 0.0),
                    c + Vec3::new(0.0, 0.4, 0.1),
                )
            })
            .collect();
        KdTree::build(&Mesh::from_triangles(tris), &KdOptions::default()).unwrap()
    }

    #[test]
    fn the_wgsl_validates_and_its_node_matches_the_rust_node() {
        let tree = row();
        for (kernel, src) in
            crate::render::kernel::all_kernels(&tree, &crate::gpu::BufferParts::WHOLE)
        {
            let m = naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{kernel}: {}", e.emit_to_string(&src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::all(),
            )
            .validate(&m)
            .unwrap_or_else(|e| panic!("{kernel}: {}", e.emit_to_string(&src)));
        }
        let fields = [("a", offset_of!(Node, a)), ("b", offset_of!(Node, b))];
        let src = shaders::trace_source(&tree, &crate::gpu::BufferParts::WHOLE);
        shaders::check_struct(&src, "KdNode", size_of::<Node>(), &fields).unwrap();
        assert_eq!(2 * size_of::<Node>(), 16, "two nodes to a word");
        assert_eq!(tree.arrays().nodes.len() % 16, 0);
        assert!(tree.stats().nodes > 9, "{:?}", tree.stats());
        tree.validate().unwrap();
        // The empty tree is valid too (one empty leaf, padded).
        let empty = KdTree::build(&Mesh::default(), &KdOptions::default()).unwrap();
        empty.validate().unwrap();
        assert_eq!(empty.overrides().len(), 6);
    }

    #[test]
    fn validate_rejects_corrupted_trees() {
        let tree = row();
        let inner = (tree.nodes.iter())
            .position(|n| !n.is_leaf() && n.empty_children() == (false, false))
            .unwrap();
        let leaf = (tree.nodes.iter())
            .position(|n| n.count() > 0 && n.is_leaf())
            .unwrap();
        let corrupt = |f: &dyn Fn(&mut KdTree)| {
            let mut t = tree.clone();
            f(&mut t);
            t.validate().unwrap_err()
        };
        let n = tree.nodes.len() as u32;
        let errors = [
            corrupt(&|t| t.nodes[inner].b += (n + 5) << ABOVE_SHIFT),
            corrupt(&|t| t.nodes[inner].b |= ABOVE_EMPTY),
            corrupt(&|t| t.nodes[leaf].a = t.tris.len() as u32),
            corrupt(&|t| {
                t.nodes.pop();
            }),
            corrupt(&|t| t.bounds.hi.x = f32::INFINITY),
        ];
        assert!(errors[0].contains("outside") && errors[1].contains("flags"));
        assert!(errors[2].contains("refers to triangles") && errors[3].contains("padded"));
        assert!(errors[4].contains("not finite"));
    }
}
