//! The default GPU layout: 32-byte nodes in depth-first pre-order. An inner node's first
//! child is at i + 1 and holds the low side of the split axis; the second child's index and
//! the split axis are stored. A leaf holds (first, count) into the triangle array, which is
//! in leaf order; every triangle keeps its original index.

use crate::geometry::{Aabb, Triangle};
use crate::scene::Mesh;

use super::{Bvh, Node, MAX_DEPTH};

/// Low two bits of `GpuNode::b` equal to this mark a leaf; otherwise they are the axis.
pub const LEAF_TAG: u32 = 3;

/// One node, 32 bytes (WGSL `Node` in shaders/common.wgsl).
/// Inner: `a` = second child index, `b` = split axis (0..=2).
/// Leaf: `a` = first triangle, `b` = count << 2 | LEAF_TAG.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuNode {
    pub lo: [f32; 3],
    pub a: u32,
    pub hi: [f32; 3],
    pub b: u32,
}

impl GpuNode {
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == LEAF_TAG
    }
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }
    pub fn count(&self) -> u32 {
        self.b >> 2
    }
    pub fn bbox(&self) -> Aabb {
        Aabb {
            lo: self.lo.into(),
            hi: self.hi.into(),
        }
    }
}

/// One triangle, 48 bytes (WGSL `Tri`): three vertices, the original index in v0's slot w.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuTri {
    pub v0: [f32; 3],
    pub prim: u32,
    pub v1: [f32; 3],
    pub _pad1: u32,
    pub v2: [f32; 3],
    pub _pad2: u32,
}

impl GpuTri {
    pub fn triangle(&self) -> Triangle {
        Triangle::new(self.v0.into(), self.v1.into(), self.v2.into())
    }
}

/// A flattened BVH, ready for the CPU tracer or upload.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlatBvh {
    pub nodes: Vec<GpuNode>,
    pub tris: Vec<GpuTri>,
}

impl FlatBvh {
    pub fn new(bvh: &Bvh, mesh: &Mesh) -> FlatBvh {
        use rayon::prelude::*;
        let tris = bvh
            .order
            .par_iter()
            .map(|&id| {
                let t = &mesh.triangles[id as usize];
                GpuTri {
                    v0: t.v[0].into(),
                    prim: id,
                    v1: t.v[1].into(),
                    _pad1: 0,
                    v2: t.v[2].into(),
                    _pad2: 0,
                }
            })
            .collect();
        // Every subtree knows its size, so each writes its own part of the array; the big
        // ones on all threads (most of the time here is first touches of fresh pages).
        let mut nodes = bytemuck::zeroed_vec(bvh.root.nodes() as usize);
        write(&bvh.root, &mut nodes, 0);
        FlatBvh { nodes, tris }
    }

    /// Bytes the GPU holds for this BVH.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice()) + std::mem::size_of_val(self.tris.as_slice())
    }

    /// Checks every invariant traversal relies on (child indices in range and forward, leaf
    /// ranges in range, depth ≤ MAX_DEPTH). Run before handing the BVH to an unchecked GPU
    /// module; an error names the first bad node.
    pub fn validate(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("BVH has no nodes".into());
        }
        let mut stack = vec![(0usize, 0usize, self.nodes.len())];
        let mut seen = 0usize;
        while let Some((i, depth, end)) = stack.pop() {
            seen += 1;
            if depth > MAX_DEPTH {
                return Err(format!("node {i} is at depth {depth} > {MAX_DEPTH}"));
            }
            let n = &self.nodes[i];
            if n.is_leaf() {
                let (first, count) = (n.a as usize, n.count() as usize);
                if first + count > self.tris.len() {
                    return Err(format!(
                        "leaf {i} refers to triangles {first}..{} of {}",
                        first + count,
                        self.tris.len()
                    ));
                }
            } else {
                let second = n.a as usize;
                if i + 1 >= second || second >= end {
                    return Err(format!(
                        "inner node {i} has second child {second} outside {}..{end}",
                        i + 2
                    ));
                }
                stack.push((i + 1, depth + 1, second));
                stack.push((second, depth + 1, end));
            }
        }
        if seen != self.nodes.len() {
            return Err(format!(
                "{} of {} nodes are unreachable",
                self.nodes.len() - seen,
                self.nodes.len()
            ));
        }
        Ok(())
    }
}

/// Subtrees with at least this many nodes are written in parallel.
const PARALLEL_NODES: usize = 1 << 12;

/// Writes `node`'s subtree in pre-order into `out` (exactly its size), whose first element
/// is node `index` of the whole array.
fn write(node: &Node, out: &mut [GpuNode], index: u32) {
    let b = node.bbox();
    let (a, tag, children) = match node {
        Node::Leaf { start, count, .. } => (*start, count << 2 | LEAF_TAG, None),
        Node::Inner { axis, children, .. } => {
            let second = index + 1 + children[0].nodes();
            (second, *axis as u32, Some(children))
        }
    };
    let (head, rest) = out.split_first_mut().expect("a subtree has a node");
    *head = GpuNode {
        lo: b.lo.into(),
        a,
        hi: b.hi.into(),
        b: tag,
    };
    if let Some([l, r]) = children.map(|c| &**c) {
        let big = rest.len() >= PARALLEL_NODES;
        let (lo, hi) = rest.split_at_mut(l.nodes() as usize);
        if big {
            rayon::join(|| write(l, lo, index + 1), || write(r, hi, a));
        } else {
            write(l, lo, index + 1);
            write(r, hi, a);
        }
    }
}

impl GpuTri {
    /// An all-zero triangle (degenerate, never hit), padding an otherwise empty buffer.
    pub fn zeroed_tri() -> GpuTri {
        bytemuck::Zeroable::zeroed()
    }
}
