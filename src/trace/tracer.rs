//! One tracer API for both devices: build once, then `trace(&rays, query)` on the CPU twin
//! or the GPU kernel of the same layout.

use std::sync::Arc;
use std::time::Instant;

use crate::accel::bvh::layouts::{self, LayoutKind};
use crate::accel::bvh::{self, BuildOptions};
use crate::accel::instances::{Affine, GpuTwoLevel, InstanceSet};
use crate::accel::GpuForm;
use crate::accel::TraversalMode;
use crate::accel::{self, Accel, AccelKind, Query, RayStats};
use crate::device::Device;
use crate::error::{Error, Result};
use crate::geometry::{Hit, Precision, Ray, Robustness};
use crate::gpu::{BvhMemory, GpuTracer, Timings, TraceKernel, INCOMPLETE};
use crate::mesh::Mesh;

use super::BuildOn;

/// How a [`Tracer`] builds, lays out and traces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TracerOptions {
    /// BVH builder and its constants.
    pub build: BuildOptions,
    /// Flattened layout (GPU arrays and the CPU twin); None: the device's fastest,
    /// [`default_layout`](super::default_layout) (bvh8 on the CPU, cwbvh on lavapipe,
    /// dfs-sign on a hardware GPU).
    pub layout: Option<LayoutKind>,
    /// GPU: where the kernel reads the layout from.
    pub memory: BvhMemory,
    /// Triangle and slab tests, checked or trusted GPU modules.
    pub robustness: Robustness,
    /// GPU: invocations per workgroup.
    pub workgroup_size: u32,
    /// Return per-ray statistics (nodes visited, triangles tested).
    pub stats: bool,
    /// GPU: how the kernel walks the BVH (per ray, or a subgroup together); a mode that
    /// cannot run falls back to per-ray with a warning ([`TraceResult::mode`]).
    pub mode: TraversalMode,
    /// [`Tracer::with_instances`]: keep each mesh's BVH tree, so that
    /// [`Tracer::refit_mesh`] can refit it (about as much memory again as the meshes'
    /// bottom levels).
    pub refit: bool,
    /// [`Tracer::with_instances`]: trace one BVH over the flattened scene
    /// ([`InstanceSet::flatten`]) instead of two levels, for comparison; hits are numbered
    /// alike.
    pub flatten: bool,
    /// Where a one-level BVH is built ([`Tracer::new`], [`Tracer::from_mesh`]): on the CPU,
    /// or (with `build.builder` [`Builder::Lbvh`](crate::accel::bvh::Builder)) on the GPU.
    pub build_on: BuildOn,
}

impl Default for TracerOptions {
    fn default() -> Self {
        TracerOptions {
            build: BuildOptions::default(),
            layout: None,
            memory: BvhMemory::default(),
            robustness: Robustness::default(),
            workgroup_size: 64,
            stats: false,
            mode: TraversalMode::PerRay,
            refit: false,
            flatten: false,
            build_on: BuildOn::Cpu,
        }
    }
}

/// What one `trace` call returns.
#[derive(Clone, Debug, Default)]
pub struct TraceResult {
    /// One hit per ray, in ray order.
    pub hits: Vec<Hit>,
    /// Per-ray work, when [`TracerOptions::stats`] asked for it.
    pub stats: Option<Vec<RayStats>>,
    /// Wall time, and GPU time where the device measures it.
    pub timings: Timings,
    /// Rays the GPU driver cut short (a loop-iteration cap, see
    /// [`INCOMPLETE`](crate::gpu::INCOMPLETE)), traced again on the CPU twin: their hits
    /// are the CPU's, bit for bit.
    pub cpu_retraced: usize,
    /// The traversal mode that ran: [`TracerOptions::mode`], or per-ray where that mode
    /// cannot run (on the CPU, or see [`GpuTracer::subgroup_unavailable`]).
    pub mode: TraversalMode,
}

/// A mesh's acceleration structure on a device, ready to trace batches of rays: a BVH
/// flattened in a layout or another structure's GPU form (CPU twin or GPU kernel), or a
/// structure on the CPU.
pub struct Tracer<'d> {
    /// What the CPU traces (for a BVH, the layout's twin; it also re-traces rays a GPU
    /// driver cut short).
    cpu: Arc<dyn Accel>,
    layout: Option<Arc<dyn GpuForm>>,
    gpu: Option<GpuTracer<'d>>,
    options: TracerOptions,
    /// The mode that runs, [`Tracer::resolve_mode`] of the options.
    mode: TraversalMode,
    /// A tracer over instances: its two levels, which [`Tracer::set_transforms`] moves.
    two_level: Option<Arc<GpuTwoLevel>>,
}

impl<'d> Tracer<'d> {
    /// Builds the BVH over the mesh's usable triangles, flattens it, and uploads it when
    /// the device is a GPU.
    pub fn new(device: &'d Device, mesh: &Mesh, options: &TracerOptions) -> Result<Self> {
        mesh.check_arrays()?;
        let layout = Self::flattened(device, mesh, options)?;
        Self::with_layout(device, layout, options)
    }

    /// [`Tracer::new`] taking the mesh, which is freed once the layout holds its triangles
    /// and before the layout is uploaded: the mesh, the layout and the device's copy of it
    /// never take memory at once (a software driver's device memory is the host's).
    pub fn from_mesh(device: &'d Device, mesh: Mesh, options: &TracerOptions) -> Result<Self> {
        mesh.check_arrays()?;
        let layout = Self::flattened(device, &mesh, options)?;
        drop(mesh);
        Self::with_layout(device, layout, options)
    }

    /// The BVH over `mesh` built and flattened into the options' layout (the device's
    /// default where none is given).
    fn flattened(
        device: &Device,
        mesh: &Mesh,
        options: &TracerOptions,
    ) -> Result<Arc<dyn GpuForm>> {
        if options.build_on == BuildOn::Gpu {
            let kind = (options.layout).unwrap_or_else(|| super::default_layout(device));
            if let Some(built) =
                super::build_on::gpu_built(device, mesh, &options.build, kind, false)?
            {
                return Ok(built.layout);
            }
        }
        let start = std::time::Instant::now();
        let tree = bvh::build(mesh, &options.build);
        let built = start.elapsed();
        let kind = (options.layout).unwrap_or_else(|| super::default_layout(device));
        let layout: Arc<dyn GpuForm> = layouts::try_flatten_owned(kind, tree, mesh)?.into();
        log::info!(
            "BVH built ({}) in {:.0} ms, flattened into {kind} in {:.0} ms",
            options.build.builder.name(),
            built.as_secs_f64() * 1e3,
            (start.elapsed() - built).as_secs_f64() * 1e3
        );
        Ok(layout)
    }

    /// Builds the structure `kind` over the mesh: on a GPU device its GPU form
    /// ([`accel::build_gpu`]: a BVH in `kind`'s layout, the kd-tree or the BIH), on the CPU its CPU
    /// form. Structures with no GPU kernel are refused on a GPU device, naming the fix.
    pub fn with_structure(
        device: &'d Device,
        mesh: &Mesh,
        kind: AccelKind,
        options: &TracerOptions,
    ) -> Result<Self> {
        if let AccelKind::Bvh(layout) = kind {
            let layout = Some(layout);
            return Self::new(device, mesh, &TracerOptions { layout, ..*options });
        }
        if !device.is_cpu() {
            return match accel::build_gpu(kind, mesh, &options.build)? {
                Some(layout) => Self::with_layout(device, layout, options),
                None => Err(Error::Usage(format!(
                    "the {kind} structure runs on the CPU only (only the BVH, the kd-tree and \
                     the BIH have GPU kernels): use --device cpu"
                ))),
            };
        }
        let mut tracer = Tracer {
            cpu: accel::build(kind, mesh, &options.build)?.into(),
            layout: None,
            gpu: None,
            options: *options,
            mode: TraversalMode::PerRay,
            two_level: None,
        };
        tracer.resolve_mode();
        Ok(tracer)
    }

    /// Builds a two-level structure over meshes placed by instances
    /// ([`accel::instances`]): each mesh's BVH flattened into `options.layout` (None: the
    /// device's default), a top-level BVH over the instances, uploaded when the device is a
    /// GPU. Hits are numbered as in [`InstanceSet::flatten`]'s mesh. With
    /// [`TracerOptions::flatten`], one BVH over that mesh instead.
    pub fn with_instances(
        device: &'d Device,
        set: &InstanceSet,
        options: &TracerOptions,
    ) -> Result<Self> {
        if options.flatten {
            // InstanceSet::new's checks (its fields are public), as the two levels make them.
            set.check()?;
            let n = set.triangle_count() as u128;
            crate::limits::check_memory(
                &format!("the flattened scene ({n} triangles)"),
                n * 256,
                "trace it in two levels (without flatten)",
            )?;
            return Self::new(device, &set.flatten()?, options);
        }
        if options.build_on == BuildOn::Gpu {
            log::warn!("a scene in two levels builds its levels on the CPU (not --build-on gpu)");
        }
        let start = std::time::Instant::now();
        let kind = (options.layout).unwrap_or_else(|| super::default_layout(device));
        let two = match options.refit {
            true => GpuTwoLevel::build_refittable(kind, set, &options.build)?,
            false => GpuTwoLevel::build(kind, set, &options.build)?,
        };
        log::info!(
            "{} meshes built ({}) and flattened into {kind}, top level over {} instances, in \
             {:.0} ms",
            set.meshes.len(),
            options.build.builder.name(),
            set.instances.len(),
            start.elapsed().as_secs_f64() * 1e3
        );
        let two = Arc::new(two);
        // Copied to the device, not shared: moving instances writes over its words.
        let gpu = match device.gpu_context() {
            Some(ctx) => Some(GpuTracer::new(ctx, two.as_ref(), options.memory)?),
            None => None,
        };
        let mut tracer = Self::over(two.clone(), gpu, options);
        tracer.two_level = Some(two);
        Ok(tracer)
    }

    /// Moves the instances of a tracer over instances ([`Tracer::with_instances`]):
    /// `maps[i]` places instance i, in order. Only the top level is built again
    /// ([`GpuTwoLevel::moved`]); on a GPU only its words are written over the uploaded
    /// arrays (the meshes' bottom levels stay where they are) and no kernel is compiled
    /// again. The hits are then those of a tracer built over the moved instances. Refused
    /// (nothing moved) for a tracer not over instances, or as [`GpuTwoLevel::moved`]
    /// refuses the maps.
    pub fn set_transforms(&mut self, maps: &[Affine]) -> Result<()> {
        let Some(two) = &self.two_level else {
            return Err(Error::Usage(
                "set_transforms moves the instances of a tracer made by with_instances".into(),
            ));
        };
        let moved = Arc::new(two.moved(maps, &self.options.build)?);
        if let Some(gpu) = &self.gpu {
            let (first, bytes) = moved.top_words();
            gpu.write_node_words(first, &bytes)?;
        }
        self.cpu = moved.clone();
        self.layout = Some(moved.clone());
        self.two_level = Some(moved);
        Ok(())
    }

    /// Moves the triangles of mesh `k` of a tracer over instances made with
    /// [`TracerOptions::refit`]: `moved` is that mesh deformed (the same triangles, in the
    /// same order). Its BVH is refit (bounds recomputed, shape kept) and flattened again,
    /// the top level built again; on a GPU only that mesh's words and the top level's are
    /// written over the uploaded arrays (the other meshes stay where they are) and no kernel
    /// is compiled again. The hits are then those of a tracer built over the moved mesh.
    /// Refused (nothing changed) as [`GpuTwoLevel::refit_mesh`] refuses.
    pub fn refit_mesh(&mut self, k: usize, moved: &Mesh) -> Result<()> {
        let Some(two) = &self.two_level else {
            return Err(Error::Usage(
                "refit_mesh refits a mesh of a tracer made by with_instances".into(),
            ));
        };
        let refit = Arc::new(two.refit_mesh(k, moved, &self.options.build)?);
        if let Some(gpu) = &self.gpu {
            if let Some(w) = refit.mesh_words(k) {
                gpu.write_node_words(w.node_base, w.nodes)?;
                gpu.write_tri_words(w.tri_base, w.tris)?;
            }
            let (first, bytes) = refit.top_words();
            gpu.write_node_words(first, &bytes)?;
        }
        self.cpu = refit.clone();
        self.layout = Some(refit.clone());
        self.two_level = Some(refit);
        Ok(())
    }

    /// A tracer over an already flattened layout (`options.build` and `options.layout` are
    /// then not used): benches and tests share one layout between tracers.
    pub fn with_layout(
        device: &'d Device,
        layout: Arc<dyn GpuForm>,
        options: &TracerOptions,
    ) -> Result<Self> {
        // Nothing writes over a layout's words once uploaded, so a device whose memory is
        // the host's may read them where they lie.
        let gpu = match device.gpu_context() {
            Some(ctx) => Some(GpuTracer::new_shared(ctx, &layout, options.memory)?),
            None => None,
        };
        Ok(Self::over(layout, gpu, options))
    }

    /// The tracer over `layout`, uploaded to `gpu` where there is one.
    fn over(layout: Arc<dyn GpuForm>, gpu: Option<GpuTracer<'d>>, options: &TracerOptions) -> Self {
        let mut tracer = Tracer {
            cpu: layout.clone(),
            layout: Some(layout),
            gpu,
            options: *options,
            mode: TraversalMode::PerRay,
            two_level: None,
        };
        tracer.resolve_mode();
        tracer
    }

    /// Settles the mode that runs for the options in force: the one asked for, or per-ray
    /// (with a warning naming why) where it cannot run.
    fn resolve_mode(&mut self) {
        let want = self.options.mode;
        let why = match (want, &self.gpu) {
            (TraversalMode::PerRay, _) => None,
            (TraversalMode::Subgroup, None) => Some("the CPU traces one ray at a time".to_string()),
            (TraversalMode::Subgroup, Some(gpu)) => {
                gpu.subgroup_unavailable(self.options.workgroup_size)
            }
        };
        self.mode = match why {
            None => want,
            Some(why) => {
                log::warn!("no {want} traversal ({why}): tracing per ray");
                TraversalMode::PerRay
            }
        };
    }

    /// The traversal mode that runs (see [`TraceResult::mode`]).
    pub fn mode(&self) -> TraversalMode {
        self.mode
    }

    /// Changes the traversal mode (no rebuild or upload); falls back to per-ray with a
    /// warning where the mode cannot run.
    pub fn set_mode(&mut self, mode: TraversalMode) {
        self.options.mode = mode;
        self.resolve_mode();
    }

    /// The layout traced (on the CPU, its twin): a BVH layout, or on a GPU device another
    /// structure's GPU form; None for a structure traced on the CPU only.
    pub fn layout(&self) -> Option<&Arc<dyn GpuForm>> {
        self.layout.as_ref()
    }

    /// The options in force.
    pub fn options(&self) -> &TracerOptions {
        &self.options
    }

    /// Changes the options that need no rebuild or upload: robustness, workgroup size,
    /// statistics.
    pub fn set_kernel(&mut self, robustness: Robustness, workgroup_size: u32, stats: bool) {
        let resolve = workgroup_size != self.options.workgroup_size;
        self.options.robustness = robustness;
        self.options.workgroup_size = workgroup_size;
        self.options.stats = stats;
        if resolve {
            self.resolve_mode();
        }
    }

    /// Traces a batch of rays: the closest hit or any hit of each.
    pub fn trace(&mut self, rays: &[Ray], query: Query) -> Result<TraceResult> {
        let o = self.options;
        if o.robustness.precision != Precision::F32 && self.layout.is_none() {
            return Err(Error::Usage(
                "f64 precision is the BVH's (its CPU twin's): use --accel bvh or --precision f32"
                    .into(),
            ));
        }
        match &mut self.gpu {
            Some(gpu) => {
                let kernel = TraceKernel {
                    query,
                    robustness: o.robustness,
                    stats: o.stats,
                    workgroup_size: o.workgroup_size,
                    mode: self.mode,
                };
                let (mut hits, mut stats, timings) = gpu.trace(rays, kernel)?;
                let cut: Vec<usize> = (0..hits.len())
                    .filter(|&i| hits[i].prim == INCOMPLETE)
                    .collect();
                if !cut.is_empty() {
                    log::warn!(
                        "{} of {} rays the GPU kernel could not finish (more loop iterations \
                         than the driver runs); traced them again on the CPU",
                        cut.len(),
                        rays.len()
                    );
                }
                for &i in &cut {
                    let mut s = RayStats::default();
                    hits[i] = self.cpu.intersect(&rays[i], query, &o.robustness, &mut s);
                    if let Some(stats) = stats.as_mut() {
                        stats[i] = s;
                    }
                }
                Ok(TraceResult {
                    hits,
                    stats,
                    timings,
                    cpu_retraced: cut.len(),
                    mode: self.mode,
                })
            }
            None => {
                let start = Instant::now();
                let (hits, stats) = match o.stats {
                    true => {
                        let (hits, stats) = self.cpu.trace_batch(rays, query, &o.robustness);
                        (hits, Some(stats))
                    }
                    false => (self.cpu.trace_hits(rays, query, &o.robustness), None),
                };
                Ok(TraceResult {
                    hits,
                    stats,
                    timings: Timings {
                        gpu_ms: None,
                        wall_ms: start.elapsed().as_secs_f64() * 1e3,
                    },
                    cpu_retraced: 0,
                    mode: self.mode,
                })
            }
        }
    }
}
