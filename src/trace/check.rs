//! The CPU-vs-GPU equivalence check (`lancer check`): the same rays traced on each layout's
//! CPU twin and its GPU kernel (in each traversal mode), and on the driver's own traversal
//! where the adapter has ray queries; per layout, mode, ray set and query, how many answers
//! are identical, agree, are genuine ties (named by the f64 oracle) or disagree.
//!
//! A BVH file's answers are judged too ([`ORACLE_MODE`] rows): a twin and a kernel that
//! read the same wrong arrays agree with each other, so the file's CPU-twin answers are
//! compared with those of a tree built here from the mesh, and every difference is judged
//! by the f64 oracle; an answer it finds wrong is a disagreement.

use std::collections::HashMap;
use std::sync::Arc;

use serde::Serialize;

use super::compare::{compare_hits, compare_hits_independent, Comparison, Disagreement};
use super::files::{view_ray_sets, RaySet};
use super::{Tracer, TracerOptions};
use crate::accel::bvh::layouts::bvh_file::BvhFile;
use crate::accel::bvh::layouts::{try_flatten, LayoutKind};
use crate::accel::bvh::{build, BuildOptions};
use crate::accel::{GpuForm, Query, TraversalMode};
use crate::device::Device;
use crate::error::{Error, Result};
use crate::geometry::{Ray, Robustness};
use crate::gpu::{BvhMemory, DriverTracer, GpuContext};
use crate::mesh::Mesh;

/// Disagreements a row keeps for its report (the first ones).
pub const KEPT_DISAGREEMENTS: usize = 3;

/// The mode of the rows that judge a BVH file's answers: its CPU twin's answers against a
/// tree built here from the mesh, the differences judged by the f64 oracle.
pub const ORACLE_MODE: &str = "oracle";

/// The rays a check traces.
#[derive(Clone, Debug)]
pub enum CheckRays {
    /// The default view's primary rays (`width` × `height`), and the shadow and diffuse
    /// bounce rays from their hits ([`view_ray_sets`]).
    View {
        /// Width of the view.
        width: u32,
        /// Height of the view.
        height: u32,
    },
    /// Given rays (a ray file, named `name`), traced for the closest and for any hit.
    Given {
        /// What the rows call them.
        name: String,
        /// The rays.
        rays: Vec<Ray>,
    },
}

/// What [`run`] checks.
pub struct CheckConfig {
    /// The rays.
    pub rays: CheckRays,
    /// The layouts to flatten and check (ignored with `bvh`: its layout is checked).
    pub layouts: Vec<LayoutKind>,
    /// One traversal mode (one that cannot run is listed in [`CheckReport::not_run`]), or
    /// `None`: every mode the layout and the adapter offer (one that cannot run is a row
    /// that did not run).
    pub mode: Option<TraversalMode>,
    /// How the tree is built before each layout is flattened.
    pub build: BuildOptions,
    /// A BVH file (built from the mesh) to check instead of building one; its answers are
    /// also judged by the f64 oracle ([`ORACLE_MODE`] rows).
    pub bvh: Option<BvhFile>,
    /// Where the GPU kernels read the BVH from.
    pub memory: BvhMemory,
    /// The robustness knobs the tracers use.
    pub robustness: Robustness,
}

impl CheckConfig {
    /// Every layout in every mode on the default view of `width` × `height`, default
    /// options.
    pub fn view(width: u32, height: u32) -> CheckConfig {
        CheckConfig {
            rays: CheckRays::View { width, height },
            layouts: LayoutKind::ALL.to_vec(),
            mode: None,
            build: BuildOptions::default(),
            bvh: None,
            memory: BvhMemory::default(),
            robustness: Robustness::default(),
        }
    }
}

/// A check's result (`check --json`: one object a run).
#[derive(Clone, Debug, Serialize)]
pub struct CheckReport {
    /// The GPU adapter checked.
    pub adapter: String,
    /// One row per layout, mode, ray set and query.
    pub rows: Vec<CheckRow>,
    /// Answers that disagree, over all rows (exit code 1 when above 0).
    pub disagree: usize,
    /// "LAYOUT MODE" pairs asked for by name that could not run (exit code 1).
    pub not_run: Vec<String>,
    /// The adapter's name.
    #[serde(skip)]
    pub adapter_name: String,
    /// Whether the driver's own traversal was checked (the adapter has ray queries).
    #[serde(skip)]
    pub driver: bool,
}

/// One layout × mode × ray set × query.
#[derive(Clone, Debug, Serialize)]
pub struct CheckRow {
    /// `--layout` name ("driver" for the driver's own traversal).
    pub layout: &'static str,
    /// Traversal mode ("ray-query" for the driver's; [`ORACLE_MODE`] for a BVH file's
    /// answers against a tree built here, judged by the oracle).
    pub mode: &'static str,
    /// primary, shadow, bounce, or the ray file.
    pub rays: String,
    /// "closest" or "any".
    pub query: &'static str,
    /// False where the layout or the adapter has no such mode (the counts are then 0).
    pub ran: bool,
    /// Rays traced.
    pub count: usize,
    /// Answers equal bit for bit.
    pub identical: usize,
    /// Same triangle, t within 2 ulp (identical ones included).
    pub agree: usize,
    /// Different answers the f64 oracle finds both right.
    pub genuine_ties: usize,
    /// Wrong answers.
    pub disagree: usize,
    /// The first [`KEPT_DISAGREEMENTS`] wrong answers.
    #[serde(skip)]
    pub first_disagreements: Vec<Disagreement>,
}

/// The markdown table's header lines.
pub const TABLE_HEADER: [&str; 2] = [
    "| layout | mode | rays | query | count | identical | agree | genuine ties | disagree |",
    "|---|---|---|---|---|---|---|---|---|",
];

impl CheckRow {
    /// The row of a ray set that was traced and compared.
    pub fn ran(
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
            first_disagreements: cmp
                .disagree
                .iter()
                .take(KEPT_DISAGREEMENTS)
                .cloned()
                .collect(),
        }
    }

    /// The row of a mode that could not run.
    pub fn not_run(layout: LayoutKind, mode: TraversalMode) -> CheckRow {
        CheckRow {
            layout: layout.name(),
            mode: mode.name(),
            rays: String::new(),
            query: "",
            ran: false,
            count: 0,
            identical: 0,
            agree: 0,
            genuine_ties: 0,
            disagree: 0,
            first_disagreements: Vec::new(),
        }
    }

    /// The row as a line of the markdown table ([`TABLE_HEADER`]).
    pub fn markdown(&self) -> String {
        let (layout, mode, name) = (self.layout, self.mode, &self.rays);
        if !self.ran {
            return format!("| {layout} | {mode} | – | – | – | – | – | – | not run |");
        }
        let query = if self.query == "any" {
            Query::Any
        } else {
            Query::Closest
        };
        format!(
            "| {layout} | {mode} | {name} | {query:?} | {} | {} | {} | {} | {} |",
            self.count, self.identical, self.agree, self.genuine_ties, self.disagree
        )
    }

    /// One line for each of the first disagreements: the ray, the CPU twin's answer and the
    /// other side's (the GPU's, or the driver's), and what the oracle found wrong; on an
    /// [`ORACLE_MODE`] row, the answer of the tree built here and the file's.
    pub fn disagreement_lines(&self) -> Vec<String> {
        let (reference, other) = match (self.layout, self.mode) {
            ("driver", _) => ("CPU", "driver"),
            (_, ORACLE_MODE) => ("built here", "file"),
            _ => ("CPU", "GPU"),
        };
        (self.first_disagreements.iter())
            .map(|d| {
                format!(
                    "  {} {} {} ray {}: {reference} {:?}, {other} {:?}: {}",
                    self.layout, self.mode, self.rays, d.ray, d.reference, d.other, d.why
                )
            })
            .collect()
    }
}

impl CheckReport {
    /// The markdown table: [`TABLE_HEADER`] and one line a row.
    pub fn table(&self) -> Vec<String> {
        (TABLE_HEADER.iter().map(|s| s.to_string()))
            .chain(self.rows.iter().map(CheckRow::markdown))
            .collect()
    }
}

/// A query as the JSON names it.
pub fn query_name(query: Query) -> &'static str {
    match query {
        Query::Closest => "closest",
        Query::Any => "any",
    }
}

/// A layout, or all of them (`--layout NAME|all`).
#[derive(Clone, Copy, Debug)]
pub enum LayoutChoice {
    /// Every registered layout.
    All,
    /// One layout.
    One(LayoutKind),
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

/// `all` or a layout's name.
pub fn layout_choice(s: &str) -> std::result::Result<LayoutChoice, String> {
    if s == "all" {
        return Ok(LayoutChoice::All);
    }
    (LayoutKind::ALL.iter().find(|k| k.name() == s))
        .map(|&k| LayoutChoice::One(k))
        .ok_or_else(|| {
            let names: Vec<&str> = LayoutKind::ALL.iter().map(|k| k.name()).collect();
            format!(
                "unknown layout {s:?}: use all or one of {}",
                names.join(", ")
            )
        })
}

/// A traversal mode, or all of them (`--mode NAME|all`).
#[derive(Clone, Copy, Debug)]
pub enum ModeChoice {
    /// Every mode the layout and adapter offer.
    All,
    /// One mode.
    One(TraversalMode),
}

impl ModeChoice {
    /// The mode chosen, or `None` for all ([`CheckConfig::mode`]).
    pub fn mode(self) -> Option<TraversalMode> {
        match self {
            ModeChoice::All => None,
            ModeChoice::One(m) => Some(m),
        }
    }
}

/// `all` or a traversal mode's name.
pub fn mode_choice(s: &str) -> std::result::Result<ModeChoice, String> {
    if s == "all" {
        return Ok(ModeChoice::All);
    }
    (TraversalMode::ALL.iter().find(|m| m.name() == s))
        .map(|&m| ModeChoice::One(m))
        .ok_or_else(|| {
            let names: Vec<&str> = TraversalMode::ALL.iter().map(|m| m.name()).collect();
            format!("unknown mode {s:?}: use all or one of {}", names.join(", "))
        })
}

/// What [`run`] reports as it goes.
pub enum CheckProgress<'a> {
    /// The ray sets are ready and tracing starts, on this adapter.
    Started {
        /// The adapter (as [`CheckReport::adapter`] names it).
        adapter: &'a str,
    },
    /// A row is done.
    Row(&'a CheckRow),
}

/// The GPU of `device`, or the error of a check without one.
pub fn require_gpu(device: &Device) -> Result<&GpuContext> {
    device.gpu_context().ok_or_else(|| {
        Error::Gpu(
            "check compares the GPU with the CPU and no GPU adapter opened: install a Vulkan \
             driver (lavapipe: mesa-vulkan-drivers) or run on a machine with a GPU"
                .into(),
        )
    })
}

/// Checks each layout's GPU kernel against its CPU twin on `device` (a GPU; a CPU device
/// is refused), and the driver's own traversal where the adapter has ray queries; a BVH
/// file's answers are also judged by the f64 oracle ([`ORACLE_MODE`]). Errors only where
/// something cannot run at all; disagreements are counted in the report.
pub fn run(
    device: &Device,
    mesh: &Mesh,
    config: &CheckConfig,
    mut progress: impl FnMut(CheckProgress<'_>),
) -> Result<CheckReport> {
    let ctx = require_gpu(device)?;
    // Built when a layout is flattened here, not for a file's; each layout flattened once
    // (the default one serves the ray sets, its row and the driver's).
    let mut tree = None;
    let mut flat: HashMap<LayoutKind, Arc<dyn GpuForm>> = HashMap::new();
    let mut layout_of = |kind: LayoutKind| -> Result<Arc<dyn GpuForm>> {
        if let Some(file) = &config.bvh {
            return Ok(file.layout.clone());
        }
        if let Some(layout) = flat.get(&kind) {
            return Ok(layout.clone());
        }
        let tree = tree.get_or_insert_with(|| build(mesh, &config.build));
        let layout: Arc<dyn GpuForm> = try_flatten(kind, tree, mesh)?.into();
        flat.insert(kind, layout.clone());
        Ok(layout)
    };
    let kinds = match &config.bvh {
        Some(file) => vec![file.kind],
        None => config.layouts.clone(),
    };
    let sets: Vec<RaySet> = match &config.rays {
        CheckRays::Given { name, rays } => vec![
            (name.clone(), Query::Closest, rays.clone()),
            (name.clone(), Query::Any, rays.clone()),
        ],
        CheckRays::View { width, height } => {
            let reference = layout_of(LayoutKind::DfsSign)?;
            view_ray_sets(
                mesh,
                reference.as_ref(),
                *width,
                *height,
                &config.robustness,
            )?
        }
    };
    let mut report = CheckReport {
        adapter: ctx.adapter.to_string(),
        rows: Vec::new(),
        disagree: 0,
        not_run: Vec::new(),
        adapter_name: ctx.adapter.name.clone(),
        driver: ctx.ray_query,
    };
    progress(CheckProgress::Started {
        adapter: &report.adapter,
    });
    let mut add = |report: &mut CheckReport, row: CheckRow| {
        progress(CheckProgress::Row(&row));
        report.disagree += row.disagree;
        report.rows.push(row);
    };
    let cpu = Device::cpu();
    for kind in kinds {
        let layout = layout_of(kind)?;
        let options = TracerOptions {
            layout: Some(kind),
            memory: config.memory,
            robustness: config.robustness,
            ..TracerOptions::default()
        };
        let mut twin = Tracer::with_layout(&cpu, layout.clone(), &options)?;
        let mut gpu = Tracer::with_layout(device, layout, &options)?;
        let twin_hits: Vec<_> = (sets.iter())
            .map(|(_, query, rays)| Ok(twin.trace(rays, *query)?.hits))
            .collect::<Result<_>>()?;
        let modes = match config.mode {
            None => TraversalMode::ALL.to_vec(),
            Some(m) => vec![m],
        };
        for mode in modes {
            gpu.set_mode(mode);
            if gpu.mode() != mode {
                // The library's warning says why; a mode asked for by name is an error.
                add(&mut report, CheckRow::not_run(kind, mode));
                if config.mode.is_some() {
                    report.not_run.push(format!("{kind} {mode}"));
                }
                continue;
            }
            for ((name, query, rays), c) in sets.iter().zip(&twin_hits) {
                let g = gpu.trace(rays, *query)?.hits;
                let cmp = compare_hits(mesh, rays, *query, c, &g);
                add(
                    &mut report,
                    CheckRow::ran(kind.name(), mode.name(), name, *query, rays.len(), &cmp),
                );
            }
        }
        // A file's twin and kernel read the same arrays, so they agree on wrong answers
        // too: the twin's answers against a tree built here, each difference judged by
        // the f64 oracle (brute force only where they differ).
        if config.bvh.is_some() {
            let here: Arc<dyn GpuForm> =
                try_flatten(kind, &build(mesh, &config.build), mesh)?.into();
            let mut here = Tracer::with_layout(&cpu, here, &options)?;
            for ((name, query, rays), c) in sets.iter().zip(&twin_hits) {
                let h = here.trace(rays, *query)?.hits;
                let cmp = compare_hits(mesh, rays, *query, &h, c);
                add(
                    &mut report,
                    CheckRow::ran(kind.name(), ORACLE_MODE, name, *query, rays.len(), &cmp),
                );
            }
        }
    }
    // The driver's own traversal, an independent oracle where the adapter has ray
    // queries: against the default layout's CPU twin (the file's with a BVH file).
    if ctx.ray_query {
        let reference = layout_of(LayoutKind::DfsSign)?;
        let mut twin = Tracer::with_layout(&cpu, reference.clone(), &TracerOptions::default())?;
        let mut driver = DriverTracer::new(ctx, reference.as_ref())?;
        for (name, query, rays) in &sets {
            let c = twin.trace(rays, *query)?.hits;
            let d = driver.trace(rays, *query)?.0;
            let cmp = compare_hits_independent(mesh, rays, *query, &c, &d);
            add(
                &mut report,
                CheckRow::ran("driver", "ray-query", name, *query, rays.len(), &cmp),
            );
        }
    }
    Ok(report)
}
