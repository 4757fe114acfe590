//! How a GPU kernel walks the BVH: one ray per invocation, or the lanes of a subgroup
//! together.

/// The traversal mode of the GPU trace and render kernels (the CPU twin always traces one
/// ray at a time). A mode a layout, adapter or workgroup size cannot run falls back to
/// [`TraversalMode::PerRay`], with a warning; [`TraceResult::mode`](crate::TraceResult)
/// and [`Rendered::mode`](crate::Rendered) say which ran. A render is the same
/// image in every mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum TraversalMode {
    /// Each invocation walks its own ray with its own stack.
    #[default]
    PerRay,
    /// The lanes of a subgroup walk together: the subgroup visits a node when any lane's
    /// ray hits its box, loads nodes and triangles cooperatively and shares one stack;
    /// each lane keeps its own closest hit (the same closest hits as per ray, bit for bit;
    /// any hits may differ, each a real hit). Needs the adapter's subgroup operations, a
    /// layout that offers it ([`GpuForm::subgroup_wgsl`](crate::accel::GpuForm)) and a
    /// workgroup of whole subgroups. Statistics count, per ray, the nodes and triangles its
    /// subgroup loaded while the ray was live (valid, and for any hit not yet answered): the
    /// union of the lanes' traversals, each load shared by the lanes.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The lanes of a subgroup walk together, sharing node loads and one \
                      stack; same closest hits as per-ray (dfs-sign, cwbvh and threaded; needs adapter \
                      subgroups)"
        )
    )]
    Subgroup,
}

impl TraversalMode {
    /// Every mode, for benches and checks that run them all.
    pub const ALL: &'static [TraversalMode] = &[TraversalMode::PerRay, TraversalMode::Subgroup];

    /// The name the command line and benches use.
    pub fn name(self) -> &'static str {
        match self {
            TraversalMode::PerRay => "per-ray",
            TraversalMode::Subgroup => "subgroup",
        }
    }
}

impl std::fmt::Display for TraversalMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
