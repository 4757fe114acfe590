//! A binary tree of merges over primitives, as PLOC's clustering and LBVH's radix tree
//! produce it (node `i < n` is primitive `i`'s leaf, later nodes are merges), made into
//! lancer's tree: leaves wherever the SAH prefers them, children low side first.

use std::sync::atomic::AtomicU32;
use std::sync::atomic::Ordering::Relaxed;

use super::tree::{children_order, leaf, Kids, Node};
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
    // Each subtree's primitive count, so that subtrees convert on all threads, each into
    // its own part of the order.
    let counts: Vec<AtomicU32> = (0..tree.kids.len()).map(|_| AtomicU32::new(1)).collect();
    count(tree, root, n, opts.parallel, 0, &counts);
    let mut order = vec![0; counts[root as usize].load(Relaxed) as usize];
    let (node, _, _) = convert(tree, root, n, opts, &counts, &mut order, 0, 0);
    Some((node, order))
}

/// Subtrees this shallow are counted and converted in parallel (2^8 tasks at most).
const PARALLEL_DEPTH: usize = 8;

/// Primitives under node `k` (kept in `counts` for inner nodes; a leaf's stays 1).
fn count(
    tree: &Clusters,
    k: u32,
    n: usize,
    parallel: bool,
    depth: usize,
    counts: &[AtomicU32],
) -> u32 {
    if (k as usize) < n {
        return 1;
    }
    let [a, b] = tree.kids[k as usize];
    let go = |c: u32| count(tree, c, n, parallel, depth + 1, counts);
    let (ca, cb) = match parallel && depth < PARALLEL_DEPTH {
        true => rayon::join(|| go(a), || go(b)),
        false => (go(a), go(b)),
    };
    counts[k as usize].store(ca + cb, Relaxed);
    ca + cb
}

/// Node `k` as a lancer node whose primitives fill `order` (its part of the whole order,
/// which starts at `start`), with its primitive count and its SAH cost times its own area.
/// No division: the GPU's flatten of the LBVH (`lbvh.wgsl`), where a division rounds more
/// loosely, makes the same choices.
#[allow(clippy::too_many_arguments)]
fn convert(
    tree: &Clusters,
    k: u32,
    n: usize,
    opts: &BuildOptions,
    counts: &[AtomicU32],
    order: &mut [u32],
    start: usize,
    depth: usize,
) -> (Node, usize, f32) {
    let bbox = tree.bbox[k as usize];
    let area = bbox.area();
    if (k as usize) < n {
        order[0] = k;
        return (leaf(bbox, start, 1), 1, opts.t_obj * area);
    }
    let [a, b] = tree.kids[k as usize];
    let (axis, swap) = children_order(&tree.bbox[a as usize], &tree.bbox[b as usize]);
    let (a, b) = if swap { (b, a) } else { (a, b) };
    let na = counts[a as usize].load(Relaxed) as usize;
    let (left, right) = order.split_at_mut(na);
    // Reserved before the children are built (see `Kids`); freed again if this becomes a leaf.
    let kids = Kids::reserve();
    let go = |c: u32, part: &mut [u32], at: usize| {
        convert(tree, c, n, opts, counts, part, at, depth + 1)
    };
    let ((l, nl, cl), (r, nr, cr)) = match opts.parallel && depth < PARALLEL_DEPTH {
        true => rayon::join(|| go(a, left, start), || go(b, right, start + na)),
        false => (go(a, left, start), go(b, right, start + na)),
    };
    let count = nl + nr;
    // T·A = 2·T_cube·A + T_L·A_L + T_R·A_R; a leaf costs N·T_obj·A (`prefers_leaf`, times A).
    let split = 2.0 * opts.t_cube * area + cl + cr;
    let as_leaf = count as f32 * opts.t_obj * area;
    if count <= opts.max_leaf.max(1) && as_leaf <= split {
        return (leaf(bbox, start, count), count, as_leaf);
    }
    (kids.inner(bbox, axis, [l, r]), count, split)
}
