//! The benchmarks behind `lancer bench …`, as library code: each bench is a module with a
//! plain `Config`, a `run(&Config, progress) -> Result<Report>` and a `Report` that
//! serialises to the JSON the CLI writes (serde) and renders as the markdown tables it
//! prints ([`BenchReport::text`]). `progress` is called with a [`Progress`] as the work
//! advances (the CLI draws a bar from it; [`silent`] ignores it).
//!
//! - [`layouts`]: every flattened BVH layout on one mesh (CPU twin and GPU kernel; the
//!   driver's ray queries and, with the `embree` feature, Embree 3 in the same run);
//! - [`structures`]: every acceleration structure on one mesh or scene;
//! - [`builders`]: every BVH builder on several meshes, and which a-priori cost predicts
//!   the measured speed;
//! - [`accuracy`]: what each robustness knob costs in time and the error it leaves;
//! - [`render`]: milliseconds per sample, specialised and all-effects kernels;
//! - [`trace`]: one structure's GPU kernel over BVH memory × workgroup × module;
//! - [`instances`]: a mesh placed many times, in two levels against its flattened copy;
//! - [`refit`]: a deforming mesh's BVH refit against rebuilt;
//! - [`scale`]: from a mesh file to its first traced rays, step by step, and the peak
//!   memory on the way.
//!
//! Shared pieces: [`timing`] (medians, paired runs), [`rays`] (the ray sets every bench
//! traces), [`markdown`] (tables), [`memory`] (peak heap bytes), [`rank`] (rank
//! correlation), [`page`] (a dated results page, `--report`), and with the
//! `charts` feature [`chart`] (PNG charts, plotters) and [`colour_bar`] (the heatmap's bar).

pub mod accuracy;
pub mod builders;
#[cfg(feature = "charts")]
pub mod chart;
#[cfg(feature = "charts")]
pub mod colour_bar;
pub mod heatmap;
pub mod instances;
pub mod layouts;
pub mod markdown;
pub mod memory;
pub mod page;
pub mod rank;
pub mod rays;
pub mod refit;
pub mod render;
pub mod scale;
pub mod structures;
pub mod timing;
pub mod trace;

use std::cell::{Cell, RefCell};
use std::path::Path;

use crate::device::{Device, DeviceChoice};
use crate::error::Result;

/// How far a bench has come: `done` of `total` steps (timed runs, samples or settings; the
/// total can grow as the bench finds more to do), and what it is doing now.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// Steps done.
    pub done: u64,
    /// Steps in all, as far as known.
    pub total: u64,
    /// What runs now (a layout's name, a setting), or empty.
    pub message: String,
}

/// A progress callback that ignores every report.
pub fn silent(_: Progress) {}

/// Counts a bench's steps and tells its progress callback of each change.
pub(crate) struct Ticker<'a> {
    report: &'a dyn Fn(Progress),
    done: Cell<u64>,
    total: Cell<u64>,
    message: RefCell<String>,
}

impl<'a> Ticker<'a> {
    /// A count of `total` steps, none done.
    pub(crate) fn new(report: &'a dyn Fn(Progress), total: u64) -> Ticker<'a> {
        let t = Ticker {
            report,
            done: Cell::new(0),
            total: Cell::new(total),
            message: RefCell::new(String::new()),
        };
        t.tell();
        t
    }

    fn tell(&self) {
        (self.report)(Progress {
            done: self.done.get(),
            total: self.total.get(),
            message: self.message.borrow().clone(),
        });
    }

    /// `n` more steps done.
    pub(crate) fn inc(&self, n: u64) {
        self.done.set(self.done.get() + n);
        self.tell();
    }

    /// `n` more steps to do.
    pub(crate) fn grow(&self, n: u64) {
        self.total.set(self.total.get() + n);
        self.tell();
    }

    /// What runs now.
    pub(crate) fn say(&self, message: impl Into<String>) {
        *self.message.borrow_mut() = message.into();
        self.tell();
    }
}

/// What every bench's report gives beside its JSON: a title, the adapter it measured,
/// the text the CLI prints (markdown tables and notes), and its charts.
pub trait BenchReport: serde::Serialize {
    /// The chart files a results page draws beside itself, by suffix: `""` is `NAME.png`,
    /// `"cpu"` is `NAME-cpu.png` (see [`page::beside`]).
    const CHARTS: &'static [&'static str];

    /// One line naming the bench and its input, e.g. "bench layouts: bunny.obj".
    fn title(&self) -> String;

    /// The GPU adapter measured (name, driver, backend), or None for the CPU alone.
    fn adapter(&self) -> Option<String>;

    /// What the CLI prints: header lines, markdown tables and notes, one line each.
    fn text(&self) -> String;

    /// Draws the charts, one a path, in the order of [`Self::CHARTS`]; returns those drawn
    /// (a chart of a device not measured is left out).
    #[cfg(feature = "charts")]
    fn draw_charts(&self, paths: &[std::path::PathBuf]) -> Result<Vec<std::path::PathBuf>>;
}

/// Opens the device a bench measures beside the CPU: with `auto`, any GPU adapter that
/// opens, a software one included (the bench times its kernels; a log line says so), else
/// the CPU; `cpu`: none; `gpu`: a GPU or an error.
pub fn open_device(choice: DeviceChoice) -> Result<Device> {
    let device = match choice {
        DeviceChoice::Auto => Device::open_any()?,
        other => Device::open(other)?,
    };
    device.log_choice();
    Ok(device)
}

/// CPU threads the benches run on (rayon's pool).
pub(crate) fn cpu_threads() -> usize {
    rayon::current_num_threads()
}

/// The adapter of `device` as reports name it, or None on the CPU.
pub(crate) fn adapter_of(device: &Device) -> Option<String> {
    device.gpu_context().map(|c| c.adapter.to_string())
}

/// The file name of a path as a report names it (the whole string when it has none).
pub(crate) fn file_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map_or(path.to_string(), |n| n.to_string_lossy().into_owned())
}

/// A unit variant's name as the command line spells it (clap's kebab case): `DfsSign` is
/// "dfs-sign", `Textures` "textures".
pub(crate) fn kebab(v: impl std::fmt::Debug) -> String {
    let mut out = String::new();
    for (i, c) in format!("{v:?}").chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            out.push('-');
        }
        out.extend(c.to_lowercase());
    }
    out
}
