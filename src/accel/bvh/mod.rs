//! Bounding volume hierarchy: the tree, its builders (sweep SAH, binned SAH, median, spatial
//! splits, PLOC, LBVH), the reinsertion optimiser and its statistics (SAH, end-point overlap).
//! Flattened layouts for the GPU live in `crate::accel::bvh::layouts`.

mod binned;
mod cluster_tree;
mod epo;
pub mod layouts;
pub mod lbvh;
mod median;
mod options;
mod ploc;
mod prim_ref;
mod prims;
mod refit;
mod reinsert;
mod sbvh;
mod stats;
mod sweep;
mod tree;
mod tree_check;

use rayon::prelude::*;

use crate::geometry::Aabb;
use crate::mesh::{Mesh, TriStatus};

pub use binned::MAX_BINS;
pub use epo::epo_cost;
pub use options::{BuildOptions, Builder, EXACT_BELOW};
pub use reinsert::optimize;
pub use sbvh::{DUPLICATION, OVERLAP, SPATIAL_BINS};
pub use stats::BvhStats;
pub use tree::{Bvh, Node, MAX_DEPTH};

use prims::Prims;

/// Builds a BVH over the mesh's included triangles. Deterministic for a given input.
pub fn build(mesh: &Mesh, opts: &BuildOptions) -> Bvh {
    let ids = Included::of(mesh);
    let prims = match &ids {
        Included::All => Prims::new(mesh.triangles.par_iter().map(|t| t.bbox())),
        Included::Some(ids) => {
            Prims::new(ids.par_iter().map(|&i| mesh.triangles[i as usize].bbox()))
        }
    };
    build_prims(
        prims,
        (&ids, mesh.len()),
        opts,
        Some(&|i| mesh.triangles[ids.id(i) as usize]),
    )
}

/// Builds a BVH over boxes instead of triangles (the top level over instances' world
/// boxes): `order` holds positions in `boxes`. The spatial-split builder, which clips
/// triangles, builds binned here. Deterministic for a given input.
pub fn build_boxes(boxes: &[Aabb], opts: &BuildOptions) -> Bvh {
    build_prims(
        Prims::new(boxes.par_iter().copied()),
        (&Included::All, boxes.len()),
        opts,
        None,
    )
}

/// The triangles a tree is built over, by position: every one (position = index, the
/// usual case: no list is made), or those listed.
enum Included {
    All,
    Some(Vec<u32>),
}

impl Included {
    fn of(mesh: &Mesh) -> Included {
        if mesh.status.len() == mesh.len() && mesh.count(TriStatus::Ok) == mesh.len() {
            Included::All
        } else {
            Included::Some(mesh.included())
        }
    }

    /// The list of included triangles, None when every one is.
    fn list(&self) -> Option<&[u32]> {
        match self {
            Included::All => None,
            Included::Some(ids) => Some(ids),
        }
    }

    /// The triangle at position i.
    fn id(&self, i: u32) -> u32 {
        match self {
            Included::All => i,
            Included::Some(ids) => ids[i as usize],
        }
    }
}

/// The builders' common entry: `prims` are the boxes of the primitives `ids` (positions
/// into `ids` in the tree; `order` maps them back) of the `mesh_len` in the mesh (or
/// boxes), `triangle(i)` the triangle of position i (the spatial-split builder clips them;
/// without triangles it builds binned).
fn build_prims(
    prims: Prims,
    (ids, mesh_len): (&Included, usize),
    opts: &BuildOptions,
    triangle: Option<&(dyn Fn(u32) -> crate::geometry::Triangle + Sync)>,
) -> Bvh {
    if prims.len() == 0 {
        return Bvh::empty(mesh_len);
    }
    let (root, local) = match opts.builder {
        Builder::Sweep => sweep::build(prims, opts),
        Builder::Binned => binned::build(prims, opts),
        Builder::Median => median::build(&prims, opts),
        Builder::Sbvh => match triangle {
            Some(triangle) => sbvh::build(prims, triangle, opts),
            None => binned::build(prims, opts),
        },
        Builder::Ploc => match ploc::build(&prims, opts) {
            Some(tree) => tree,
            None => binned::build(prims, opts),
        },
        Builder::Lbvh => match lbvh::build(&prims, opts) {
            Some(tree) => tree,
            None => binned::build(prims, opts),
        },
    };
    finish(root, local, (ids.list(), mesh_len), opts)
}

/// A builder's tree over positions `local` in `ids` (None: positions are the indices) of
/// the `mesh_len` in the mesh, as the BVH over `ids`, optimised when asked.
fn finish(
    root: Node,
    local: Vec<u32>,
    (ids, mesh_len): (Option<&[u32]>, usize),
    opts: &BuildOptions,
) -> Bvh {
    let order = match ids {
        None => local,
        Some(ids) => local.par_iter().map(|&l| ids[l as usize]).collect(),
    };
    let mut bvh = Bvh {
        root,
        order,
        mesh_len,
    };
    if opts.optimize {
        optimize(&mut bvh, opts);
    }
    bvh
}

/// The BVH of an LBVH radix tree over the mesh's included triangles `ids` (built on the
/// GPU: `gpu::build_lbvh`), exactly as [`build`] makes it from the CPU's radix tree: the
/// SAH's leaves, the depth cap (beyond it, the binned builder), the optimiser. Refused,
/// naming the fault, where an id is not a triangle of `mesh` or `tree` is not a radix tree
/// over the ids ([`lbvh::RadixTree::check`]).
pub fn build_from_radix_tree(
    mesh: &Mesh,
    ids: &[u32],
    tree: lbvh::RadixTree,
    opts: &BuildOptions,
) -> crate::Result<Bvh> {
    let refuse = |e: String| {
        crate::Error::Usage(format!(
            "refusing the radix tree: {e} (lbvh::radix_tree makes one over boxes)"
        ))
    };
    if let Some(&i) = ids.iter().find(|&&i| i as usize >= mesh.len()) {
        return Err(refuse(format!("id {i} of a mesh of {}", mesh.len())));
    }
    if ids.len() > lbvh::MAX_PRIMS {
        return Err(refuse(format!(
            "{} ids, more than the {} it takes",
            ids.len(),
            lbvh::MAX_PRIMS
        )));
    }
    tree.check(ids.len()).map_err(refuse)?;
    if ids.is_empty() {
        return Ok(Bvh::empty(mesh.len()));
    }
    let prims = Prims::new(ids.par_iter().map(|&i| mesh.triangles[i as usize].bbox()));
    let (root, local) = match lbvh::to_tree(tree, &prims, opts) {
        Some(tree) => tree,
        None => binned::build(prims, opts),
    };
    Ok(finish(root, local, (Some(ids), mesh.len()), opts))
}
