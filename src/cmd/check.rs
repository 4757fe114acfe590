//! `lancer check`: the CPU-vs-GPU equivalence test as a command. Traces the same rays on
//! each layout's CPU twin and GPU kernel (in each traversal mode) and prints, per layout, mode
//! and query, how many answers are identical, agree, are genuine ties (named by the f64
//! oracle) or disagree.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use clap::Args;
use lancer::accel::bvh::build;
use lancer::accel::bvh::layouts::{try_flatten, LayoutKind};
use lancer::accel::GpuForm;
use lancer::gpu::DriverTracer;
use lancer::mesh::load_mesh;
use lancer::trace::compare::{compare_hits, compare_hits_independent, Comparison};
use lancer::trace::files::decode_rays;
use lancer::{Device, Error, Query, Ray, Result, Tracer, TracerOptions, TraversalMode};
use serde::Serialize;

use super::input::load_bvh;
use super::out::{is_std, print_json, read_input, say, Say};
use super::{view_ray_sets, BuilderArgs, DeviceArgs, RobustnessArgs, BUILDER_IDS};

/// `check --json`: one object a run.
#[derive(Serialize)]
struct CheckReport {
    /// The GPU adapter checked.
    adapter: String,
    /// One row per layout, mode, ray set and query.
    rows: Vec<CheckRow>,
    /// Answers that disagree, over all rows (exit code 1 when above 0).
    disagree: usize,
    /// "LAYOUT MODE" pairs asked for by name that could not run (exit code 1).
    not_run: Vec<String>,
}

/// One layout × mode × ray set × query.
#[derive(Serialize)]
struct CheckRow {
    /// `--layout` name.
    layout: &'static str,
    /// Traversal mode.
    mode: &'static str,
    /// primary, shadow, bounce, or the ray file.
    rays: String,
    /// "closest" or "any".
    query: &'static str,
    /// False where the layout or the adapter has no such mode (the counts are then 0).
    ran: bool,
    /// Rays traced.
    count: usize,
    /// Answers equal bit for bit.
    identical: usize,
    /// Same triangle, t within 2 ulp (identical ones included).
    agree: usize,
    /// Different answers the f64 oracle finds both right.
    genuine_ties: usize,
    /// Wrong answers.
    disagree: usize,
}

impl CheckRow {
    /// The row of a ray set that was traced and compared.
    fn ran(
        layout: &'static str,
        mode: &'static str,
        rays: &str,
        query: Query,
        count: usize,
        cmp: &Comparison,
    ) -> CheckRow {
        CheckRow {
            layout,
            mode,
            rays: rays.to_string(),
            query: query_name(query),
            ran: true,
            count,
            identical: cmp.identical,
            agree: cmp.agree,
            genuine_ties: cmp.ties,
            disagree: cmp.disagree.len(),
        }
    }

    /// Prints the row and its first disagreements (`other` names the side compared with the
    /// CPU twin); returns how many answers disagree.
    fn report(&self, say: &Say, query: Query, other: &str, cmp: &Comparison) -> usize {
        let (layout, mode, name) = (self.layout, self.mode, &self.rays);
        say!(
            say,
            "| {layout} | {mode} | {name} | {query:?} | {} | {} | {} | {} | {} |",
            self.count,
            self.identical,
            self.agree,
            self.genuine_ties,
            self.disagree
        );
        for d in cmp.disagree.iter().take(3) {
            eprintln!(
                "  {layout} {mode} {name} ray {}: CPU {:?}, {other} {:?}: {}",
                d.ray, d.reference, d.other, d.why
            );
        }
        self.disagree
    }
}

/// A query as the JSON names it.
fn query_name(query: Query) -> &'static str {
    match query {
        Query::Closest => "closest",
        Query::Any => "any",
    }
}

/// A layout, or all of them.
#[derive(Clone, Copy, Debug)]
pub enum LayoutChoice {
    /// Every registered layout.
    All,
    /// One layout.
    One(LayoutKind),
}

/// `--layout NAME|all`.
pub fn layout_choice(s: &str) -> std::result::Result<LayoutChoice, String> {
    use clap::ValueEnum;
    if s == "all" {
        return Ok(LayoutChoice::All);
    }
    LayoutKind::from_str(s, false)
        .map(LayoutChoice::One)
        .map_err(|_| {
            let names: Vec<&str> = LayoutKind::ALL.iter().map(|k| k.name()).collect();
            format!(
                "unknown layout {s:?}: use all or one of {}",
                names.join(", ")
            )
        })
}

/// A traversal mode, or all of them.
#[derive(Clone, Copy, Debug)]
pub enum ModeChoice {
    /// Every mode the layout and adapter offer.
    All,
    /// One mode.
    One(TraversalMode),
}

/// `--mode NAME|all`.
pub fn mode_choice(s: &str) -> std::result::Result<ModeChoice, String> {
    use clap::ValueEnum;
    if s == "all" {
        return Ok(ModeChoice::All);
    }
    TraversalMode::from_str(s, false)
        .map(ModeChoice::One)
        .map_err(|_| {
            let names: Vec<&str> = TraversalMode::ALL.iter().map(|m| m.name()).collect();
            format!("unknown mode {s:?}: use all or one of {}", names.join(", "))
        })
}

impl LayoutChoice {
    /// The layouts chosen.
    pub fn kinds(self) -> Vec<LayoutKind> {
        match self {
            LayoutChoice::All => LayoutKind::ALL.to_vec(),
            LayoutChoice::One(k) => vec![k],
        }
    }
}

#[derive(Args)]
pub struct CheckCmd {
    /// Mesh (.obj, .ply, .gltf, .glb).
    mesh: PathBuf,
    /// Ray file (32 bytes a ray), or - for stdin; by default the primary rays of the default view
    /// (--width × --height) and the shadow and diffuse bounce rays from their hits.
    #[arg(long)]
    rays: Option<PathBuf>,
    /// GpuForm to check: a name or all.
    #[arg(long = "layout", value_name = "NAME|all", default_value = "all", value_parser = layout_choice)]
    layouts: LayoutChoice,
    /// GPU traversal mode to check: per-ray, subgroup, or all (each mode the layout and the
    /// adapter offer; a mode that cannot run is named and skipped).
    #[arg(long = "mode", value_name = "NAME|all", default_value = "all", value_parser = mode_choice)]
    modes: ModeChoice,
    /// Width of the default view.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Height of the default view.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    device: DeviceArgs,
    #[command(flatten)]
    robustness: RobustnessArgs,
    #[command(flatten)]
    build: BuilderArgs,
    /// Check the BVH in this file (`build --out`; docs/src/reference/file-formats.md) instead of
    /// building one: only its layout is checked (--layout and the builder options are
    /// refused with it), and MESH must be the mesh it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = BUILDER_IDS, conflicts_with = "layouts")]
    bvh: Option<PathBuf>,
    /// Print the results as one JSON object on stdout, the table on stderr (keys: the
    /// book's JSON page, docs/src/reference/json.md).
    #[arg(long)]
    json: bool,
}

impl CheckCmd {
    pub fn run(self) -> Result<()> {
        let say = Say::new(self.json);
        let mesh = load_mesh(&self.mesh)?;
        // A check needs a GPU: auto takes any adapter here, a software one included.
        let device = self.device.open_any_gpu()?;
        let Some(ctx) = device.gpu_context() else {
            return Err(Error::Gpu(
                "check compares the GPU with the CPU and no GPU adapter opened: install a Vulkan \
                 driver (lavapipe: mesa-vulkan-drivers) or run on a machine with a GPU"
                    .into(),
            ));
        };
        let bvh = (self.bvh.as_ref())
            .map(|p| load_bvh(p, &mesh))
            .transpose()?;
        // Built when a layout is flattened here, not for a file's; each layout flattened once
        // (the default one serves the ray sets, its row and the driver's).
        let mut tree = None;
        let mut flat: HashMap<LayoutKind, Arc<dyn GpuForm>> = HashMap::new();
        let mut layout_of = |kind: LayoutKind| -> lancer::Result<Arc<dyn GpuForm>> {
            if let Some(file) = &bvh {
                return Ok(file.layout.clone());
            }
            if let Some(layout) = flat.get(&kind) {
                return Ok(layout.clone());
            }
            let tree = tree.get_or_insert_with(|| build(&mesh, &self.build.options()));
            let layout: Arc<dyn GpuForm> = try_flatten(kind, tree, &mesh)?.into();
            flat.insert(kind, layout.clone());
            Ok(layout)
        };
        let kinds = match &bvh {
            Some(file) => vec![file.kind],
            None => self.layouts.kinds(),
        };
        let sets: Vec<(String, Query, Vec<Ray>)> = match &self.rays {
            Some(path) => {
                let name = match is_std(path) {
                    true => PathBuf::from("<stdin>"),
                    false => path.clone(),
                };
                let rays = decode_rays(&name, &read_input(path)?)?;
                let name = name.display().to_string();
                vec![
                    (name.clone(), Query::Closest, rays.clone()),
                    (name, Query::Any, rays),
                ]
            }
            None => {
                let reference = layout_of(LayoutKind::DfsSign)?;
                let rob = self.robustness.robustness();
                view_ray_sets(&mesh, reference.as_ref(), self.width, self.height, &rob)?
            }
        };
        say!(say, "adapter {}", ctx.adapter);
        say!(
            say,
            "| layout | mode | rays | query | count | identical | agree | genuine ties | disagree |"
        );
        say!(say, "|---|---|---|---|---|---|---|---|---|");
        let mut rows = Vec::new();
        let cpu = Device::cpu();
        let mut bad = 0usize;
        let mut not_run = Vec::new();
        for kind in kinds {
            let layout = layout_of(kind)?;
            let options = TracerOptions {
                layout: Some(kind),
                memory: self.device.bvh_memory(),
                robustness: self.robustness.robustness(),
                ..TracerOptions::default()
            };
            let mut twin = Tracer::with_layout(&cpu, layout.clone(), &options)?;
            let mut gpu = Tracer::with_layout(&device, layout, &options)?;
            let twin_hits: Vec<_> = (sets.iter())
                .map(|(_, query, rays)| Ok(twin.trace(rays, *query)?.hits))
                .collect::<Result<_>>()?;
            let modes = match self.modes {
                ModeChoice::All => TraversalMode::ALL.to_vec(),
                ModeChoice::One(m) => vec![m],
            };
            for mode in modes {
                gpu.set_mode(mode);
                if gpu.mode() != mode {
                    // The library's warning says why; a mode asked for by name is an error.
                    say!(say, "| {kind} | {mode} | – | – | – | – | – | – | not run |");
                    rows.push(CheckRow {
                        layout: kind.name(),
                        mode: mode.name(),
                        rays: String::new(),
                        query: "",
                        ran: false,
                        count: 0,
                        identical: 0,
                        agree: 0,
                        genuine_ties: 0,
                        disagree: 0,
                    });
                    if let ModeChoice::One(_) = self.modes {
                        not_run.push(format!("{kind} {mode}"));
                    }
                    continue;
                }
                for ((name, query, rays), c) in sets.iter().zip(&twin_hits) {
                    let g = gpu.trace(rays, *query)?.hits;
                    let cmp = compare_hits(&mesh, rays, *query, c, &g);
                    let row =
                        CheckRow::ran(kind.name(), mode.name(), name, *query, rays.len(), &cmp);
                    bad += row.report(&say, *query, "GPU", &cmp);
                    rows.push(row);
                }
            }
        }
        // The driver's own traversal, an independent oracle where the adapter has ray
        // queries: against the default layout's CPU twin (the file's with --bvh).
        if ctx.ray_query {
            let reference = layout_of(LayoutKind::DfsSign)?;
            let mut twin = Tracer::with_layout(&cpu, reference.clone(), &TracerOptions::default())?;
            let mut driver = DriverTracer::new(ctx, reference.as_ref())?;
            for (name, query, rays) in &sets {
                let c = twin.trace(rays, *query)?.hits;
                let d = driver.trace(rays, *query)?.0;
                let cmp = compare_hits_independent(&mesh, rays, *query, &c, &d);
                let row = CheckRow::ran("driver", "ray-query", name, *query, rays.len(), &cmp);
                bad += row.report(&say, *query, "driver", &cmp);
                rows.push(row);
            }
        } else {
            say!(
                say,
                "(no driver rows: {} offers no ray queries; lavapipe from Mesa 25 does)",
                ctx.adapter.name
            );
        }
        if self.json {
            print_json(&CheckReport {
                adapter: ctx.adapter.to_string(),
                rows,
                disagree: bad,
                not_run: not_run.clone(),
            })?;
        }
        if bad > 0 {
            return Err(Error::Differ(format!(
                "{bad} answers disagree between the GPU and the CPU twin (listed above)"
            )));
        }
        if !not_run.is_empty() {
            return Err(Error::Gpu(format!(
                "{} could not run on {} (the warning above says why)",
                not_run.join(", "),
                ctx.adapter.name
            )));
        }
        say!(say, "every answer agrees or is a genuine tie");
        Ok(())
    }
}
