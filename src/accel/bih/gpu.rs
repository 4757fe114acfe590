//! The BIH on the GPU: the tree's own arrays, uploaded as they are — 16-byte nodes one to a
//! word, the leaves' [`LeafTri`](crate::accel::LeafTri)s — walked by `bih.wgsl`, whose CPU
//! twin is the tree's [`Accel`](crate::accel::Accel) (`traverse.rs`).

use super::{Bih, BihNode, BIH_LEAF_TAG, BIH_LINK_SHIFT, BIH_NODE_BYTES, MAX_BIH_DEPTH};
use crate::accel::plane_ray::{root_box_overrides, traversal_wgsl};
use crate::accel::AccelKind;
use crate::accel::{GpuArrays, GpuForm};

impl GpuForm for Bih {
    fn name(&self) -> &'static str {
        AccelKind::Bih.name()
    }

    fn node_bytes(&self) -> usize {
        BIH_NODE_BYTES
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        let u32s = [
            ("BIH_LEAF_TAG", BIH_LEAF_TAG),
            ("BIH_LINK_SHIFT", BIH_LINK_SHIFT),
        ];
        traversal_wgsl(&u32s, MAX_BIH_DEPTH, include_str!("bih.wgsl"))
    }

    /// The root's box, which the traversal clips the ray to first (`PLANE_LO_X` …
    /// `PLANE_HI_Z`).
    fn overrides(&self) -> Vec<(&'static str, f64)> {
        root_box_overrides(&self.bounds)
    }

    /// Every node reachable from the root exactly once: an inner node's left child next to
    /// it, its right child after the left subtree and inside its own (or, one-sided, the
    /// next node as both); depth ≤ [`MAX_BIH_DEPTH`] (the stack holds one entry per level);
    /// leaf ranges inside the triangle array; the root an empty leaf exactly when there are
    /// no triangles (the kernel's early miss); a finite root box.
    fn validate(&self) -> Result<(), String> {
        let n = self.nodes.len();
        let Some(root) = self.nodes.first() else {
            return Err("no nodes (an empty tree is one empty leaf)".into());
        };
        let empty_root = root.is_leaf() && root.count == 0;
        if empty_root != self.tris.is_empty() {
            return Err(format!(
                "the root is {}an empty leaf over {} triangles",
                if empty_root { "" } else { "not " },
                self.tris.len()
            ));
        }
        let b = self.bounds;
        if !(b.lo.is_finite() && b.hi.is_finite()) {
            return Err(format!("the root box {b:?} is not finite"));
        }
        // (node, depth, end of its subtree)
        let mut stack = vec![(0usize, 0usize, n)];
        let mut seen = 0usize;
        while let Some((i, depth, end)) = stack.pop() {
            seen += 1;
            if seen > n {
                return Err(format!("nodes are reached more than once (node {i})"));
            }
            if depth > MAX_BIH_DEPTH {
                return Err(format!("node {i} is at depth {depth} > {MAX_BIH_DEPTH}"));
            }
            let node: BihNode = self.nodes[i];
            if node.is_leaf() {
                let (first, count) = (node.index(), node.count as usize);
                if first + count > self.tris.len() {
                    return Err(format!(
                        "leaf {i} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
                continue;
            }
            let (left, right) = (i + 1, node.index());
            if right == left && left < end {
                // One-sided: the next node is the only child.
                stack.push((left, depth + 1, end));
                continue;
            }
            if right <= left || right >= end {
                return Err(format!(
                    "inner node {i} has its right child at {right}, outside {}..{end}",
                    i + 2
                ));
            }
            stack.push((left, depth + 1, right));
            stack.push((right, depth + 1, end));
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

    use super::super::BihOptions;
    use super::*;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;
    use crate::mesh::Mesh;

    /// Small triangles in a row along x, at varying heights, and one far off: the global
    /// heuristic splits them.
    fn row() -> Bih {
        let mut tris: Vec<Triangle> = (0..64)
            .map(|i| {
                let c = Vec3::new(i as f32, (i % 7) as f32 * 0.3, (i % 5) as f32 * 0.2);
                Triangle::new(
                    c,
                    c + Vec3::new(0.4, 0.0, 0.0),
                    c + Vec3::new(0.0, 0.4, 0.1),
                )
            })
            .collect();
        let far = Vec3::new(30.0, 500.0, 0.0);
        tris.push(Triangle::new(far, far + Vec3::X, far + Vec3::Y));
        Bih::build(&Mesh::from_triangles(tris), &BihOptions::default()).unwrap()
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
        let fields = [
            ("clip", offset_of!(BihNode, clip)),
            ("link", offset_of!(BihNode, link)),
            ("count", offset_of!(BihNode, count)),
        ];
        let src = shaders::trace_source(&tree, &crate::gpu::BufferParts::WHOLE);
        shaders::check_struct(&src, "BihNode", size_of::<BihNode>(), &fields).unwrap();
        assert_eq!(tree.arrays().nodes.len(), 16 * tree.stats().nodes);
        assert!(tree.stats().nodes > 9, "{:?}", tree.stats());
        tree.validate().unwrap();
        // The empty tree is valid too (one empty leaf).
        let empty = Bih::build(&Mesh::default(), &BihOptions::default()).unwrap();
        empty.validate().unwrap();
        assert_eq!(empty.overrides().len(), 6);
    }

    #[test]
    fn validate_rejects_corrupted_trees() {
        let tree = row();
        let inner = (tree.nodes.iter().enumerate())
            .position(|(i, n)| !n.is_leaf() && n.index() != i + 1)
            .unwrap();
        let leaf = tree.nodes.iter().position(|n| n.is_leaf()).unwrap();
        let corrupt = |f: &dyn Fn(&mut Bih)| {
            let mut t = tree.clone();
            f(&mut t);
            t.validate().unwrap_err()
        };
        let n = tree.nodes.len() as u32;
        let errors = [
            corrupt(&|t| t.nodes[inner].link += (n + 5) << BIH_LINK_SHIFT),
            corrupt(&|t| t.nodes[leaf].link = (t.tris.len() as u32) << BIH_LINK_SHIFT | 3),
            corrupt(&|t| t.nodes[0] = BihNode::leaf(0, 0)),
            corrupt(&|t| {
                t.nodes.pop();
            }),
            corrupt(&|t| t.bounds.hi.x = f32::INFINITY),
            corrupt(&|t| t.nodes.push(BihNode::leaf(0, 1))),
        ];
        assert!(errors[0].contains("outside"), "{}", errors[0]);
        assert!(errors[1].contains("refers to triangles"), "{}", errors[1]);
        assert!(errors[2].contains("empty leaf over"), "{}", errors[2]);
        assert!(errors[4].contains("not finite"), "{}", errors[4]);
        assert!(errors[5].contains("unreachable"), "{}", errors[5]);
        // A popped node leaves its parent's child outside the array.
        assert!(errors[3].contains("outside"), "{}", errors[3]);
    }
}
