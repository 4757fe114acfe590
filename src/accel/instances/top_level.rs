//! The top level: a BVH over the instances' world boxes (the SAH builders over boxes, one
//! instance a leaf), in dfs-sign nodes, and one entry per instance in leaf order.

use rayon::prelude::*;

use super::{Affine, InstanceSet};
use crate::accel::bvh::layouts::{dfs_nodes, DfsNode};
use crate::accel::bvh::{self, BuildOptions};
use crate::geometry::Aabb;
use crate::mesh::{Mesh, TriStatus};

/// One instance as the top level reads it, 64 bytes (WGSL: four words read by
/// `top_entry` in two_level.wgsl): the map into its object space, its first triangle index,
/// its mesh (bottom level) and where that bottom level's arrays start on the GPU.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct TopEntry {
    /// World space to object space.
    pub to_object: Affine,
    /// Its first triangle's index in the flattened numbering.
    pub first_prim: u32,
    /// Index of its mesh and bottom level.
    pub mesh: u32,
    /// First 16-byte word of its bottom level's nodes in the GPU node array.
    pub node_base: u32,
    /// First 16-byte word of its bottom level's triangles in the GPU triangle array.
    pub tri_base: u32,
}

/// The top-level tree: dfs-sign nodes whose leaves each refer to one of `entries` (built
/// with `max_leaf` 1, which every builder honours): the walks (two_level.wgsl and its twin)
/// enter a leaf's one instance without a loop over a range.
#[derive(Clone, Debug, Default)]
pub(crate) struct TopLevel {
    /// Depth-first nodes; empty when no instance has a triangle to hit.
    pub nodes: Vec<DfsNode>,
    /// The instances in leaf order.
    pub entries: Vec<TopEntry>,
}

/// A mesh's usable triangles in eight parts, by the octant of the bounds' centre their
/// centroid lies in: each part's box (none for an empty part; none at all for a mesh with no
/// usable triangle).
pub(crate) fn parts(mesh: &Mesh) -> Vec<Aabb> {
    let centre = mesh.bounds().center();
    let boxes = (mesh.triangles.par_iter().zip(&mesh.status))
        .filter(|(_, s)| **s == TriStatus::Ok)
        .fold(
            || [Aabb::EMPTY; 8],
            |mut boxes, (t, _)| {
                let b = t.bbox();
                let c = b.center().cmpgt(centre).bitmask() as usize;
                boxes[c] = boxes[c].union(b);
                boxes
            },
        )
        .reduce(
            || [Aabb::EMPTY; 8],
            |mut a, b| {
                for (a, b) in a.iter_mut().zip(b) {
                    *a = a.union(b);
                }
                a
            },
        );
    boxes.into_iter().filter(|b| !b.is_empty()).collect()
}

impl TopLevel {
    /// The top level over `set`'s instances whose mesh has a triangle to hit, built by
    /// `opts.builder` with one instance a leaf. An instance's world box is the union of its
    /// mesh's [`parts`] mapped into world space (under a map that turns the axes, tighter
    /// than the mapped box of the whole mesh). Maps must be invertible
    /// ([`InstanceSet::new`] checks them).
    pub fn build(set: &InstanceSet, opts: &BuildOptions) -> TopLevel {
        let firsts = set.first_prims();
        let mesh_parts: Vec<Vec<Aabb>> = set.meshes.iter().map(|m| parts(m)).collect();
        let placed: Vec<u32> = (0..set.instances.len() as u32)
            .filter(|&i| !mesh_parts[set.instances[i as usize].mesh as usize].is_empty())
            .collect();
        let boxes: Vec<Aabb> = placed
            .par_iter()
            .map(|&i| {
                let inst = &set.instances[i as usize];
                let parts = &mesh_parts[inst.mesh as usize];
                let map = &inst.to_world;
                if map.keeps_axes() {
                    let whole = parts.iter().fold(Aabb::EMPTY, |b, p| b.union(*p));
                    return map.bound_box(&whole);
                }
                (parts.iter()).fold(Aabb::EMPTY, |b, p| b.union(map.bound_box(p)))
            })
            .collect();
        if boxes.is_empty() {
            return TopLevel::default();
        }
        let opts = BuildOptions {
            max_leaf: 1,
            ..*opts
        };
        let tree = bvh::build_boxes(&boxes, &opts);
        let entries = tree
            .order
            .iter()
            .map(|&k| {
                let i = placed[k as usize];
                let inst = &set.instances[i as usize];
                TopEntry {
                    to_object: inst.to_world.inverse().unwrap_or(Affine::IDENTITY),
                    first_prim: firsts[i as usize],
                    mesh: inst.mesh,
                    node_base: 0,
                    tri_base: 0,
                }
            })
            .collect();
        TopLevel {
            nodes: dfs_nodes(&tree),
            entries,
        }
    }

    /// Bounds of every placed instance (empty when none is).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, DfsNode::bbox)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::Vec3;

    use super::*;
    use crate::accel::bvh::Builder;
    use crate::accel::instances::Instance;
    use crate::geometry::Triangle;

    /// The walks take one instance a leaf: every builder makes leaves of one, even over
    /// instances placed on top of each other (which no split separates).
    #[test]
    fn every_builder_makes_leaves_of_one_instance() {
        let mesh = Arc::new(Mesh::from_triangles(vec![Triangle::new(
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
        )]));
        let instances: Vec<Instance> = (0..40)
            .map(|i| Instance {
                mesh: 0,
                // Twenty pairs of coincident copies along x.
                to_world: Affine::translation(Vec3::new((i / 2) as f32, 0.0, 0.0)),
            })
            .collect();
        let set = InstanceSet::new(vec![mesh], instances).unwrap();
        for builder in Builder::ALL {
            for optimize in [false, true] {
                let opts = BuildOptions {
                    builder,
                    optimize,
                    ..BuildOptions::default()
                };
                let top = TopLevel::build(&set, &opts);
                let leaves: Vec<&DfsNode> = top.nodes.iter().filter(|n| n.is_leaf()).collect();
                assert_eq!(leaves.len(), 40, "{builder:?}");
                assert!(leaves.iter().all(|n| n.count() == 1), "{builder:?}");
                let mut seen: Vec<u32> = leaves.iter().map(|n| n.a).collect();
                seen.sort_unstable();
                assert_eq!(seen, (0..40).collect::<Vec<u32>>(), "{builder:?}");
            }
        }
    }
}
