//! A binary tree of merges over primitives, as PLOC's clustering and LBVH's radix tree
//! produce it (node `i < n` is primitive `i`'s leaf, later nodes are merges), made into
//! lancer's tree: leaves wherever the SAH prefers them, children low side first.

use super::tree::{children_order, leaf, Node};
use super::BuildOptions;
use crate::geometry::Aabb;

/// The clustered binary tree: node `i < n` is primitive `i`'s leaf; later nodes are merges.
pub(crate) struct Clusters {
    pub bbox: Vec<Aabb>,
    pub kids: Vec<[u32; 2]>,
}

/// Depth of the deepest leaf under `root`, without recursion (a clustered tree may be deep).
fn depth(tree: &Clusters, root: u32, n: usize) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(root, 0usize)];
    while let Some((k, d)) = stack.pop() {
        deepest = deepest.max(d);
        if k as usize >= n {
            for c in tree.kids[k as usize] {
                stack.push((c, d + 1));
            }
        }
    }
    deepest
}

/// The lancer tree: leaves where the SAH prefers them, children ordered low side first;
/// None when the clustered tree is deeper than the cap.
pub(crate) fn to_node(
    what: &str,
    tree: &Clusters,
    root: u32,
    n: usize,
    opts: &BuildOptions,
) -> Option<(Node, Vec<u32>)> {
    let d = depth(tree, root, n);
    if d > opts.max_depth.min(super::MAX_DEPTH) {
        log::warn!(
            "the {what} tree is {d} levels deep, more than the stack holds: built with binned SAH"
        );
        return None;
    }
    let mut order = Vec::with_capacity(n);
    let (node, _, _) = convert(tree, root, n, opts, &mut order);
    Some((node, order))
}

/// Node `k` as a lancer node (appending its primitives to `order`), with its primitive
/// count and its SAH cost times its own area. No division: the GPU's flatten of the LBVH
/// (`lbvh.wgsl`), where a division rounds more loosely, makes the same choices.
fn convert(
    tree: &Clusters,
    k: u32,
    n: usize,
    opts: &BuildOptions,
    order: &mut Vec<u32>,
) -> (Node, usize, f32) {
    let bbox = tree.bbox[k as usize];
    let area = bbox.area();
    let start = order.len();
    if (k as usize) < n {
        order.push(k);
        return (leaf(bbox, start, 1), 1, opts.t_obj * area);
    }
    let [a, b] = tree.kids[k as usize];
    let (axis, swap) = children_order(&tree.bbox[a as usize], &tree.bbox[b as usize]);
    let (a, b) = if swap { (b, a) } else { (a, b) };
    let (l, nl, cl) = convert(tree, a, n, opts, order);
    let (r, nr, cr) = convert(tree, b, n, opts, order);
    let count = nl + nr;
    // T·A = 2·T_cube·A + T_L·A_L + T_R·A_R; a leaf costs N·T_obj·A (`prefers_leaf`, times A).
    let split = 2.0 * opts.t_cube * area + cl + cr;
    let as_leaf = count as f32 * opts.t_obj * area;
    if count <= opts.max_leaf.max(1) && as_leaf <= split {
        return (leaf(bbox, start, count), count, as_leaf);
    }
    (Node::inner(bbox, axis, [l, r]), count, split)
}
