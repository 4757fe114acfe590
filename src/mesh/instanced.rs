//! Meshes placed by instances: the unique meshes, each in its own space, and the affine maps
//! that place them (the input of `accel::instances`). Triangles are numbered as the
//! flattened scene numbers them: instances in order, each mesh's triangles in file order.

use std::sync::Arc;

use super::{Mesh, TriStatus};
use crate::error::Error;
use crate::geometry::{Aabb, Affine, Triangle};

/// One placement of a mesh: which one, and its object-to-world map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`InstanceSet::meshes`].
    pub mesh: u32,
    /// Object space to world space.
    pub to_world: Affine,
}

/// Most triangles an instanced scene may number (as for a flattened one: indices stay below
/// the miss marker with room to spare).
pub const MAX_INSTANCED_TRIANGLES: u64 = u32::MAX as u64 / 2;

/// Meshes placed by instances: what a two-level structure (`accel::instances`) is built
/// over.
#[derive(Clone, Debug, Default)]
pub struct InstanceSet {
    /// The unique meshes, each in its own (object) space.
    pub meshes: Vec<Arc<Mesh>>,
    /// The placements, in numbering order.
    pub instances: Vec<Instance>,
}

impl InstanceSet {
    /// A set of `meshes` placed by `instances`, refused (naming the first bad instance)
    /// when an instance names no mesh or has a map that is not finite and invertible, or
    /// when the instanced triangles are more than [`MAX_INSTANCED_TRIANGLES`].
    pub fn new(meshes: Vec<Arc<Mesh>>, instances: Vec<Instance>) -> crate::Result<InstanceSet> {
        let set = InstanceSet { meshes, instances };
        set.check()?;
        Ok(set)
    }

    /// [`InstanceSet::new`]'s checks, for a set whose public fields were set by hand.
    pub fn check(&self) -> crate::Result<()> {
        for (i, inst) in self.instances.iter().enumerate() {
            if inst.mesh as usize >= self.meshes.len() {
                return Err(Error::Usage(format!(
                    "instance {i} places mesh {} of {}",
                    inst.mesh,
                    self.meshes.len()
                )));
            }
            if inst.to_world.inverse().is_none() {
                return Err(Error::Usage(format!(
                    "instance {i} has a map that is not finite and invertible: {:?}",
                    inst.to_world.rows
                )));
            }
        }
        let total = self.triangle_count();
        if total > MAX_INSTANCED_TRIANGLES {
            return Err(Error::Usage(format!(
                "{total} instanced triangles, more than lancer numbers \
                 ({MAX_INSTANCED_TRIANGLES}): place fewer instances"
            )));
        }
        Ok(())
    }

    /// Logs one warning naming `path` and counting the placed triangles left out of the BVH
    /// (each mesh's, once for every instance of it: what a trace of the set leaves out),
    /// and refuses a set in which no instance places a usable triangle, or one too small in
    /// world space to trace (as a single mesh is: [`MIN_EXTENT`](crate::limits::MIN_EXTENT)).
    pub fn check_usable(&self, path: &std::path::Path) -> crate::Result<()> {
        let mut uses = vec![0u64; self.meshes.len()];
        // An instance of no mesh counts nothing here (InstanceSet::new refuses it).
        for i in &self.instances {
            if let Some(n) = uses.get_mut(i.mesh as usize) {
                *n += 1;
            }
        }
        let mut left_out = [0u64; 5];
        let mut usable = false;
        for (mesh, &n) in self.meshes.iter().zip(&uses).filter(|(_, &n)| n > 0) {
            for (total, count) in left_out.iter_mut().zip(mesh.exclusions()) {
                *total += count * n;
            }
            usable |= mesh.status.contains(&TriStatus::Ok);
        }
        if let Some(s) = super::exclusion_summary(left_out) {
            log::warn!("{}: {s}", path.display());
        }
        if !usable {
            return Err(Error::input(
                path,
                None,
                format!(
                    "no usable triangle ({} placed): nothing to trace",
                    (self.meshes.iter().zip(&uses))
                        .map(|(m, &n)| m.len() as u64 * n)
                        .sum::<u64>()
                ),
            ));
        }
        super::load::check_extent(path, "scene", self.bounds().extent().length())
    }

    /// The mesh an instance places, None where it names none (a set made by hand that
    /// [`InstanceSet::check`] refuses).
    fn mesh_of(&self, inst: &Instance) -> Option<&Mesh> {
        self.meshes.get(inst.mesh as usize).map(|m| &**m)
    }

    /// Triangles of the flattened scene (every instance's mesh, excluded triangles
    /// included, as they are numbered). An instance of no mesh counts none.
    pub fn triangle_count(&self) -> u64 {
        (self.instances.iter())
            .map(|i| self.mesh_of(i).map_or(0, |m| m.len() as u64))
            .sum()
    }

    /// Bounds of the placed meshes: the union of each instance's mesh bounds mapped into
    /// world space ([`Affine::image_box`]; for a rotated instance, looser than its
    /// triangles' own bounds). An instance of no mesh adds nothing.
    pub fn bounds(&self) -> Aabb {
        let mesh_bounds: Vec<Aabb> = self.meshes.iter().map(|m| m.bounds()).collect();
        self.instances
            .iter()
            .fold(Aabb::EMPTY, |b, i| match mesh_bounds.get(i.mesh as usize) {
                Some(m) => b.union(i.to_world.image_box(m)),
                None => b,
            })
    }

    /// Each instance's first triangle index in the flattened numbering (an instance of no
    /// mesh numbers none; beyond u32, as [`InstanceSet::check`] refuses, they wrap).
    pub fn first_prims(&self) -> Vec<u32> {
        let mut next = 0u32;
        self.instances
            .iter()
            .map(|i| {
                let first = next;
                next = next.wrapping_add(self.mesh_of(i).map_or(0, |m| m.len() as u32));
                first
            })
            .collect()
    }

    /// The scene as one mesh in world space, numbered as the instanced scene: each instance's
    /// triangles mapped by [`Affine::point`] (corners kept in order, also under a mirroring
    /// map, so that u and v mean the same). A triangle its mesh leaves out stays out; the
    /// others are classified again in world space. Refused as [`InstanceSet::check`]
    /// refuses a set, or where the flattened mesh would not fit in memory.
    pub fn flatten(&self) -> crate::Result<Mesh> {
        self.check()?;
        let n = self.triangle_count() as usize;
        let per_triangle =
            (std::mem::size_of::<Triangle>() + std::mem::size_of::<TriStatus>()) as u128;
        crate::limits::check_memory(
            &format!("the flattened copy of {n} instanced triangles"),
            n as u128 * per_triangle,
            "trace or render the instances in two levels instead",
        )?;
        let (mut triangles, mut status) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for inst in &self.instances {
            let a = &inst.to_world;
            let mesh = &self.meshes[inst.mesh as usize];
            for (t, s) in mesh.triangles.iter().zip(&mesh.status) {
                let world = Triangle {
                    v: t.v.map(|p| a.point(p)),
                };
                status.push(match s {
                    TriStatus::Ok => super::classify(&world),
                    other => *other,
                });
                triangles.push(world);
            }
        }
        Ok(Mesh {
            triangles,
            status,
            short_faces: self
                .instances
                .iter()
                .map(|i| self.meshes[i.mesh as usize].short_faces)
                .sum(),
            sources: self
                .meshes
                .iter()
                .flat_map(|m| m.sources.iter().cloned())
                .collect(),
        })
    }
}
