use std::path::PathBuf;

use clap::Args;
use lancer::accel::bvh::Builder;
use lancer::mesh::InstanceSet;
use lancer::trace::files::encode_hits;
use lancer::trace::stats::{TraceReport, TraceStats};
use lancer::trace::TraceResult;
use lancer::{AccelKind, Error, LayoutKind, Query, Result, Tracer, TracerOptions, TraversalMode};

use super::input::load_bvh;
use super::out::{check_output, is_std, print_json, read_rays, say, write_output, Say};
use super::{BuildArgs, DeviceArgs, RobustnessArgs, BVH_CONFLICTS};
use lancer::render::{load_geometry, load_traceable, Geometry};

#[derive(Args)]
pub struct TraceCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Input ray file (32 bytes a ray; docs/src/reference/file-formats.md), or - for stdin.
    #[arg(long)]
    rays: PathBuf,
    /// Output hit file (16 bytes a ray), or - for stdout (text then goes to stderr).
    #[arg(short, long)]
    out: PathBuf,
    #[command(flatten)]
    device: DeviceArgs,
    /// Any hit (occlusion) instead of the closest hit.
    #[arg(long)]
    any_hit: bool,
    #[command(flatten)]
    robustness: RobustnessArgs,
    /// Print traversal statistics: device, structure, layout, mode, times, work per ray.
    #[arg(long)]
    stats: bool,
    /// Print the summary (and the --stats) as one JSON object on stdout, the text on
    /// stderr; the keys are described in the book's JSON page, docs/src/reference/json.md.
    #[arg(long)]
    json: bool,
    /// GPU: invocations per workgroup (the adapter's limit applies).
    #[arg(long, default_value_t = 64)]
    workgroup_size: u32,
    /// GPU traversal: one ray per invocation, or the lanes of a subgroup together (falls
    /// back to per-ray, with a warning, where the adapter or layout has no subgroup mode).
    #[arg(long, value_enum, default_value_t = TraversalMode::PerRay)]
    mode: TraversalMode,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure (all but the BVH, the kd-tree and the BIH run on the CPU).
    #[arg(long, value_parser = super::accel_arg(), default_value = "bvh")]
    accel: lancer::AccelKind,
    /// Trace the BVH in this file (`build --out`; docs/src/reference/file-formats.md) instead of
    /// building one: its layout is the file's (--accel, --layout and the builder options are
    /// refused with it), and MESH must be the mesh it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = BVH_CONFLICTS)]
    bvh: Option<PathBuf>,
    /// Trace one BVH over the whole scene, flattened, where the file places a mesh more than
    /// once (a glTF mesh drawn by several nodes); without it such a scene is traced in two
    /// levels, a BVH per mesh under one over the instances. Hits are numbered alike.
    #[arg(long)]
    flatten: bool,
    /// Where the BVH is built: cpu, or gpu (--builder lbvh: the same tree, built by WGSL
    /// kernels on the GPU device and flattened there into dfs-sign, else read back and
    /// flattened on the CPU; without a GPU the CPU builds it, with a warning).
    #[arg(long, value_enum, default_value_t = lancer::trace::BuildOn::Cpu, conflicts_with = "bvh")]
    build_on: lancer::trace::BuildOn,
}

impl TraceCmd {
    pub fn run(self) -> Result<()> {
        let to_stdout = is_std(&self.out);
        if to_stdout && self.json {
            return Err(Error::Usage(
                "--json and --out - both write to stdout: write the hits to a file".into(),
            ));
        }
        let builder = self.build.options().builder;
        if self.build_on == lancer::trace::BuildOn::Gpu && builder != Builder::Lbvh {
            return Err(Error::Usage(format!(
                "--build-on gpu builds with --builder lbvh only, not {}",
                builder.name()
            )));
        }
        let say = Say::new(to_stdout || self.json);
        let two_level = matches!(self.accel, AccelKind::Bvh(_)) && self.bvh.is_none();
        let mesh = match two_level && !self.flatten {
            true => match load_traceable(&self.mesh)? {
                Geometry::Placed(set) => return self.run_instanced(&set, say),
                Geometry::Mesh(mesh) => mesh,
            },
            false => load_geometry(&self.mesh)?,
        };
        let mut inputs = mesh.sources.clone();
        inputs.push(self.rays.clone());
        inputs.extend(self.bvh.clone());
        check_output(&self.out, &inputs)?;
        // The rays are read once the structure is built (they would add to its peak of
        // memory); a ray file of partial rays is refused now.
        if !is_std(&self.rays) {
            lancer::trace::files::check_ray_file(&self.rays)?;
        }
        let bvh = (self.bvh.as_ref())
            .map(|p| load_bvh(p, &mesh))
            .transpose()?;
        let device = self.device.open_for(self.accel)?;
        let layout = bvh
            .as_ref()
            .map_or(self.build.layout_on(&device), |f| f.kind);
        let options = self.options(layout);
        let kind = self.accel.with_layout(layout);
        let mut tracer = match &bvh {
            Some(file) => Tracer::with_layout(&device, file.layout.clone(), &options)?,
            // A BVH's layout holds the triangles: the mesh goes before the upload.
            None if matches!(kind, AccelKind::Bvh(_)) => {
                Tracer::from_mesh(&device, mesh, &options)?
            }
            None => Tracer::with_structure(&device, &mesh, kind, &options)?,
        };
        let rays = read_rays(&self.rays)?;
        let result = tracer.trace(&rays, self.query())?;
        self.report(
            &result,
            TraceStats::new(&result, &device, kind, layout, &options),
            say,
        )
    }

    /// Traces a scene of meshes placed by instances in two levels.
    fn run_instanced(&self, set: &InstanceSet, say: Say) -> Result<()> {
        log::info!(
            "{}: {} meshes placed by {} instances ({} triangles instanced): traced in two \
             levels (--flatten: one BVH over the flattened scene)",
            self.mesh.display(),
            set.meshes.len(),
            set.instances.len(),
            set.triangle_count()
        );
        let mut inputs: Vec<PathBuf> = set.meshes.iter().flat_map(|m| m.sources.clone()).collect();
        inputs.push(self.rays.clone());
        check_output(&self.out, &inputs)?;
        let rays = read_rays(&self.rays)?;
        let device = self.device.open_for(self.accel)?;
        let layout = self.build.layout_on(&device);
        let options = self.options(layout);
        let mut tracer = Tracer::with_instances(&device, set, &options)?;
        let result = tracer.trace(&rays, self.query())?;
        let kind = self.accel.with_layout(layout);
        self.report(
            &result,
            TraceStats::new(&result, &device, kind, layout, &options),
            say,
        )
    }

    /// The tracer's options, the layout settled.
    fn options(&self, layout: LayoutKind) -> TracerOptions {
        TracerOptions {
            build: self.build.options(),
            layout: Some(layout),
            memory: self.device.bvh_memory,
            robustness: self.robustness.robustness(),
            workgroup_size: self.workgroup_size,
            stats: self.stats,
            mode: self.mode,
            refit: false,
            flatten: self.flatten,
            build_on: self.build_on,
        }
    }

    fn query(&self) -> Query {
        if self.any_hit {
            Query::Any
        } else {
            Query::Closest
        }
    }

    /// Writes the hits and prints the summary (and the statistics).
    fn report(&self, result: &TraceResult, stats: TraceStats, say: Say) -> Result<()> {
        if self.stats {
            stats.text().into_iter().for_each(|l| say!(say, "{l}"));
        }
        write_output(&self.out, &encode_hits(&result.hits))?;
        let report = TraceReport::new(result, &self.out.display().to_string(), None);
        report
            .text(result)
            .into_iter()
            .for_each(|l| say!(say, "{l}"));
        if self.json {
            print_json(&TraceReport {
                stats: self.stats.then_some(stats),
                ..report
            })?;
        }
        Ok(())
    }
}
