//! Where a tracer's or a renderer's BVH is built: on the CPU, or on the GPU device (the
//! LBVH builder).

use std::sync::Arc;

use crate::accel::bvh::layouts::{self, LayoutKind};
use crate::accel::bvh::{self, BuildOptions, Bvh};
use crate::accel::GpuForm;
use crate::device::Device;
use crate::error::{Error, Result};
use crate::mesh::Mesh;

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

/// A layout built on the GPU ([`gpu_built`]), with its tree where asked for.
pub struct GpuBuilt {
    /// The flattened layout.
    pub layout: Arc<dyn GpuForm>,
    /// The tree it holds (for its statistics).
    pub tree: Option<Bvh>,
    /// Wall time to build and flatten, ms (the tree for the statistics not included).
    pub ms: f64,
}

/// The LBVH over `mesh` built on the device's GPU and flattened into `kind` (there for
/// dfs-sign without the optimiser, else read back and flattened on the CPU), with its tree
/// when `want_tree`; None on a device without a GPU, where the caller builds on the CPU
/// (the same tree). Any builder but the LBVH is a usage error.
pub fn gpu_built(
    device: &Device,
    mesh: &Mesh,
    build: &BuildOptions,
    kind: LayoutKind,
    want_tree: bool,
) -> Result<Option<GpuBuilt>> {
    if build.builder != bvh::Builder::Lbvh {
        return Err(Error::Usage(format!(
            "building on the GPU takes the lbvh builder, not {}",
            build.builder.name()
        )));
    }
    let Some(ctx) = device.gpu_context() else {
        log::warn!("no GPU device: the LBVH is built on the CPU (the same tree)");
        return Ok(None);
    };
    let start = std::time::Instant::now();
    let there = kind == LayoutKind::DfsSign && !build.optimize && build.max_depth >= bvh::MAX_DEPTH;
    let ms = || start.elapsed().as_secs_f64() * 1e3;
    let built = if there {
        let flat = crate::gpu::lbvh_dfs_sign(ctx, mesh, build)?;
        let ms = ms();
        GpuBuilt {
            tree: want_tree.then(|| flat.tree(mesh.len())),
            layout: Arc::new(flat),
            ms,
        }
    } else {
        let tree = crate::gpu::build_lbvh(ctx, mesh, build)?;
        match want_tree {
            true => GpuBuilt {
                layout: layouts::try_flatten(kind, &tree, mesh)?.into(),
                ms: ms(),
                tree: Some(tree),
            },
            false => GpuBuilt {
                layout: layouts::try_flatten_owned(kind, tree, mesh)?.into(),
                ms: ms(),
                tree: None,
            },
        }
    };
    log::info!(
        "BVH built (lbvh) on {} and flattened into {kind} {} in {:.0} ms",
        ctx.adapter.name,
        if there { "there" } else { "on the CPU" },
        built.ms
    );
    Ok(Some(built))
}
