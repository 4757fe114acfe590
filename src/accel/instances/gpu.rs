//! The two-level structure's GPU form: every mesh's bottom level flattened into one BVH
//! layout, their arrays one after another, the top level's nodes and entries after the
//! bottom levels' nodes; `two_level.wgsl` walks the top level and calls the layout's own
//! `traverse` for each instance. Its CPU twin is [`TwoLevel`] over the same layouts.

use std::sync::{Arc, OnceLock};

use super::top_level::TopEntry;
use super::{InstanceSet, TwoLevel};
use crate::accel::bvh::layouts::{self, DfsNode, LayoutKind, DFS_LEAF_TAG};
use crate::accel::bvh::{self, BuildOptions, MAX_DEPTH};
use crate::accel::{Accel, GpuArrays, GpuForm, Mask, Query, RayStats};
use crate::geometry::{Aabb, Affine, Hit, Ray, Robustness};

/// Bytes of one 16-byte word of the GPU arrays.
const WORD: usize = 16;

/// One mesh's bottom level in a [`GpuTwoLevel`]'s arrays ([`GpuTwoLevel::mesh_words`]).
pub struct MeshWords<'a> {
    /// Its first node word.
    pub node_base: u32,
    /// Its node words' bytes.
    pub nodes: &'a [u8],
    /// Its first triangle word.
    pub tri_base: u32,
    /// Its triangle words' bytes.
    pub tris: &'a [u8],
}

/// A two-level structure on the GPU: bottom levels in one BVH layout, a top-level BVH
/// over the instances. Its [`Accel`] is the CPU twin of its WGSL.
pub struct GpuTwoLevel {
    twin: TwoLevel<dyn GpuForm>,
    layout: LayoutKind,
    /// The bottom layout's traversal, generated for its deepest bottom level.
    bottom_wgsl: String,
    /// The GPU arrays, laid out on first use (a CPU device never asks): the bottom levels'
    /// nodes, then the top level's nodes, then its entries; the bottom levels' triangles.
    arrays: OnceLock<(Vec<u8>, Vec<u8>)>,
    /// First word of the top level's nodes, and of its entries, in `nodes`.
    top_node_base: u32,
    top_entry_base: u32,
    /// Each mesh's BVH before flattening, kept for [`GpuTwoLevel::refit_mesh`] (empty when
    /// built without: [`GpuTwoLevel::build`]).
    trees: Vec<Arc<bvh::Bvh>>,
}

impl GpuTwoLevel {
    /// Builds each of `set`'s meshes with `options` and flattens it into `layout`, then the
    /// top level over the instances (as [`TwoLevel::build`]), and lays out the GPU arrays.
    /// Refused as [`InstanceSet::new`] refuses, or as
    /// [`layouts::try_flatten`] refuses a mesh.
    pub fn build(
        layout: LayoutKind,
        set: &InstanceSet,
        options: &BuildOptions,
    ) -> crate::Result<GpuTwoLevel> {
        let bottom = |_: usize, m: &crate::mesh::Mesh| -> crate::Result<Box<dyn GpuForm>> {
            layouts::try_flatten_owned(layout, bvh::build(m, options), m)
        };
        let twin = TwoLevel::over(set, bottom, options)?;
        GpuTwoLevel::over(layout, twin, Vec::new())
    }

    /// [`GpuTwoLevel::build`], keeping each mesh's BVH tree so that
    /// [`GpuTwoLevel::refit_mesh`] can refit it (the trees' memory, about as much again as
    /// the bottom levels', is held as long as the structure).
    pub fn build_refittable(
        layout: LayoutKind,
        set: &InstanceSet,
        options: &BuildOptions,
    ) -> crate::Result<GpuTwoLevel> {
        let trees: Vec<Arc<bvh::Bvh>> = (set.meshes.iter())
            .map(|m| Arc::new(bvh::build(m, options)))
            .collect();
        let bottom = |k: usize, m: &crate::mesh::Mesh| -> crate::Result<Box<dyn GpuForm>> {
            layouts::try_flatten(layout, &trees[k], m)
        };
        let twin = TwoLevel::over(set, bottom, options)?;
        GpuTwoLevel::over(layout, twin, trees)
    }

    /// The GPU form of `twin`, its bottom levels in `layout`.
    fn over(
        layout: LayoutKind,
        mut twin: TwoLevel<dyn GpuForm>,
        trees: Vec<Arc<bvh::Bvh>>,
    ) -> crate::Result<GpuTwoLevel> {
        // The deepest bottom level's traversal, whose stack holds every bottom level's walk.
        let deepest = twin.bottoms.iter().max_by_key(|b| b.stack_depth());
        let Some(bottom_wgsl) = deepest.map(|b| b.wgsl()) else {
            return Err(crate::Error::Usage(
                "an instanced scene needs at least one mesh".into(),
            ));
        };
        let bases = bottom_bases(&twin.bottoms);
        for e in &mut twin.top.entries {
            (e.node_base, e.tri_base) = bases[e.mesh as usize];
        }
        let node_words: usize = twin
            .bottoms
            .iter()
            .map(|b| b.arrays().nodes.len() / WORD)
            .sum();
        let top_node_base = node_words as u32;
        let top_entry_base = top_node_base + (twin.top.nodes.len() * 2) as u32;
        Ok(GpuTwoLevel {
            twin,
            layout,
            bottom_wgsl,
            arrays: OnceLock::new(),
            top_node_base,
            top_entry_base,
            trees,
        })
    }

    /// The same instances with mesh `k`'s triangles moved to `moved` (the same triangles in
    /// the same order: a deforming mesh): its tree refit ([`bvh::Bvh::refit`]) and flattened
    /// again, the top level built again over the moved mesh. Mesh k's arrays keep their size
    /// and place, and so does the top level: a GPU copy becomes the refit structure by
    /// writing [`GpuTwoLevel::mesh_words`] of mesh k and [`GpuTwoLevel::top_words`] over it.
    /// Refused for a structure built without its trees ([`GpuTwoLevel::build`]), a mesh
    /// index out of range, or a mesh of another triangle count.
    pub fn refit_mesh(
        &self,
        k: usize,
        moved: &crate::mesh::Mesh,
        options: &BuildOptions,
    ) -> crate::Result<GpuTwoLevel> {
        let usage = |m: String| crate::Error::Usage(m);
        let Some(tree) = self.trees.get(k) else {
            return Err(usage(match self.trees.is_empty() {
                true => "refit needs the meshes' trees: build with build_refittable \
                         (TracerOptions::refit)"
                    .into(),
                false => format!("no mesh {k} of {}", self.trees.len()),
            }));
        };
        let had = self.twin.meshes[k].len();
        if moved.len() != had {
            return Err(usage(format!(
                "mesh {k} has {had} triangles, the moved one {}: refit moves the same \
                 triangles",
                moved.len()
            )));
        }
        let mut tree = (**tree).clone();
        tree.refit(moved)?;
        let bottom: Arc<dyn GpuForm> = layouts::try_flatten(self.layout, &tree, moved)?.into();
        let old = self.twin.bottoms[k].arrays();
        let new = bottom.arrays();
        if (old.nodes.len(), old.tris.len()) != (new.nodes.len(), new.tris.len()) {
            return Err(usage(format!(
                "mesh {k} refit flattens to other array sizes: build the structure again"
            )));
        }
        let mut moved_mesh = moved.clone();
        moved_mesh.status = self.twin.meshes[k].status.clone();
        let twin = self
            .twin
            .with_mesh(k, Arc::new(moved_mesh), bottom, options)?;
        let mut trees = self.trees.clone();
        trees[k] = Arc::new(tree);
        let refit = GpuTwoLevel::over(self.layout, twin, trees)?;
        if (refit.top_node_base, refit.top_entry_base) != (self.top_node_base, self.top_entry_base)
            || refit.twin.top.nodes.len() != self.twin.top.nodes.len()
        {
            return Err(usage(
                "the refit top level has another size: build the structure again".into(),
            ));
        }
        refit
            .check_top()
            .map_err(|e| usage(format!("the refit top level is invalid: {e}")))?;
        Ok(refit)
    }

    /// Mesh `k`'s bottom level in the GPU arrays: where its node words and its triangle
    /// words start, and their bytes.
    pub fn mesh_words(&self, k: usize) -> Option<MeshWords<'_>> {
        let b = self.twin.bottoms.get(k)?;
        let (node_base, tri_base) = bottom_bases(&self.twin.bottoms)[k];
        let a = b.arrays();
        Some(MeshWords {
            node_base,
            nodes: a.nodes,
            tri_base,
            tris: a.tris,
        })
    }

    /// The same bottom levels (shared: not built, flattened or laid out again) with the
    /// instances moved ([`TwoLevel::moved`]). Only the top level is new, and it fills the
    /// same words of the node array as this one's: a GPU copy of this structure becomes the
    /// moved one by writing [`GpuTwoLevel::top_words`] over it, and the kernels' override
    /// constants stay the same (no pipeline is compiled again). Refused as
    /// [`TwoLevel::moved`] refuses, or where the new top level would not fill the same
    /// words.
    pub fn moved(&self, maps: &[Affine], options: &BuildOptions) -> crate::Result<GpuTwoLevel> {
        let mut twin = self.twin.moved(maps, options)?;
        let bases = bottom_bases(&twin.bottoms);
        for e in &mut twin.top.entries {
            (e.node_base, e.tri_base) = bases[e.mesh as usize];
        }
        let (old, new) = (&self.twin.top, &twin.top);
        if (old.nodes.len(), old.entries.len()) != (new.nodes.len(), new.entries.len()) {
            return Err(crate::Error::Usage(format!(
                "the moved top level has {} nodes and {} entries where the first had {} and \
                 {}: build the structure again",
                new.nodes.len(),
                new.entries.len(),
                old.nodes.len(),
                old.entries.len()
            )));
        }
        let moved = GpuTwoLevel {
            twin,
            layout: self.layout,
            bottom_wgsl: self.bottom_wgsl.clone(),
            arrays: OnceLock::new(),
            top_node_base: self.top_node_base,
            top_entry_base: self.top_entry_base,
            trees: self.trees.clone(),
        };
        moved
            .check_top()
            .map_err(|e| crate::Error::Usage(format!("the moved top level is invalid: {e}")))?;
        Ok(moved)
    }

    /// Whether `set` places the meshes this structure was built over (the same meshes, by
    /// pointer, and as many instances): [`GpuTwoLevel::moved`] then takes its maps.
    pub fn places(&self, set: &InstanceSet) -> bool {
        self.twin.places(set)
    }

    /// The top level's words in the node array: the first one's index, and their bytes (its
    /// nodes, then its entries).
    pub fn top_words(&self) -> (u32, Vec<u8>) {
        let top = &self.twin.top;
        let mut bytes = Vec::with_capacity(
            std::mem::size_of_val(&top.nodes[..]) + std::mem::size_of_val(&top.entries[..]),
        );
        bytes.extend_from_slice(bytemuck::cast_slice(&top.nodes));
        bytes.extend_from_slice(bytemuck::cast_slice(&top.entries));
        (self.top_node_base, bytes)
    }

    /// The GPU arrays laid out (see [`GpuTwoLevel::arrays`]).
    fn lay_out(&self) -> (Vec<u8>, Vec<u8>) {
        let (mut nodes, mut tris) = (Vec::new(), Vec::new());
        for b in self.twin.bottoms.iter() {
            let a = b.arrays();
            nodes.extend_from_slice(a.nodes);
            tris.extend_from_slice(a.tris);
        }
        nodes.extend_from_slice(bytemuck::cast_slice(&self.twin.top.nodes));
        nodes.extend_from_slice(bytemuck::cast_slice(&self.twin.top.entries));
        if tris.is_empty() {
            // Every array is bound, so none may be empty (no triangle is ever read).
            tris.resize(3 * WORD, 0);
        }
        (nodes, tris)
    }

    /// The top level's structure: children forward and in range, depth within the stack,
    /// every node reached once, leaves within the entries, each entry once; every box
    /// holds its children's; entries name a bottom level and its arrays' offsets.
    fn check_top(&self) -> Result<(), String> {
        let (nodes, entries) = (&self.twin.top.nodes, &self.twin.top.entries);
        if nodes.is_empty() {
            return match entries.is_empty() {
                true => Ok(()),
                false => Err("top level has entries but no nodes".into()),
            };
        }
        let mut seen_entries = vec![false; entries.len()];
        let mut stack = vec![(0usize, 0usize, nodes.len())];
        let mut seen = 0usize;
        while let Some((i, depth, end)) = stack.pop() {
            seen += 1;
            if depth > MAX_DEPTH {
                return Err(format!("top node {i} is at depth {depth} > {MAX_DEPTH}"));
            }
            let n: &DfsNode = &nodes[i];
            if n.is_leaf() {
                // The walks (two_level.wgsl and its twin) take one instance a leaf.
                if n.count() != 1 {
                    return Err(format!(
                        "top leaf {i} holds {} instances, not one",
                        n.count()
                    ));
                }
                let Some(seen) = seen_entries.get_mut(n.a as usize) else {
                    return Err(format!("top leaf {i} refers to an entry past the end"));
                };
                if *seen {
                    return Err(format!(
                        "top leaf {i} refers to an entry another leaf holds"
                    ));
                }
                *seen = true;
                continue;
            }
            let second = n.a as usize;
            if i + 1 >= second || second >= end {
                return Err(format!(
                    "top node {i} has second child {second} outside {}..{end}",
                    i + 2
                ));
            }
            for c in [i + 1, second] {
                if !n.bbox().contains(&nodes[c].bbox()) {
                    return Err(format!("top node {i} does not hold its child {c}"));
                }
            }
            stack.push((i + 1, depth + 1, second));
            stack.push((second, depth + 1, end));
        }
        if seen != nodes.len() || seen_entries.contains(&false) {
            return Err("top level has unreachable nodes or entries".into());
        }
        let bases = bottom_bases(&self.twin.bottoms);
        for (k, e) in entries.iter().enumerate() {
            let TopEntry {
                mesh,
                node_base,
                tri_base,
                ..
            } = *e;
            if bases.get(mesh as usize) != Some(&(node_base, tri_base)) {
                return Err(format!(
                    "top entry {k} names mesh {mesh} at offsets it does not have"
                ));
            }
        }
        Ok(())
    }
}

/// Each bottom level's first node word and first triangle word in the GPU arrays.
fn bottom_bases(bottoms: &[Arc<dyn GpuForm>]) -> Vec<(u32, u32)> {
    let mut base = (0u32, 0u32);
    let mut bases = Vec::with_capacity(bottoms.len());
    for b in bottoms {
        bases.push(base);
        let a = b.arrays();
        base.0 += (a.nodes.len() / WORD) as u32;
        base.1 += (a.tris.len() / WORD) as u32;
    }
    bases
}

impl Accel for GpuTwoLevel {
    fn bounds(&self) -> Aabb {
        self.twin.bounds()
    }

    fn intersect_masked(
        &self,
        ray: &Ray,
        query: Query,
        robustness: &Robustness,
        mask: Mask<'_>,
        stats: &mut RayStats,
    ) -> Hit {
        self.twin
            .intersect_masked(ray, query, robustness, mask, stats)
    }

    fn trace_hits(&self, rays: &[Ray], query: Query, robustness: &Robustness) -> Vec<Hit> {
        self.twin.trace_hits(rays, query, robustness)
    }
}

impl GpuForm for GpuTwoLevel {
    fn name(&self) -> &'static str {
        self.layout.name()
    }

    fn arrays(&self) -> GpuArrays<'_> {
        let (nodes, tris) = self.arrays.get_or_init(|| self.lay_out());
        GpuArrays::new(nodes, tris)
    }

    /// The arrays' bytes, counted without laying them out.
    fn bytes(&self) -> usize {
        let top = &self.twin.top;
        let bottoms: usize = self.twin.bottoms.iter().map(|b| b.bytes()).sum();
        bottoms + std::mem::size_of_val(&top.nodes[..]) + std::mem::size_of_val(&top.entries[..])
    }

    fn triangles(&self) -> usize {
        self.twin.bottoms.iter().map(|b| b.triangles()).sum()
    }

    /// The bottom layout's traversal, then the top level's walk (`trace_ray`).
    fn wgsl(&self) -> String {
        format!(
            "{}\nconst TOP_LEAF_TAG: u32 = {DFS_LEAF_TAG}u;\n{}",
            self.bottom_wgsl,
            include_str!("two_level.wgsl")
        )
    }

    fn defines_trace_ray(&self) -> bool {
        true
    }

    fn overrides(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("INSTANCES", 1.0),
            ("TOP_NODE_BASE", self.top_node_base as f64),
            ("TOP_ENTRY_BASE", self.top_entry_base as f64),
        ]
    }

    /// Every bottom level's own checks, then the top level's: its structure, its boxes and its
    /// entries' offsets.
    fn validate(&self) -> Result<(), String> {
        for (m, b) in self.twin.bottoms.iter().enumerate() {
            b.validate().map_err(|e| format!("mesh {m}: {e}"))?;
        }
        self.check_top()
    }

    fn node_bytes(&self) -> usize {
        self.twin.bottoms.first().map_or(32, |b| b.node_bytes())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};
    use std::sync::Arc;

    use glam::Vec3;

    use super::*;
    use crate::accel::instances::{Affine, Instance};
    use crate::geometry::Triangle;
    use crate::mesh::Mesh;

    /// two_level.wgsl reads an entry as four words: three map rows, then (first_prim, mesh,
    /// node_base, tri_base).
    #[test]
    fn entry_words_are_where_the_wgsl_reads_them() {
        assert_eq!(size_of::<TopEntry>(), 4 * WORD);
        assert_eq!(offset_of!(TopEntry, to_object), 0);
        assert_eq!(offset_of!(TopEntry, first_prim), 3 * WORD);
        assert_eq!(offset_of!(TopEntry, mesh), 3 * WORD + 4);
        assert_eq!(offset_of!(TopEntry, node_base), 3 * WORD + 8);
        assert_eq!(offset_of!(TopEntry, tri_base), 3 * WORD + 12);
        assert_eq!(size_of::<DfsNode>(), 2 * WORD);
    }

    fn two_meshes_three_instances() -> GpuTwoLevel {
        let tri = |z: f32| Triangle::new(Vec3::new(0.0, 0.0, z), Vec3::X, Vec3::Y);
        let meshes = vec![
            Arc::new(Mesh::from_triangles(vec![tri(0.0), tri(1.0)])),
            Arc::new(Mesh::from_triangles(vec![tri(0.5)])),
        ];
        let at = |mesh, x| Instance {
            mesh,
            to_world: Affine::translation(Vec3::new(x, 0.0, 0.0)),
        };
        let set = InstanceSet::new(meshes, vec![at(0, 0.0), at(1, 2.0), at(0, 4.0)]).unwrap();
        GpuTwoLevel::build(LayoutKind::DfsSign, &set, &BuildOptions::default()).unwrap()
    }

    #[test]
    fn validate_names_a_broken_top_level() {
        let good = two_meshes_three_instances();
        assert_eq!(good.validate(), Ok(()));
        assert_eq!(good.twin.top.entries.len(), 3);
        let mut bad = two_meshes_three_instances();
        bad.twin.top.entries[1].node_base += 1;
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("offsets it does not have"));
        let mut bad = two_meshes_three_instances();
        bad.twin.top.nodes[0].lo[0] += 1.0;
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("does not hold its child"));
        let mut bad = two_meshes_three_instances();
        let leaf = bad
            .twin
            .top
            .nodes
            .iter()
            .rposition(|n| n.is_leaf())
            .unwrap();
        bad.twin.top.nodes[leaf].a = 7;
        assert!(bad.validate().unwrap_err().contains("past the end"));
    }
}
