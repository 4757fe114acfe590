//! `dfs-distance`: the nodes of [`dfs-sign`](super::DfsSign) (32 bytes, depth-first
//! pre-order), walked in the order of the children's entry distances: at an inner node both
//! child boxes are tested, the nearer hit child is visited first and the farther pushed with
//! its entry distance, which culls it on the pop once a closer hit is known (the seed's
//! "order on the intervals [near far]"). Loads two nodes per inner step where dfs-sign loads
//! one, in exchange for skipping boxes the ray misses without visiting them.

mod twin;

use crate::accel::bvh::Bvh;
use crate::mesh::Mesh;

use super::dfs_sign::{node_wgsl, DfsNode};
use super::{DfsSign, GpuArrays, LayoutKind};

/// A BVH flattened like `dfs-sign`, traversed in entry-distance order; its
/// [`Accel`](crate::accel::Accel) is the CPU twin of `dfs_distance.wgsl`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DfsDistance {
    flat: DfsSign,
}

impl DfsDistance {
    /// Flattens a built tree (the dfs-sign arrays).
    /// Panics on a mesh smaller than the tree's ([`Bvh::mesh_len`]): input goes through
    /// [`try_flatten`](super::try_flatten), which refuses it.
    pub fn flatten(bvh: &Bvh, mesh: &Mesh) -> DfsDistance {
        DfsDistance {
            flat: DfsSign::flatten(bvh, mesh),
        }
    }

    /// A layout from raw arrays (the dfs-sign arrays), refused unless they are whole
    /// records and pass [`validate`](super::GpuForm::validate).
    pub fn from_arrays(arrays: GpuArrays<'_>) -> Result<DfsDistance, String> {
        DfsSign::from_arrays(arrays).map(|flat| DfsDistance { flat })
    }

    fn nodes(&self) -> &[DfsNode] {
        &self.flat.nodes
    }
}

impl super::GpuForm for DfsDistance {
    fn name(&self) -> &'static str {
        LayoutKind::DfsDistance.name()
    }

    fn node_bytes(&self) -> usize {
        self.flat.node_bytes()
    }

    fn arrays(&self) -> GpuArrays<'_> {
        self.flat.arrays()
    }

    fn wgsl(&self) -> String {
        format!("{}{}", node_wgsl(), include_str!("dfs_distance.wgsl"))
    }

    /// The dfs-sign invariants; the stack gets one entry per level, as dfs-sign's.
    fn validate(&self) -> Result<(), String> {
        self.flat.validate()
    }
}
