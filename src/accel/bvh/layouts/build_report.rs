//! `lancer build`: a BVH built and flattened into a layout, with its shape, cost, build
//! time and size.

use std::time::Instant;

use serde::Serialize;

use super::{try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions, Builder, Bvh, BvhStats};
use crate::accel::GpuForm;
use crate::mesh::Mesh;
use crate::util::human_bytes;

/// What a build made (`lancer build`, and its `--json` object).
#[derive(Clone, Debug, Serialize)]
pub struct BuildReport {
    /// The builder (`--builder`).
    pub builder: Builder,
    /// The layout's name (`--layout`).
    pub layout: &'static str,
    /// Where the tree was built when not on the CPU: the GPU adapter (`--build-on gpu`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub built_on: Option<String>,
    /// The tree's shape and SAH cost (triangles: those with NaN, zero area or out of range
    /// are left out).
    #[serde(flatten)]
    pub stats: BvhStats,
    /// Wall time to build and flatten, in ms.
    pub build_ms: f64,
    /// Bytes of the flattened layout (what the GPU holds).
    pub bytes: usize,
    /// Instances in the scene, where it places a mesh more than once (the BVH is built
    /// over the flattened scene: every instance's triangles).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instances: Option<usize>,
    /// Triangles of the flattened scene, where it places a mesh more than once.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instanced_triangles: Option<u64>,
    /// The BVH file written, if any (set by the caller that writes it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
    /// The process's peak resident memory in bytes, if the caller measured it (the
    /// command line does, where the system says).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_memory_bytes: Option<u64>,
}

/// Builds a BVH over `mesh` with `options`, flattens it into `layout`, and reports.
pub fn build_and_flatten(
    mesh: &Mesh,
    options: &BuildOptions,
    layout: LayoutKind,
) -> crate::Result<(Box<dyn GpuForm>, BuildReport)> {
    let t0 = Instant::now();
    let bvh = build(mesh, options);
    flatten_and_report(mesh, &bvh, options, layout, t0)
}

/// Flattens a BVH built from `started` on (by [`build`] or on a GPU) into `layout`, and
/// reports the build and flatten time since `started`.
pub fn flatten_and_report(
    mesh: &Mesh,
    bvh: &Bvh,
    options: &BuildOptions,
    layout: LayoutKind,
    started: Instant,
) -> crate::Result<(Box<dyn GpuForm>, BuildReport)> {
    let flat = try_flatten(layout, bvh, mesh)?;
    let build_ms = started.elapsed().as_secs_f64() * 1e3;
    let report = BuildReport::new(bvh, flat.as_ref(), options, build_ms);
    Ok((flat, report))
}

impl BuildReport {
    /// The report of `bvh` flattened into `flat` in `build_ms` (the caller fills in where
    /// it was built, the scene's instances, the file written and the peak memory).
    pub fn new(bvh: &Bvh, flat: &dyn GpuForm, options: &BuildOptions, build_ms: f64) -> Self {
        BuildReport {
            builder: options.builder,
            layout: flat.name(),
            built_on: None,
            stats: BvhStats::of(bvh, options),
            build_ms,
            bytes: flat.bytes(),
            instances: None,
            instanced_triangles: None,
            out: None,
            peak_memory_bytes: None,
        }
    }
}

impl BuildReport {
    /// The report as aligned lines of text.
    pub fn text(&self) -> Vec<String> {
        let s = &self.stats;
        let mut lines = vec![
            match &self.built_on {
                Some(on) => format!("builder     {} (built on {on})", self.builder.name()),
                None => format!("builder     {}", self.builder.name()),
            },
            format!("layout      {}", self.layout),
            format!("triangles   {}", s.triangles),
            format!("references  {}", s.references),
            format!("nodes       {}", s.nodes),
            format!("leaves      {}", s.leaves),
            format!("max depth   {}", s.max_depth),
            format!("SAH cost    {:.3}", s.sah_cost),
            format!("build ms    {:.2}", self.build_ms),
            format!("GPU bytes   {}", self.bytes),
        ];
        if let (Some(n), Some(t)) = (self.instances, self.instanced_triangles) {
            lines.push(format!("instances   {n} ({t} triangles, built flattened)"));
        }
        lines.extend(self.out.iter().map(|o| format!("written to  {o}")));
        lines.extend(
            (self.peak_memory_bytes.iter()).map(|b| format!("peak memory {}", human_bytes(*b))),
        );
        lines
    }
}
