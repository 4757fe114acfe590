//! `bvh4` and `bvh8`: W-wide BVHs (W = 4 or 8) collapsed from the binary SAH tree, one
//! program for both widths. Each node holds up to W children with their boxes side by side
//! (structure of arrays: the W x minima, the W y minima, …); a ray tests the used slots'
//! boxes with the shared slab test (`Aabb::slab_interval`, WGSL `slab_interval`), visits
//! the children it hits nearest first and pushes the others, with their entry distances,
//! on the stack. A child is an inner node or a leaf: a range of the shared [`LeafTri`]s,
//! tested by the shared leaf step.
//!
//! Node: 32·W bytes (2·W words of 16 bytes): six `[f32; W]` box planes, W child references,
//! W child kinds. On the Stanford bunny (69,451 triangles, default sweep build), with the
//! 48-byte triangles: `bvh4` 8,598 nodes of 128 bytes, 63.8 bytes per triangle; `bvh8`
//! 4,313 nodes of 256 bytes, 63.9 (`dfs-sign`: 49,177 nodes of 32 bytes, 22.7 + 48).
//! A wider node costs more per visit and is visited less: on the bunny's primary rays that
//! hit, `bvh8`'s twin visits 6.2 nodes, `bvh4`'s 9.2.
//!
//! Collapse: the SAH dynamic programme of Ylitie, Karras & Laine 2017 for W slots
//! (`sah_collapse`), which also merges binary leaves into leaves of up to four triangles;
//! where its tree would be deeper than the stack holds (a degenerate binary tree), the
//! greedy collapse (`greedy_collapse`), whose depth is bounded by construction.
//!
//! Stack: a traversal holds at most W − 1 entries per wide node on its current path. The
//! greedy collapse makes a wide node at depth d from a binary node at depth b ≥ d·log2(W),
//! and binary inner nodes lie at depth ≤ [`MAX_DEPTH`] − 1 = 63, so wide nodes lie at depth
//! ≤ 63 / log2(W) (31 for bvh4, 21 for bvh8), and (W − 1) entries for each of those levels
//! (96 for bvh4, 154 for bvh8) hold any traversal; `validate` checks every node's depth
//! against it. An entry is 8 bytes (node and slot, entry distance); the kernel keeps the
//! stack in a `var<private>` of W − 1 entries for each level of the tree at hand (`depth`),
//! zeroed once per invocation, not per `traverse` call.
//! (On lavapipe, a function-local stack of 192 12-byte entries made bvh4's kernel ~10×
//! slower than `dfs-sign` on the bunny's primary rays.)

mod greedy_collapse;
mod sah_collapse;
mod twin;

use crate::accel::bvh::{Bvh, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::mesh::Mesh;

use super::validate_boxes::{check_boxes, node_zero, At, BoxTree, Child, Slot};
use super::{GpuArrays, LayoutKind, LeafTri};

/// A 4-wide BVH (the `bvh4` layout); its [`Accel`](crate::accel::Accel) is the CPU twin of
/// `wide_bvh.wgsl` for four slots.
pub type Bvh4 = WideBvh<4>;

/// An 8-wide BVH (the `bvh8` layout); its [`Accel`](crate::accel::Accel) is the CPU twin of
/// `wide_bvh.wgsl` for eight slots.
pub type Bvh8 = WideBvh<8>;

/// `WideNode::kind` of an inner child (generated into the WGSL as `WIDE_INNER`); 0 is an
/// unused slot, anything else the triangle count of a leaf.
pub(crate) const INNER: u32 = u32::MAX;

/// Binary levels one wide level spans: log2(W).
const fn levels_per_node(w: usize) -> usize {
    w.trailing_zeros() as usize
}

/// Deepest wide node (the root at 0) whose traversal the stack holds: the greedy
/// collapse's bound (see the module doc).
const fn max_wide_depth(w: usize) -> usize {
    (MAX_DEPTH - 1) / levels_per_node(w)
}

/// Stack entries a traversal holds at most while it visits a node at wide depth `depth`:
/// W − 1 for the node and for each of its ancestors (the kernel's `WIDE_STACK_SIZE` is
/// this for the tree's deepest node).
const fn stack_entries(w: usize, depth: usize) -> usize {
    (w - 1) * (depth + 1)
}

/// Traversal stack entries any valid tree needs at most (`validate`'s bound): W − 1 per
/// level for wide depths 0..=`max_wide_depth(w)`.
pub(crate) const fn stack_size(w: usize) -> usize {
    stack_entries(w, max_wide_depth(w))
}

/// The most stack entries either width needs (the twin's stack array; generic consts
/// cannot size an array).
pub(crate) const MAX_STACK_SIZE: usize = stack_size(8);
const _: () = assert!(stack_size(4) == 96 && MAX_STACK_SIZE == 154);

/// One node, 32·W bytes (WGSL `WideNode` in wide_bvh.wgsl). Slot k's box is
/// (`lo_x[k]`, `lo_y[k]`, `lo_z[k]`)–(`hi_x[k]`, …). `kind[k]`: [`INNER`] (`child[k]` is a
/// node index), 0 (unused slot: zero box, never entered) or a leaf's triangle count
/// (`child[k]` is its first triangle).
///
/// Public only so that [`WideBvh`]'s bounds can name it (it is not exported: the arrays
/// are [`GpuForm::arrays`](super::GpuForm::arrays)).
// Aligned to cache lines, so that a node spans W / 2 of them, not one more (a few % of
// the CPU twin's rays/s).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode<const W: usize> {
    pub(crate) lo_x: [f32; W],
    pub(crate) lo_y: [f32; W],
    pub(crate) lo_z: [f32; W],
    pub(crate) hi_x: [f32; W],
    pub(crate) hi_y: [f32; W],
    pub(crate) hi_z: [f32; W],
    pub(crate) child: [u32; W],
    pub(crate) kind: [u32; W],
}

/// `Pod` for the two widths whose nodes have no padding: eight W-word arrays, 32·W bytes,
/// a multiple of the 64-byte alignment and of the GPU's 16-byte words.
macro_rules! pod_width {
    ($($w:literal),*) => {$(
        const _: () = assert!(std::mem::size_of::<WideNode<$w>>() == 32 * $w);
        // SAFETY: `repr(C)`, only `f32`/`u32` arrays, and no padding (the size is the sum
        // of the fields', asserted above).
        unsafe impl bytemuck::Zeroable for WideNode<$w> {}
        // SAFETY: as above; any bit pattern is a valid `f32` or `u32`.
        unsafe impl bytemuck::Pod for WideNode<$w> {}
    )*};
}
pod_width!(4, 8);

impl<const W: usize> WideNode<W> {
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

    /// The bit set of the used slots.
    #[inline(always)]
    fn used(&self) -> u32 {
        let mut used = 0;
        for g in (0..W / 4).map(|i| 4 * i) {
            let four = glam::UVec4::from_slice(&self.kind[g..g + 4]);
            used |= four.cmpne(glam::UVec4::ZERO).bitmask() << g;
        }
        used
    }
}

/// A BVH flattened in the W-wide layout ([`Bvh4`] or [`Bvh8`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WideBvh<const W: usize> {
    nodes: Vec<WideNode<W>>,
    tris: Vec<LeafTri>,
}

impl<const W: usize> WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    /// Bytes of one node record (what `RayStats::nodes` counts loads of).
    pub(crate) const NODE_BYTES: usize = std::mem::size_of::<WideNode<W>>();

    /// Bits of a stack entry that name the slot (generated into the WGSL as
    /// `WIDE_SLOT_BITS`): an entry is `node << SLOT_BITS | slot`.
    pub(crate) const SLOT_BITS: u32 = W.trailing_zeros();

    /// Most nodes a layout may have: the node indices a stack entry can name (past any
    /// binding limit).
    const MAX_NODES: usize = 1 << (32 - Self::SLOT_BITS);

    /// The registry's name for this width.
    fn kind() -> LayoutKind {
        match W {
            4 => LayoutKind::Bvh4,
            _ => LayoutKind::Bvh8,
        }
    }

    /// Collapses a built binary tree into W-wide nodes, in depth-first pre-order (the root
    /// at 0).
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> WideBvh<W> {
        // The triangles and the nodes are independent: gathered and collapsed side by side.
        let (tris, nodes) = rayon::join(
            || LeafTri::gather(bvh, mesh),
            || {
                sah_collapse::collapse(&bvh.root, max_wide_depth(W))
                    .unwrap_or_else(|| greedy_collapse::collapse(&bvh.root))
            },
        );
        WideBvh { nodes, tris }
    }

    /// The depth of the deepest node (the root at 0): the kernel's stack holds W − 1
    /// entries for each level down to it, not for the deepest tree the builders allow, as
    /// WGSL zero-fills a private array at every invocation (bvh8's 154 entries: 1,232 bytes
    /// a ray). Children come after their parents (as `validate` requires; a child that
    /// does not is skipped here).
    fn depth(&self) -> usize {
        let mut depth = vec![0usize; self.nodes.len()];
        let mut deepest = 0;
        for (i, n) in self.nodes.iter().enumerate() {
            for k in 0..W {
                let c = n.child[k] as usize;
                if n.kind[k] == INNER && c > i && c < depth.len() {
                    depth[c] = depth[i] + 1;
                    deepest = deepest.max(depth[c]);
                }
            }
        }
        deepest
    }

    /// A layout from raw arrays (as [`arrays`](super::GpuForm::arrays) gives them), refused
    /// unless they are whole records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<WideBvh<W>, String> {
        let (nodes, tris) = super::records(arrays)?;
        let layout = WideBvh { nodes, tris };
        super::GpuForm::validate(&layout)?;
        Ok(layout)
    }
}

impl<const W: usize> super::GpuForm for WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    fn name(&self) -> &'static str {
        Self::kind().name()
    }

    fn node_bytes(&self) -> usize {
        Self::NODE_BYTES
    }

    fn arrays(&self) -> GpuArrays<'_> {
        GpuArrays::of(&self.nodes, &self.tris)
    }

    /// `WIDE_STACK_SIZE` holds W − 1 entries for each level of this tree.
    fn stack_depth(&self) -> usize {
        self.depth()
    }

    fn wgsl(&self) -> String {
        format!(
            "const WIDE_INNER: u32 = {INNER}u;\n\
             const WIDE_WIDTH: u32 = {W}u;\n\
             const WIDE_GROUPS: u32 = {}u;\n\
             const WIDE_STACK_SIZE: u32 = {}u;\n\
             const WIDE_NODE_WORDS: u32 = {}u;\n\
             const WIDE_SLOT_BITS: u32 = {}u;\n{}",
            W / 4,
            stack_entries(W, self.depth()),
            Self::NODE_BYTES / 16,
            Self::SLOT_BITS,
            include_str!("wide_bvh.wgsl")
        )
    }

    /// Every node reached once from the root through forward child indices, at a depth whose
    /// W − 1 pushes per level fit the stack; used slots have finite boxes; then every slot's
    /// box holds the triangles below it and the leaves cover the triangle array once
    /// (`check_boxes`).
    fn validate(&self) -> Result<(), String> {
        self.check_structure()?;
        check_boxes(self)
    }
}

impl<const W: usize> BoxTree for WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    /// Node 0, whose slots the traversal tests first.
    fn roots(&self) -> impl Iterator<Item = Slot> + '_ {
        node_zero()
    }

    fn slots(&self, node: u32) -> impl Iterator<Item = Slot> + '_ {
        let n = &self.nodes[node as usize];
        (0..W).filter(move |&k| n.kind[k] != 0).map(move |k| Slot {
            bbox: Some(n.bbox(k)),
            child: match n.kind[k] {
                INNER => Child::Node(n.child[k]),
                count => Child::Tris {
                    first: n.child[k],
                    count,
                },
            },
            at: At::Slot {
                node,
                slot: k as u32,
            },
        })
    }

    fn tris(&self) -> &[LeafTri] {
        &self.tris
    }
}

impl<const W: usize> WideBvh<W>
where
    WideNode<W>: bytemuck::Pod,
{
    /// [`validate`](super::GpuForm::validate)'s structural checks.
    fn check_structure(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("BVH has no nodes".into());
        }
        // Stack entries hold node << SLOT_BITS | slot.
        if self.nodes.len() > Self::MAX_NODES {
            return Err(format!(
                "{} nodes, more than the {} a stack entry can name",
                self.nodes.len(),
                Self::MAX_NODES
            ));
        }
        // Each node's own slots on all threads (the first fault by index is named); then, in
        // index order (children come after their parents, checked first), that every node
        // is reached once from the root and no deeper than the stack holds.
        use rayon::prelude::*;
        let bad = (0..self.nodes.len())
            .into_par_iter()
            .find_first(|&i| self.check_node(i).is_err());
        if let Some(i) = bad {
            self.check_node(i)?;
        }
        let stack_size = stack_size(W);
        // A node's depth (the stack check below keeps it far under u8::MAX), or none yet.
        const UNREACHED: u8 = u8::MAX;
        let mut depth = vec![UNREACHED; self.nodes.len()];
        depth[0] = 0;
        for (i, n) in self.nodes.iter().enumerate() {
            let d = depth[i];
            if d == UNREACHED {
                return Err(format!(
                    "node {i} (one of {} nodes) is unreachable",
                    self.nodes.len()
                ));
            }
            let d = d as usize;
            if stack_entries(W, d) > stack_size {
                return Err(format!(
                    "node {i} is at depth {d}: its traversal may need more than \
                     {stack_size} stack entries"
                ));
            }
            for k in (0..W).filter(|&k| n.kind[k] == INNER) {
                let c = n.child[k] as usize;
                if depth[c] != UNREACHED {
                    return Err(format!("node {c} is reached twice"));
                }
                depth[c] = u8::try_from(d + 1)
                    .ok()
                    .filter(|&dc| dc != UNREACHED)
                    .ok_or_else(|| format!("node {c} is deeper than {}", UNREACHED - 1))?;
            }
        }
        Ok(())
    }

    /// [`check_structure`](Self::check_structure)'s checks of node `i`'s own slots: finite
    /// boxes, inner children after it and in range, leaf ranges in range.
    fn check_node(&self, i: usize) -> Result<(), String> {
        let n = &self.nodes[i];
        for k in 0..W {
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
                continue;
            }
            let end = child + kind as usize;
            if end > self.tris.len() {
                return Err(format!(
                    "node {i} slot {k} refers to triangles {child}..{end} of {}",
                    self.tris.len()
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::accel::GpuForm;
    use crate::geometry::Triangle;
    use crate::gpu::shaders;

    /// The kernel reads plane p (lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, child, kind) of slots
    /// 4g..4g+3 at word p · WIDE_GROUPS + g of a WIDE_NODE_WORDS-word node: the Rust node's
    /// fields lie there, and the constants the source is given say so.
    fn the_wgsl_node_matches<const W: usize>()
    where
        WideNode<W>: bytemuck::Pod,
    {
        let mesh = Mesh::from_triangles(vec![Triangle::new(
            glam::Vec3::ZERO,
            glam::Vec3::X,
            glam::Vec3::Y,
        )]);
        let layout =
            WideBvh::<W>::flatten(&crate::accel::bvh::build(&mesh, &Default::default()), &mesh);
        let offsets = [
            offset_of!(WideNode<W>, lo_x),
            offset_of!(WideNode<W>, lo_y),
            offset_of!(WideNode<W>, lo_z),
            offset_of!(WideNode<W>, hi_x),
            offset_of!(WideNode<W>, hi_y),
            offset_of!(WideNode<W>, hi_z),
            offset_of!(WideNode<W>, child),
            offset_of!(WideNode<W>, kind),
        ];
        let groups = W / 4;
        for (p, offset) in offsets.into_iter().enumerate() {
            assert_eq!(offset, 16 * p * groups, "plane {p}");
        }
        let src = shaders::trace_source(&layout, &crate::gpu::BufferParts::WHOLE);
        for constant in [
            format!("const WIDE_WIDTH: u32 = {W}u;"),
            format!("const WIDE_GROUPS: u32 = {groups}u;"),
            format!("const WIDE_NODE_WORDS: u32 = {}u;", 8 * groups),
        ] {
            assert!(src.contains(&constant), "{constant}");
        }
        naga::front::wgsl::parse_str(&src)
            .map_err(|e| e.emit_to_string(&src))
            .unwrap();
        assert_eq!(size_of::<WideNode<W>>(), 16 * 8 * groups);
        assert_eq!(WideBvh::<W>::NODE_BYTES, 32 * W);
        assert!(layout.validate().is_ok());
    }

    #[test]
    fn the_wgsl_node_matches_the_rust_node() {
        the_wgsl_node_matches::<4>();
        the_wgsl_node_matches::<8>();
    }

    /// A soup of 3000 small triangles in a 10-unit cube.
    fn soup() -> Mesh {
        soup_of(3000)
    }

    /// A soup of `n` small triangles in a 10-unit cube.
    fn soup_of(n: usize) -> Mesh {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut f = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let tris = (0..n)
            .map(|_| {
                let c = glam::Vec3::new(f(), f(), f()) * 10.0;
                let mut v = || c + glam::Vec3::new(f(), f(), f()) * 0.3;
                Triangle::new(v(), v(), v())
            })
            .collect();
        Mesh::from_triangles(tris)
    }

    /// The SAH cost the collapses weigh: C_NODE·area per node, C_TRI·area per leaf triangle.
    fn sah_cost<const W: usize>(nodes: &[WideNode<W>]) -> f64 {
        let mut cost = 0.0;
        for n in nodes {
            let used = (0..W).filter(|&k| n.kind[k] != 0);
            let bbox = used.clone().fold(Aabb::EMPTY, |b, k| b.union(n.bbox(k)));
            cost += (sah_collapse::C_NODE * bbox.area()) as f64;
            for k in used.filter(|&k| n.kind[k] != INNER) {
                cost += (sah_collapse::C_TRI * n.bbox(k).area() * n.kind[k] as f32) as f64;
            }
        }
        cost
    }

    fn sah_collapse_costs_no_more_than_greedy<const W: usize>(mesh: &Mesh)
    where
        WideNode<W>: bytemuck::Pod,
    {
        let bvh = crate::accel::bvh::build(mesh, &Default::default());
        let tris = LeafTri::gather(&bvh, mesh);
        let sah = sah_collapse::collapse::<W>(&bvh.root, max_wide_depth(W)).unwrap();
        // On one thread as on several (a big tree's subtrees are decided, counted and
        // written on several).
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let serial =
            one_thread.install(|| sah_collapse::collapse::<W>(&bvh.root, max_wide_depth(W)));
        assert_eq!(serial.as_ref(), Some(&sah));
        let greedy = greedy_collapse::collapse::<W>(&bvh.root);
        assert_eq!(WideBvh::<W>::flatten(&bvh, mesh).nodes, sah);
        for nodes in [&sah, &greedy] {
            let layout = WideBvh {
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
        let leaves = |nodes: &[WideNode<W>]| {
            (nodes.iter().flat_map(|n| n.kind))
                .filter(|&k| k != INNER && k != 0)
                .count()
        };
        assert_eq!(leaves(&greedy), binary_leaves(&bvh.root));
        assert!(leaves(&sah) < binary_leaves(&bvh.root));
        // Too deep for a bound of 2 levels: none, and flatten takes the greedy collapse.
        assert!(sah_collapse::collapse::<W>(&bvh.root, 2).is_none());
    }

    #[test]
    fn the_sah_collapse_costs_no_more_than_the_greedy_one() {
        // 3000 triangles, and enough for the tree's top to be collapsed on several threads.
        let big = soup_of(20_000);
        let nodes = crate::accel::bvh::build(&big, &Default::default())
            .root
            .nodes();
        assert!(
            nodes >= 2 * sah_collapse::PARALLEL_NODES,
            "{nodes} binary nodes"
        );
        for mesh in [soup(), big] {
            sah_collapse_costs_no_more_than_greedy::<4>(&mesh);
            sah_collapse_costs_no_more_than_greedy::<8>(&mesh);
        }
    }

    fn soup_collapses_greedily<const W: usize>()
    where
        WideNode<W>: bytemuck::Pod,
    {
        let mesh = soup();
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let layout = WideBvh::<W> {
            nodes: greedy_collapse::collapse(&bvh.root),
            tris: LeafTri::gather(&bvh, &mesh),
        };
        layout.validate().unwrap();
        // The collapse stops short of W children only when all of them are leaves.
        for (i, n) in layout.nodes.iter().enumerate() {
            let used = n.kind.iter().filter(|&&k| k != 0).count();
            assert!(
                used == W || !n.kind.contains(&INNER),
                "node {i} has {used} children, some inner"
            );
        }
        // Every binary inner node is a wide node or pulled up into one, which gained one
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
            for k in 0..W {
                if n.kind[k] == INNER {
                    let c = &layout.nodes[n.child[k] as usize];
                    let u = (0..W)
                        .filter(|&j| c.kind[j] != 0)
                        .fold(Aabb::EMPTY, |u, j| u.union(c.bbox(j)));
                    assert_eq!(u, n.bbox(k));
                }
            }
        }
    }

    #[test]
    fn a_soup_collapses_greedily_into_valid_nodes() {
        soup_collapses_greedily::<4>();
        soup_collapses_greedily::<8>();
    }
}
