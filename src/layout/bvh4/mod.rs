//! `bvh4`: a 4-wide BVH collapsed from the binary SAH tree. Each node holds up to four
//! children with their boxes side by side (structure of arrays: the four x minima, the four
//! y minima, …: one node is eight 16-byte loads); a ray tests the used slots' boxes with the
//! shared slab test (`Aabb::slab_interval`, WGSL `slab_interval`), visits the children it
//! hits nearest first and pushes the others, with their entry distances, on the stack. A
//! child is an inner node or a leaf: a range of the shared [`LeafTri`]s, tested by the
//! shared leaf step.
//!
//! Node: 128 bytes (8 words of 16 bytes): six `[f32; 4]` box planes, four child references,
//! four child kinds. On the Stanford bunny (69,451 triangles, default sweep build): 8,598
//! nodes, 15.8 node bytes per triangle, 63.8 bytes per triangle with the 48-byte triangles
//! (the greedy collapse: 12,454 nodes, 71.0 bytes; `dfs-sign`: 49,177 nodes of 32 bytes,
//! 22.7 + 48).
//!
//! Collapse: the SAH dynamic programme of Ylitie, Karras & Laine 2017 for four slots
//! (`sah_collapse`), which also merges binary leaves into leaves of up to four triangles;
//! where its tree would be deeper than the stack holds (a degenerate binary tree), the
//! greedy collapse (`greedy_collapse`), whose depth is bounded by construction.
//!
//! Stack: a traversal holds at most three entries per 4-wide node on its current path.
//! 4-wide nodes lie at depth ≤ [`MAX_WIDE_DEPTH`] = 31 (binary inner nodes at depth
//! ≤ [`MAX_DEPTH`] − 1 = 63, and the greedy collapse halves that), and `STACK_SIZE` =
//! 3 · 32 = 96 entries hold any traversal; `validate` checks every node's depth against it. An entry is 8 bytes (node and slot, entry distance), the
//! stack 768 bytes; the kernel keeps it in a `var<private>`, zeroed once per invocation,
//! not per `traverse` call. (On lavapipe, a function-local stack of 192 12-byte entries
//! made the kernel ~10× slower than `dfs-sign` on the bunny's primary rays.)

mod greedy_collapse;
mod sah_collapse;
mod twin;

use crate::accel::bvh::{Bvh, MAX_DEPTH};
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

/// Deepest 4-wide node (the root at 0) whose traversal `STACK_SIZE` holds.
const MAX_WIDE_DEPTH: usize = STACK_SIZE / (WIDTH - 1) - 1;

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
        let nodes = sah_collapse::collapse(&bvh.root, MAX_WIDE_DEPTH)
            .unwrap_or_else(|| greedy_collapse::collapse(&bvh.root));
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

    /// A soup of 3000 small triangles in a 10-unit cube.
    fn soup() -> Mesh {
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
        Mesh::from_triangles(tris)
    }

    /// The SAH cost the collapses weigh: C_NODE·area per node, C_TRI·area per leaf triangle.
    fn sah_cost(nodes: &[Bvh4Node]) -> f64 {
        let mut cost = 0.0;
        for n in nodes {
            let used = (0..WIDTH).filter(|&k| n.kind[k] != 0);
            let bbox = used.clone().fold(Aabb::EMPTY, |b, k| b.union(n.bbox(k)));
            cost += (sah_collapse::C_NODE * bbox.area()) as f64;
            for k in used.filter(|&k| n.kind[k] != INNER) {
                cost += (sah_collapse::C_TRI * n.bbox(k).area() * n.kind[k] as f32) as f64;
            }
        }
        cost
    }

    #[test]
    fn the_sah_collapse_costs_no_more_than_the_greedy_one() {
        let mesh = soup();
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let tris = LeafTri::gather(&bvh, &mesh);
        let sah = sah_collapse::collapse(&bvh.root, MAX_WIDE_DEPTH).unwrap();
        let greedy = greedy_collapse::collapse(&bvh.root);
        assert_eq!(Bvh4::flatten(&bvh, &mesh).nodes, sah);
        for nodes in [&sah, &greedy] {
            let layout = Bvh4 {
                nodes: nodes.clone(),
                tris: tris.clone(),
            };
            layout.validate().unwrap();
        }
        // Optimal among the collapses that keep binary subtrees whole, of which the greedy
        // one is one; and it merges small leaves (the greedy collapse keeps the binary ones).
        let (s, g) = (sah_cost(&sah), sah_cost(&greedy));
        assert!(s <= g, "SAH collapse {s}, greedy {g}");
        assert!(
            sah.len() < greedy.len(),
            "{} nodes, greedy {}",
            sah.len(),
            greedy.len()
        );
        fn binary_leaves(n: &crate::accel::bvh::Node) -> usize {
            match n {
                crate::accel::bvh::Node::Leaf { .. } => 1,
                crate::accel::bvh::Node::Inner { children, .. } => {
                    binary_leaves(&children[0]) + binary_leaves(&children[1])
                }
            }
        }
        let leaves = |nodes: &[Bvh4Node]| {
            (nodes.iter().flat_map(|n| n.kind))
                .filter(|&k| k != INNER && k != 0)
                .count()
        };
        assert_eq!(leaves(&greedy), binary_leaves(&bvh.root));
        assert!(leaves(&sah) < binary_leaves(&bvh.root));
        // Too deep for a bound of 2 levels: none, and flatten takes the greedy collapse.
        assert!(sah_collapse::collapse(&bvh.root, 2).is_none());
    }

    #[test]
    fn a_soup_collapses_greedily_into_valid_nodes() {
        let mesh = soup();
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let layout = Bvh4 {
            nodes: greedy_collapse::collapse(&bvh.root),
            tris: LeafTri::gather(&bvh, &mesh),
        };
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
