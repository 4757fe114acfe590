use serde::Serialize;

use super::{BuildOptions, FlatBvh};

/// Shape and cost of a flattened BVH.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BvhStats {
    pub triangles: usize,
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    /// Σ inner A/A_root·2·T_cube + Σ leaf A/A_root·N·T_obj.
    pub sah_cost: f64,
    pub bytes: usize,
}

impl BvhStats {
    pub fn of(flat: &FlatBvh, opts: &BuildOptions) -> BvhStats {
        let root_area = flat.nodes[0].bbox().area() as f64;
        let norm = if root_area > 0.0 {
            1.0 / root_area
        } else {
            0.0
        };
        let (mut leaves, mut max_depth, mut cost) = (0, 0, 0.0f64);
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            let n = &flat.nodes[i];
            let a = n.bbox().area() as f64 * norm;
            max_depth = max_depth.max(d);
            if n.is_leaf() {
                leaves += 1;
                cost += a * n.count() as f64 * opts.t_obj as f64;
            } else {
                cost += a * 2.0 * opts.t_cube as f64;
                stack.push((i + 1, d + 1));
                stack.push((n.a as usize, d + 1));
            }
        }
        BvhStats {
            triangles: flat.tris.len(),
            nodes: flat.nodes.len(),
            leaves,
            max_depth,
            sah_cost: cost,
            bytes: flat.bytes(),
        }
    }
}
