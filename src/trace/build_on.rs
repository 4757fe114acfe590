//! Where a tracer's BVH is built: on the CPU, or on the GPU device (the LBVH builder).

/// Where the BVH is built ([`TracerOptions::build_on`](super::TracerOptions::build_on),
/// `--build-on`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum BuildOn {
    /// The CPU builders, on all threads.
    #[default]
    Cpu,
    /// The GPU device's kernels (`--builder lbvh` only): the same tree as the CPU's LBVH,
    /// flattened there into dfs-sign, else read back and flattened on the CPU. On a device
    /// without a GPU the CPU builds it, with a warning.
    Gpu,
}
