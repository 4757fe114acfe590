//! The BVH's flattened layouts: each one the BVH's [`GpuForm`] — its GPU arrays, the WGSL
//! that walks them, and the CPU twin that walks the same arrays in the same order — one
//! folder each, registered in [`LayoutKind`]. Other structures with a GPU form implement
//! [`GpuForm`] in their own folder (the kd-tree and the BIH: `src/accel/{kdtree,bih}/gpu.rs`);
//! [`accel::build_gpu`](crate::accel::build_gpu) builds any of them for the GPU.
//!
//! # Adding a BVH layout
//!
//! A layout is one folder, `src/accel/bvh/layouts/<name>/`, plus one registry line:
//!
//! 1. `mod.rs`: a type holding the flattened arrays (its node type is `#[repr(C)]`,
//!    `bytemuck::Pod`, a multiple of 16 bytes, and private to the folder) and a
//!    `flatten(&Bvh, &Mesh)` constructor. Leaves refer to ranges of [`LeafTri`]s in leaf
//!    order, so the triangle array, its loader and its upload are shared.
//! 2. `<name>.wgsl`: `fn traverse(r: Ray, any_hit: bool) -> Hit`, reading nodes with
//!    `node_word(i)` and triangles with `load_tri(i)` (`shaders/lib/traversal.wgsl`), testing
//!    boxes with `slab_hit` and triangles with `intersect_tri` (`shaders/lib/common.wgsl`,
//!    which honour the [`Robustness`](crate::geometry::Robustness) overrides), counting work
//!    in `n_nodes`/`n_tris` when `COUNT_STATS`, and keeping the tie rule: `beats` to accept a
//!    hit (and `alpha_passes`, the render's alpha masks — `test_leaf` and `test_tri` ask
//!    both), `prune_bound(best.t)` (never `best.t` itself) to cut boxes. It sets
//!    `traversal_done` when it ends by itself (a driver may cut a long loop short).
//!    WGSL names of its own start with the layout's name, so two layouts never collide.
//! 3. `twin.rs`: `impl Accel` that runs the WGSL algorithm step for step in f32 — same
//!    child order, same stack discipline, same tests in the same operation order, the
//!    mask of `intersect_masked` handed to the leaf step (`LeafRay::new`) — so the
//!    GPU and the twin agree bit for bit (the equivalence tests in `tests/gpu_vs_cpu.rs`
//!    run over every entry of [`LayoutKind::ALL`]). Its `intersect_pruned` returns the
//!    prune bound of the hit it returns with it (what the WGSL leaves in `taken_prune`), so
//!    that a two-level walk over it need not test the triangle again.
//! 4. `impl GpuForm`: name, arrays, WGSL source (and `stack_depth`, where the source
//!    sizes its stack to the tree: a two-level scene takes its deepest mesh's source),
//!    overrides, validation (its structural checks, then `validate_boxes::check_boxes`
//!    on its `BoxTree`: the node and slot walk every layout's geometric check shares); and
//!    `from_arrays(GpuArrays) -> Result<Self, String>`, which rebuilds it from its arrays
//!    (with `records`) and runs `validate` (a [BVH file](bvh_file) is read through it).
//! 5. Register it: a variant of [`LayoutKind`] and its arms in [`flatten`] and
//!    [`from_arrays`].
//!
//! Stack depth: the builders cap depth at [`MAX_DEPTH`](crate::accel::bvh::MAX_DEPTH),
//! the kernels' stack size; a layout whose traversal needs more entries per level must
//! say so in `validate`.

mod build_report;
mod bvh2_wide_node;
pub mod bvh_file;
mod cwbvh;
mod dfs_distance;
mod dfs_sign;
mod interleave;
mod sah_collapse;
mod threaded;
mod validate_boxes;
mod wide_bvh;

use crate::accel::bvh::Bvh;
use crate::accel::gpu_form::records;
use crate::accel::{GpuArrays, GpuForm, LeafTri};
use crate::mesh::Mesh;

pub use build_report::{build_and_flatten, flatten_and_report, BuildReport};
pub use bvh2_wide_node::Bvh2WideNode;
pub(crate) use cwbvh::CwbvhWalk;
pub use cwbvh::{CwChild, Cwbvh};
pub use dfs_distance::DfsDistance;
pub use dfs_sign::DfsSign;
pub(crate) use dfs_sign::{dfs_nodes, DfsNode, DfsNodeRay, LEAF_TAG as DFS_LEAF_TAG};
pub(crate) use interleave::{trace_chunk, walk_interleaved, ChunkWalk, Stepper, IDLE_RAY, WALKS};
pub use threaded::Threaded;
pub use wide_bvh::{Bvh4, Bvh8, WideBvh};

/// Whether the CPU has AVX2 and the bit instructions the twins' AVX2 builds use (`cwbvh`
/// and `bvh8`, whose eight slots fit one vector, and `bvh4`).
#[cfg(target_arch = "x86_64")]
pub(crate) fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("popcnt")
        && std::arch::is_x86_feature_detected!("bmi1")
        && std::arch::is_x86_feature_detected!("lzcnt")
}

/// The registry of layouts: one variant per folder.
///
/// No layout is the default everywhere: the fastest depends on the device
/// (`lancer::trace::default_layout`, above this module in the house).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LayoutKind {
    /// 32-byte nodes in depth-first order, children visited in the order the ray's sign on
    /// the split axis gives.
    DfsSign,
    /// The dfs-sign nodes, both children tested and entered nearest first by entry
    /// distance; the farther is culled on the pop once a closer hit is known.
    DfsDistance,
    /// 64-byte nodes holding both children's boxes (Aila & Laine 2009): both tested per
    /// visit, the nearer hit child first.
    Bvh2WideNode,
    /// 80-byte compressed 8-wide nodes (Ylitie et al. 2017): children's boxes in 8 bits per
    /// plane, slots ordered by ray octant, a stack of node groups.
    Cwbvh,
    /// 128-byte 4-wide nodes collapsed from the binary tree by SAH: the four children's boxes
    /// tested per visit, the hit ones visited nearest first.
    Bvh4,
    /// `bvh4`'s program for 256-byte 8-wide nodes: fewer, wider nodes (half as many on the
    /// bunny), fewer visits per ray.
    Bvh8,
    /// The dfs-sign tree in eight copies, one per ray octant, each in the order dfs-sign
    /// visits it for that octant's rays; skip indices instead of a stack.
    Threaded,
}

impl LayoutKind {
    /// Every layout, for tests and benches that run them all.
    pub const ALL: &'static [LayoutKind] = &[
        LayoutKind::DfsSign,
        LayoutKind::DfsDistance,
        LayoutKind::Bvh2WideNode,
        LayoutKind::Cwbvh,
        LayoutKind::Bvh4,
        LayoutKind::Bvh8,
        LayoutKind::Threaded,
    ];

    /// The layout of this [name](LayoutKind::name), if any.
    pub fn from_name(name: &str) -> Option<LayoutKind> {
        LayoutKind::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// The name the command line and benches use.
    pub fn name(self) -> &'static str {
        match self {
            LayoutKind::DfsSign => "dfs-sign",
            LayoutKind::DfsDistance => "dfs-distance",
            LayoutKind::Bvh2WideNode => "bvh2-wide-node",
            LayoutKind::Cwbvh => "cwbvh",
            LayoutKind::Bvh4 => "bvh4",
            LayoutKind::Bvh8 => "bvh8",
            LayoutKind::Threaded => "threaded",
        }
    }
}

impl std::fmt::Display for LayoutKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Flattens a built tree into the chosen layout, after checking that `mesh` holds the
/// triangles it refers to (a tree built over a bigger mesh is refused) and that its arrays
/// fit in the memory available (the `threaded` layout holds eight copies of the tree's
/// nodes): the library's and the command line's way in, for trees built from input.
pub fn try_flatten(kind: LayoutKind, bvh: &Bvh, mesh: &Mesh) -> crate::Result<Box<dyn GpuForm>> {
    bvh.check_mesh(mesh, "flatten it with")?;
    if kind == LayoutKind::Threaded {
        crate::limits::check_memory(
            "the threaded layout",
            Threaded::node_array_bytes(bvh.root.nodes() as u64),
            "choose another --layout (dfs-sign holds one copy of the nodes)",
        )?;
    }
    Ok(flatten(kind, bvh, mesh))
}

/// [`try_flatten`], consuming the tree: layouts that can (`cwbvh`, the GPU default) free
/// its nodes before writing their own, for a lower peak of memory.
pub fn try_flatten_owned(
    kind: LayoutKind,
    bvh: Bvh,
    mesh: &Mesh,
) -> crate::Result<Box<dyn GpuForm>> {
    match kind {
        LayoutKind::Cwbvh => {
            bvh.check_mesh(mesh, "flatten it with")?;
            Ok(Box::new(Cwbvh::flatten_owned(bvh, mesh)))
        }
        _ => try_flatten(kind, &bvh, mesh),
    }
}

/// Flattens a built tree into the chosen layout, unchecked: for trees known to fit (tests,
/// benches); input goes through [`try_flatten`]. Panics on a mesh smaller than the tree's
/// ([`Bvh::mesh_len`]).
pub fn flatten(kind: LayoutKind, bvh: &Bvh, mesh: &Mesh) -> Box<dyn GpuForm> {
    match kind {
        LayoutKind::DfsSign => Box::new(DfsSign::flatten(bvh, mesh)),
        LayoutKind::DfsDistance => Box::new(DfsDistance::flatten(bvh, mesh)),
        LayoutKind::Bvh2WideNode => Box::new(Bvh2WideNode::flatten(bvh, mesh)),
        LayoutKind::Cwbvh => Box::new(Cwbvh::flatten(bvh, mesh)),
        LayoutKind::Bvh4 => Box::new(Bvh4::flatten(bvh, mesh)),
        LayoutKind::Bvh8 => Box::new(Bvh8::flatten(bvh, mesh)),
        LayoutKind::Threaded => Box::new(Threaded::flatten(bvh, mesh)),
    }
}

/// Rebuilds a layout of kind `kind` from its arrays (as [`GpuForm::arrays`] gives them);
/// refused, naming the first fault, unless they are whole records that pass
/// [`GpuForm::validate`].
pub fn from_arrays(kind: LayoutKind, arrays: GpuArrays<'_>) -> Result<Box<dyn GpuForm>, String> {
    Ok(match kind {
        LayoutKind::DfsSign => Box::new(DfsSign::from_arrays(arrays)?),
        LayoutKind::DfsDistance => Box::new(DfsDistance::from_arrays(arrays)?),
        LayoutKind::Bvh2WideNode => Box::new(Bvh2WideNode::from_arrays(arrays)?),
        LayoutKind::Cwbvh => Box::new(Cwbvh::from_arrays(arrays)?),
        LayoutKind::Bvh4 => Box::new(Bvh4::from_arrays(arrays)?),
        LayoutKind::Bvh8 => Box::new(Bvh8::from_arrays(arrays)?),
        LayoutKind::Threaded => Box::new(Threaded::from_arrays(arrays)?),
    })
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::bvh::{Node, MAX_DEPTH};
    use crate::geometry::Triangle;

    #[test]
    fn validate_refuses_a_layout_deeper_than_its_traversal_stack() {
        // A binary chain of 1000 leaves, one triangle each (made here, past the depth
        // `Bvh::new` allows: a layout this deep can come only from a file or arrays), is
        // deeper than every stack but `threaded`'s (which needs none) even once collapsed
        // eight wide.
        let n = 1000u32;
        let tris: Vec<Triangle> = (0..n)
            .map(|i| {
                let p = Vec3::new(i as f32, 0.0, 0.0);
                Triangle::new(p, p + Vec3::X, p + Vec3::Y)
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let leaf = |i: u32| Node::Leaf {
            bbox: mesh.triangles[i as usize].bbox(),
            start: i,
            count: 1,
        };
        let mut root = leaf(n - 1);
        for i in (0..n - 1).rev() {
            root = Node::parent(0, [leaf(i), root]);
        }
        let bvh = Bvh {
            root,
            order: (0..n).collect(),
            mesh_len: mesh.len(),
        };
        // The first node the check meets past the stack is one level past it, so each
        // message names the boundary: MAX_DEPTH + 1 levels of binary nodes (bvh2-wide-node's
        // records hold their children: MAX_DEPTH), the wide depth whose stack entries first
        // exceed the kernel's (bvh4: 32 levels of 3, bvh8: 22 of 7; cwbvh: one group a level).
        for &kind in LayoutKind::ALL {
            let result = flatten(kind, &bvh, &mesh).validate();
            let want = match kind {
                LayoutKind::Threaded => {
                    result.unwrap();
                    continue;
                }
                LayoutKind::DfsSign | LayoutKind::DfsDistance => {
                    format!("at depth 65 > {MAX_DEPTH}")
                }
                LayoutKind::Bvh2WideNode => format!("at depth {MAX_DEPTH}: its children"),
                LayoutKind::Cwbvh => format!("at depth 65 > the {MAX_DEPTH}-group stack"),
                LayoutKind::Bvh4 => "at depth 32: its traversal may need more than 96".into(),
                LayoutKind::Bvh8 => "at depth 22: its traversal may need more than 154".into(),
            };
            let e = result.unwrap_err();
            assert!(e.contains(&want), "{kind}: {e}");
        }
    }

    /// Big trees' structural checks run on all threads (their halves, or their nodes, side
    /// by side); the fault they name must not depend on that. The triangle array cut to a
    /// third leaves a fault in most leaves, on both sides of every split: each layout names
    /// the same one on one thread as on two, every time; and dfs-sign (whose nodes lie in
    /// the order its walk meets them) the first leaf past the cut.
    #[test]
    fn validate_names_the_same_fault_on_any_number_of_threads() {
        let tris: Vec<Triangle> = (0..30_000)
            .map(|i| {
                let f = i as f32;
                let c = Vec3::new((f * 0.37).sin(), (f * 0.91).cos(), (f * 0.53).sin()) * 10.0;
                Triangle::new(c, c + Vec3::X * 0.05, c + Vec3::Y * 0.05)
            })
            .collect();
        let mesh = Mesh::from_triangles(tris);
        let bvh = crate::accel::bvh::build(&mesh, &Default::default());
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for &kind in LayoutKind::ALL {
            let layout = flatten(kind, &bvh, &mesh);
            let a = layout.arrays();
            let cut = GpuArrays::new(a.nodes, &a.tris[..a.tris.len() / 3 / 48 * 48]);
            let refused = || from_arrays(kind, cut).err().expect("accepted");
            let want = one.install(refused);
            for _ in 0..3 {
                assert_eq!(two.install(refused), want, "{kind}");
            }
            if kind == LayoutKind::DfsSign {
                let kept = cut.tris.len() / 48;
                let nodes: &[dfs_sign::DfsNode] = bytemuck::cast_slice(a.nodes);
                let first = (nodes.iter().enumerate())
                    .find(|(_, n)| n.is_leaf() && (n.a + n.count()) as usize > kept)
                    .map(|(i, _)| i)
                    .unwrap();
                assert!(want.starts_with(&format!("leaf {first} refers")), "{want}");
            }
        }
    }
}
