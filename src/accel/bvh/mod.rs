//! Bounding volume hierarchy: the tree, its builders (sweep SAH, binned SAH, median, spatial
//! splits, PLOC), the reinsertion optimiser and its statistics (SAH, end-point overlap).
//! Flattened layouts for the GPU live in `crate::accel::bvh::layouts`.

mod binned;
mod epo;
pub mod layouts;
mod median;
mod options;
mod ploc;
mod prim_ref;
mod prims;
mod reinsert;
mod sbvh;
mod stats;
mod sweep;
mod tree;

use rayon::prelude::*;

use crate::geometry::Aabb;
use crate::mesh::Mesh;

pub use binned::MAX_BINS;
pub use epo::epo_cost;
pub use options::{BuildOptions, Builder, EXACT_BELOW};
pub use reinsert::optimize;
pub use sbvh::{DUPLICATION, OVERLAP, SPATIAL_BINS};
pub use stats::BvhStats;
pub use tree::{Bvh, Node, MAX_DEPTH};

use prims::Prims;
use tree::leaf;

/// Builds a BVH over the mesh's included triangles. Deterministic for a given input.
pub fn build(mesh: &Mesh, opts: &BuildOptions) -> Bvh {
    let ids = mesh.included();
    let prims = Prims::new(ids.par_iter().map(|&i| mesh.triangles[i as usize].bbox()));
    if ids.is_empty() {
        return Bvh {
            root: leaf(Aabb::EMPTY, 0, 0),
            order: Vec::new(),
        };
    }
    let (root, local) = match opts.builder {
        Builder::Sweep => sweep::build(prims, opts),
        Builder::Binned => binned::build(prims, opts),
        Builder::Median => median::build(&prims, opts),
        Builder::Sbvh => sbvh::build(prims, &|i| mesh.triangles[ids[i as usize] as usize], opts),
        Builder::Ploc => match ploc::build(&prims, opts) {
            Some(tree) => tree,
            None => binned::build(prims, opts),
        },
    };
    let mut bvh = Bvh {
        root,
        order: local.par_iter().map(|&l| ids[l as usize]).collect(),
    };
    if opts.optimize {
        optimize(&mut bvh, opts);
    }
    bvh
}
