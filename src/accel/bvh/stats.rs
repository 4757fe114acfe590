//! Shape and SAH cost of a built tree (independent of how it is flattened).

use serde::Serialize;

use super::{BuildOptions, Bvh, Node};

/// Shape and cost of a BVH.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BvhStats {
    /// Distinct triangles referenced by the leaves.
    pub triangles: usize,
    /// References in the leaves: the triangles, plus one for each extra leaf that holds a
    /// part of a triangle split in space (the `sbvh` builder).
    pub references: usize,
    /// Inner nodes and leaves.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Deepest leaf (root = 0).
    pub max_depth: usize,
    /// Σ inner A/A_root·2·T_cube + Σ leaf A/A_root·N·T_obj.
    pub sah_cost: f64,
}

impl BvhStats {
    /// Walks the tree once.
    pub fn of(bvh: &Bvh, opts: &BuildOptions) -> BvhStats {
        let root_area = bvh.root.bbox().area() as f64;
        let norm = if root_area > 0.0 {
            1.0 / root_area
        } else {
            0.0
        };
        let (mut leaves, mut max_depth, mut cost) = (0, 0, 0.0f64);
        let mut stack = vec![(&bvh.root, 0usize)];
        while let Some((n, d)) = stack.pop() {
            let a = n.bbox().area() as f64 * norm;
            max_depth = max_depth.max(d);
            match n {
                Node::Leaf { count, .. } => {
                    leaves += 1;
                    cost += a * *count as f64 * opts.t_obj as f64;
                }
                Node::Inner { children, .. } => {
                    cost += a * 2.0 * opts.t_cube as f64;
                    stack.push((&children[0], d + 1));
                    stack.push((&children[1], d + 1));
                }
            }
        }
        BvhStats {
            triangles: distinct(&bvh.order),
            references: bvh.order.len(),
            nodes: bvh.root.nodes() as usize,
            leaves,
            max_depth,
            sah_cost: cost,
        }
    }
}

/// Distinct values in `ids` (one bit each up to the largest).
fn distinct(ids: &[u32]) -> usize {
    let Some(&max) = ids.iter().max() else {
        return 0;
    };
    let mut bits = vec![0u64; max as usize / 64 + 1];
    for &i in ids {
        bits[i as usize / 64] |= 1 << (i % 64);
    }
    bits.iter().map(|w| w.count_ones() as usize).sum()
}
