//! `bvh4`: a 4-wide BVH collapsed from the binary SAH tree. Each node holds up to four
//! children with their boxes side by side (structure of arrays: the four x minima, the four
//! y minima, …: one node is eight 16-byte loads); a ray tests the used slots' boxes with the
//! shared slab test (`Aabb::slab_interval`, WGSL `slab_interval`), visits the children it
//! hits nearest first and pushes the others, with their entry distances, on the stack. A
//! child is an inner node or a leaf: a range of the shared [`LeafTri`]s, tested by the
//! shared leaf step.
//!
//! Node: 128 bytes (8 words of 16 bytes): six `[f32; 4]` box planes, four child references,
//! four child kinds. On the Stanford bunny (69,451 triangles, default sweep build): 12,454
//! nodes of 2.97 children on average, 23.0 node bytes per triangle, 71.0 bytes per
//! triangle with the 48-byte triangles (`dfs-sign`: 49,177 nodes of 32 bytes, 22.7 + 48).
//!
//! Collapse (Wald, Benthin & Boulos 2008, "Getting rid of packets"; tinybvh's
//! `ConvertBVH4`): a node starts with its binary node's two children and, while it has
//! fewer than four, the inner child with the largest surface area is replaced by its two
//! children. A 4-wide node costs one visit whatever its number of children, so pulling up
//! child C removes C's own visit, taken with probability area(C)/area(root): the largest
//! area is the greedy SAH choice. One rule comes first, for the stack: a node at 4-wide
//! depth d comes from a binary node at depth b ≥ 2d (an inner child one binary level down
//! that would break this is pulled up before the greedy choice).
//!
//! Stack: a traversal holds at most three entries per 4-wide node on its current path.
//! Binary inner nodes lie at depth ≤ [`MAX_DEPTH`] − 1 = 63, so 4-wide nodes at depth
//! ≤ 31, and `STACK_SIZE` = 3 · 32 = 96 entries hold any traversal; `validate` checks
//! every node's depth against it. An entry is 8 bytes (node and slot, entry distance), the
//! stack 768 bytes; the kernel keeps it in a `var<private>`, zeroed once per invocation,
//! not per `traverse` call. (On lavapipe, a function-local stack of 192 12-byte entries
//! made the kernel ~10× slower than `dfs-sign` on the bunny's primary rays.)

mod twin;

use crate::accel::bvh::{Bvh, Node, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::mesh::Mesh;

use super::{LayoutArrays, LayoutKind, LeafTri};

/// Children per node.
const WIDTH: usize = 4;

/// Bytes of one node record (what `RayStats::nodes` counts loads of).
pub(crate) const NODE_BYTES: usize = std::mem::size_of::<Bvh4Node>();

// The size the module doc states, a whole number of the GPU's 16-byte words.
const _: () = assert!(NODE_BYTES == 128 && NODE_BYTES.is_multiple_of(16));

/// `Bvh4Node::kind` of an inner child (generated into the WGSL as `BVH4_INNER`); 0 is an
/// unused slot, anything else the triangle count of a leaf.
pub(crate) const INNER: u32 = u32::MAX;

/// Bits of a stack entry that name the slot (generated into the WGSL as `BVH4_SLOT_BITS`):
/// an entry is `node << SLOT_BITS | slot`.
pub(crate) const SLOT_BITS: u32 = WIDTH.trailing_zeros();
const _: () = assert!(1 << SLOT_BITS == WIDTH);

/// The slot of a stack entry.
pub(crate) const SLOT_MASK: u32 = (1 << SLOT_BITS) - 1;

/// Most nodes a layout may have: the node indices a stack entry can name (4 GiB of nodes,
/// past any binding limit).
const MAX_NODES: usize = 1 << (32 - SLOT_BITS);

/// Traversal stack entries (generated into the WGSL as `BVH4_STACK_SIZE`): three per level
/// for 4-wide depths 0..=31 (see the module doc).
pub(crate) const STACK_SIZE: usize = (WIDTH - 1) * MAX_DEPTH / 2;

/// One node, 128 bytes (WGSL `Bvh4Node` in bvh4.wgsl). Slot k's box is
/// (`lo_x[k]`, `lo_y[k]`, `lo_z[k]`)–(`hi_x[k]`, …). `kind[k]`: [`INNER`] (`child[k]` is a
/// node index), 0 (unused slot: zero box, never entered) or a leaf's triangle count
/// (`child[k]` is its first triangle).
// Aligned to cache lines, so that a node is two of them, not three (a few % of the CPU
// twin's rays/s).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Bvh4Node {
    pub lo_x: [f32; WIDTH],
    pub lo_y: [f32; WIDTH],
    pub lo_z: [f32; WIDTH],
    pub hi_x: [f32; WIDTH],
    pub hi_y: [f32; WIDTH],
    pub hi_z: [f32; WIDTH],
    pub child: [u32; WIDTH],
    pub kind: [u32; WIDTH],
}

impl Bvh4Node {
    /// Slot k's box.
    fn bbox(&self, k: usize) -> Aabb {
        Aabb {
            lo: glam::Vec3::new(self.lo_x[k], self.lo_y[k], self.lo_z[k]),
            hi: glam::Vec3::new(self.hi_x[k], self.hi_y[k], self.hi_z[k]),
        }
    }

    fn set_bbox(&mut self, k: usize, b: &Aabb) {
        (self.lo_x[k], self.lo_y[k], self.lo_z[k]) = (b.lo.x, b.lo.y, b.lo.z);
        (self.hi_x[k], self.hi_y[k], self.hi_z[k]) = (b.hi.x, b.hi.y, b.hi.z);
    }
}

/// A BVH flattened in the `bvh4` layout; its [`Accel`](crate::accel::Accel) is the CPU twin
/// of `bvh4.wgsl`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh4 {
    nodes: Vec<Bvh4Node>,
    tris: Vec<LeafTri>,
}

impl Bvh4 {
    /// Collapses a built binary tree into 4-wide nodes, in depth-first pre-order (the root
    /// at 0).
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> Bvh4 {
        let tris = LeafTri::gather(bvh, mesh);
        // About one 4-wide node per three binary inner nodes.
        let mut nodes = Vec::with_capacity(bvh.root.nodes() as usize / 6 + 1);
        emit(&bvh.root, 0, 0, &mut nodes);
        Bvh4 { nodes, tris }
    }

    /// A layout from raw arrays (as [`arrays`](super::Layout::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::Layout::validate).
    pub fn from_arrays(arrays: LayoutArrays<'_>) -> Result<Bvh4, String> {
        let (nodes, tris) = super::records(arrays)?;
        let layout = Bvh4 { nodes, tris };
        super::Layout::validate(&layout)?;
        Ok(layout)
    }
}

/// The binary nodes that become the children of `node`'s 4-wide node, left to right, each
/// with its binary depth; `node` is at binary depth `b` and becomes a 4-wide node at depth
/// `d` ≤ b / 2. First an inner child that would break d ≤ b / 2 one level down is replaced
/// by its two children (at most both children are, which makes four); then, while there
/// are fewer than four, the inner child of largest area (the first among equals). A leaf
/// (the root of a tiny tree) is its own single child.
fn collapse(node: &Node, d: usize, b: usize) -> Vec<(&Node, usize)> {
    let Node::Inner { children, .. } = node else {
        return vec![(node, b)];
    };
    let mut slots: Vec<(&Node, usize)> = children.iter().map(|c| (c, b + 1)).collect();
    let mut k = 0;
    while k < slots.len() {
        match slots[k] {
            (Node::Inner { children, .. }, bc) if d + 1 > bc / 2 => {
                slots.splice(k..=k, children.iter().map(|c| (c, bc + 1)));
            }
            _ => k += 1,
        }
    }
    while slots.len() < WIDTH {
        let mut pick: Option<(usize, f32)> = None;
        for (k, (c, _)) in slots.iter().enumerate() {
            if matches!(c, Node::Inner { .. }) {
                let a = c.bbox().area();
                if pick.is_none_or(|(_, best)| a > best) {
                    pick = Some((k, a));
                }
            }
        }
        let Some((k, _)) = pick else { break };
        if let (Node::Inner { children, .. }, bc) = slots[k] {
            slots.splice(k..=k, children.iter().map(|c| (c, bc + 1)));
        }
    }
    slots
}

/// Appends the 4-wide subtree of `node` (at binary depth `b`, 4-wide depth `d`) to `out`
/// in pre-order; returns its index.
fn emit(node: &Node, d: usize, b: usize, out: &mut Vec<Bvh4Node>) -> u32 {
    let index = out.len();
    out.push(bytemuck::Zeroable::zeroed());
    let mut rec: Bvh4Node = bytemuck::Zeroable::zeroed();
    for (k, (c, bc)) in collapse(node, d, b).into_iter().enumerate() {
        match c {
            Node::Leaf { bbox, start, count } => {
                // An empty leaf (the root of an empty tree) is an unused slot.
                if *count > 0 {
                    rec.set_bbox(k, bbox);
                    (rec.child[k], rec.kind[k]) = (*start, *count);
                }
            }
            Node::Inner { bbox, .. } => {
                rec.set_bbox(k, bbox);
                (rec.child[k], rec.kind[k]) = (emit(c, d + 1, bc, out), INNER);
            }
        }
    }
    out[index] = rec;
    index as u32
}

impl super::Layout for Bvh4 {
    fn name(&self) -> &'static str {
        LayoutKind::Bvh4.name()
    }

    fn node_bytes(&self) -> usize {
        NODE_BYTES
    }

    fn arrays(&self) -> LayoutArrays<'_> {
        LayoutArrays::of(&self.nodes, &self.tris)
    }

    fn wgsl(&self) -> String {
        format!(
            "const BVH4_INNER: u32 = {INNER}u;\n\
             const BVH4_STACK_SIZE: u32 = {STACK_SIZE}u;\n\
             const BVH4_NODE_WORDS: u32 = {}u;\n\
             const BVH4_SLOT_BITS: u32 = {SLOT_BITS}u;\n{}",
            NODE_BYTES / 16,
            include_str!("bvh4.wgsl")
        )
    }

    /// Every node reached once from the root through forward child indices, at a depth whose
    /// three pushes per level fit `STACK_SIZE`; used slots have finite boxes holding their
    /// leaves' triangles; leaf ranges tile the triangle array.
    fn validate(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("BVH has no nodes".into());
        }
        // Stack entries hold node << SLOT_BITS | slot.
        if self.nodes.len() > MAX_NODES {
            return Err(format!(
                "{} nodes, more than the {MAX_NODES} a stack entry can name",
                self.nodes.len()
            ));
        }
        let mut reached = vec![false; self.nodes.len()];
        let mut ranges = Vec::new();
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, depth)) = stack.pop() {
            if reached[i] {
                return Err(format!("node {i} is reached twice"));
            }
            reached[i] = true;
            // Entries on the stack while node i is processed: ≤ 3 per ancestor, 3 of its own.
            if WIDTH.saturating_sub(1) * (depth + 1) > STACK_SIZE {
                return Err(format!(
                    "node {i} is at depth {depth}: its traversal may need more than \
                     {STACK_SIZE} stack entries"
                ));
            }
            let n = &self.nodes[i];
            for k in 0..WIDTH {
                let (child, kind) = (n.child[k] as usize, n.kind[k]);
                if kind == 0 {
                    continue;
                }
                let b = n.bbox(k);
                if !(b.lo.is_finite() && b.hi.is_finite()) {
                    return Err(format!("node {i} slot {k} has a non-finite box {b:?}"));
                }
                if kind == INNER {
                    if child <= i || child >= self.nodes.len() {
                        return Err(format!(
                            "node {i} slot {k} refers to node {child} outside {}..{}",
                            i + 1,
                            self.nodes.len()
                        ));
                    }
                    stack.push((child, depth + 1));
                    continue;
                }
                let end = child + kind as usize;
                let Some(tris) = self.tris.get(child..end) else {
                    return Err(format!(
                        "node {i} slot {k} refers to triangles {child}..{end} of {}",
                        self.tris.len()
                    ));
                };
                if let Some(t) = tris.iter().find(|t| {
                    let tb = Aabb::from_points(&t.triangle().v);
                    !b.contains(&tb)
                }) {
                    return Err(format!(
                        "node {i} slot {k}: triangle {} lies outside the box {b:?}",
                        t.prim
                    ));
                }
                ranges.push((child, end));
            }
        }
        if let Some(i) = reached.iter().position(|&r| !r) {
            return Err(format!(
                "node {i} (one of {} nodes) is unreachable",
                self.nodes.len()
            ));
        }
        ranges.sort_unstable();
        let mut next = 0;
        for (first, end) in ranges {
            if first < next {
                return Err(format!("triangles {first}..{next} are in two leaves"));
            }
            if first > next {
                return Err(format!("triangles {next}..{first} are in no leaf"));
            }
            next = end;
        }
        if next != self.tris.len() {
            return Err(format!(
                "triangles {next}..{} are in no leaf",
                self.tris.len()
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;
    use crate::layout::Layout;

    fn layout(mesh: &Mesh) -> Bvh4 {
        Bvh4::flatten(&crate::accel::bvh::build(mesh, &Default::default()), mesh)
    }

    #[test]
    fn the_wgsl_node_matches_the_rust_node() {
        let mesh = Mesh::from_triangles(vec![Triangle::new(
            glam::Vec3::ZERO,
            glam::Vec3::X,
            glam::Vec3::Y,
        )]);
        let layout = layout(&mesh);
        let src = shaders::trace_source(&layout);
        let fields = [
            ("lo_x", offset_of!(Bvh4Node, lo_x)),
            ("lo_y", offset_of!(Bvh4Node, lo_y)),
            ("lo_z", offset_of!(Bvh4Node, lo_z)),
            ("hi_x", offset_of!(Bvh4Node, hi_x)),
            ("hi_y", offset_of!(Bvh4Node, hi_y)),
            ("hi_z", offset_of!(Bvh4Node, hi_z)),
            ("child", offset_of!(Bvh4Node, child)),
            ("kind", offset_of!(Bvh4Node, kind)),
        ];
        shaders::check_struct(&src, "Bvh4Node", size_of::<Bvh4Node>(), &fields).unwrap();
        assert!(NODE_BYTES.is_multiple_of(16));
        assert!(layout.validate().is_ok());
    }

    #[test]
    fn a_soup_collapses_greedily_into_valid_nodes() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut f = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let tris = (0..3000)
            .map(|_| {
                let c = glam::Vec3::new(f(), f(), f()) * 10.0;
                let mut v = || c + glam::Vec3::new(f(), f(), f()) * 0.3;
                Triangle::new(v(), v(), v())
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let layout = Bvh4::flatten(&bvh, &mesh);
        layout.validate().unwrap();
        // The collapse stops short of four children only when all of them are leaves.
        for (i, n) in layout.nodes.iter().enumerate() {
            let used = n.kind.iter().filter(|&&k| k != 0).count();
            assert!(
                used == WIDTH || !n.kind.contains(&INNER),
                "node {i} has {used} children, some inner"
            );
        }
        // Every binary inner node is a 4-wide node or pulled up into one, which gained one
        // child per node pulled up: Σ (children − 1) = binary inner nodes.
        let binary_inner = (bvh.root.nodes() as usize - 1) / 2;
        let slots: usize = (layout.nodes.iter())
            .map(|n| n.kind.iter().filter(|&&k| k != 0).count() - 1)
            .sum();
        assert_eq!(slots, binary_inner);
        assert!(layout.nodes.len() < binary_inner);
        // Each slot's box is its binary node's box: the children of one node tile its
        // parent slot's box.
        for n in &layout.nodes {
            for k in 0..WIDTH {
                if n.kind[k] == INNER {
                    let c = &layout.nodes[n.child[k] as usize];
                    let u = (0..WIDTH)
                        .filter(|&j| c.kind[j] != 0)
                        .fold(Aabb::EMPTY, |u, j| u.union(c.bbox(j)));
                    assert_eq!(u, n.bbox(k));
                }
            }
        }
    }
}
