//! `lancer bench …`: each subcommand parses its options into a `lancer::bench` Config, runs
//! the bench with a progress bar, and prints its report (tables, `--json`, `--chart`,
//! `--report`).

use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lancer::bench::{page, BenchReport, Progress};
use lancer::mesh::load_mesh;
use lancer::{DeviceChoice, Result};
use serde::Serialize;

use super::out::{check_output, json_to, say, JsonTo, Say};
use super::BuildArgs;

#[derive(Args)]
pub struct BenchCmd {
    #[command(subcommand)]
    what: BenchWhat,
}

#[derive(Subcommand)]
enum BenchWhat {
    /// Trace primary (closest-hit) and shadow (any-hit) rays of the default view.
    Trace(BenchTrace),
    /// Milliseconds per spp on GPU and CPU, specialised vs all-effects kernel.
    Render(super::bench_render::BenchRender),
    /// Every acceleration structure on one mesh or scene: build, memory, work and speed (on
    /// the CPU, and on the GPU for those with a GPU kernel).
    Structures(super::bench_structures::BenchStructures),
    /// Every flattened layout on one mesh: bytes, work and bytes loaded per ray, CPU twin
    /// and GPU speed for primary, shadow and bounce rays.
    Layouts(super::bench_layouts::BenchLayouts),
    /// What each robustness knob costs in time and the error it leaves, CPU and GPU.
    Accuracy(super::bench_accuracy::BenchAccuracy),
    /// Every BVH builder on one or more meshes: build time, peak memory, SAH and EPO, work
    /// and speed per ray, and which a-priori cost predicts the speed.
    Builders(super::bench_builders::BenchBuilders),
    /// A mesh placed many times, in two levels against its flattened copy: build, bytes,
    /// work and speed per ray (CPU and GPU), and the top level's build at 10² to 10⁵
    /// instances.
    Instances(super::bench_instances::BenchInstances),
    /// A deforming mesh: its BVH refit against rebuilt at every step (time), and how the
    /// refit tree's SAH and speed per ray decay.
    Refit(super::bench_refit::BenchRefit),
    /// From a mesh file to its first traced rays, step by step (read, build, flatten, to the
    /// device, first trace) on one or more meshes, and the peak memory on the way.
    Scale(super::bench_scale::BenchScale),
}

impl BenchCmd {
    pub fn run(self) -> Result<()> {
        match self.what {
            BenchWhat::Trace(b) => b.run(),
            BenchWhat::Render(b) => b.run(),
            BenchWhat::Structures(b) => b.run(),
            BenchWhat::Layouts(b) => b.run(),
            BenchWhat::Accuracy(b) => b.run(),
            BenchWhat::Builders(b) => b.run(),
            BenchWhat::Instances(b) => b.run(),
            BenchWhat::Refit(b) => b.run(),
            BenchWhat::Scale(b) => b.run(),
        }
    }
}

#[derive(Args)]
struct BenchTrace {
    /// Mesh (.obj, .ply, .gltf, .glb).
    mesh: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// auto, gpu or cpu. auto and gpu measure the GPU kernels and the CPU tracer side by side, on any adapter
    /// (a software one such as lavapipe included); without one, auto measures the CPU alone
    /// and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    device: DeviceChoice,
    /// Timed runs per configuration (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure: one with a GPU kernel (the BVH in --layout, the kd-tree, the BIH).
    #[arg(long, value_parser = super::accel_arg(), default_value = "bvh")]
    accel: lancer::AccelKind,
    #[command(flatten)]
    out: Outputs,
}

impl BenchTrace {
    fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        (self.out).check::<lancer::bench::trace::Report>(&mesh.sources, &[])?;
        let config = lancer::bench::trace::Config {
            mesh,
            name: self.mesh.display().to_string(),
            width: self.width,
            height: self.height,
            device: self.device,
            repeat: self.repeat as usize,
            // A GPU kernel's bench: the GPU's default layout unless one is named.
            accel: (self.accel).with_layout(
                self.build
                    .layout
                    .unwrap_or(lancer::trace::defaults::GPU_LAYOUT),
            ),
            build: self.build.options(),
        };
        let report = with_bar("runs", |p| lancer::bench::trace::run(&config, p))?;
        self.out.finish(&report, &[])
    }
}

/// `--device` and `--bvh-memory`, shared by the benches that time the CPU twins and the GPU
/// kernels side by side.
#[derive(Args)]
pub struct BenchDevice {
    /// auto, gpu or cpu. auto and gpu measure the GPU kernels and the CPU side by side, on any
    /// adapter (a software one such as lavapipe included); without one, auto measures the CPU
    /// alone and gpu is an error; cpu measures the CPU alone.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto, hide_possible_values = true)]
    pub device: DeviceChoice,
    /// GPU: where the kernels read the BVH (or other structure) from.
    #[arg(long, value_enum, default_value_t = lancer::gpu::BvhMemory::default())]
    pub bvh_memory: lancer::gpu::BvhMemory,
}

/// Runs a bench with a progress bar on stderr (`unit`: what its steps are), cleared when
/// the bench ends.
pub fn with_bar<R>(unit: &str, run: impl FnOnce(&dyn Fn(Progress)) -> Result<R>) -> Result<R> {
    let bar = Bar(super::out::progress_bar(0));
    let template = match unit {
        "" => "{bar:40} {pos}/{len} {msg}".to_string(),
        u => format!("{{bar:40}} {{pos}}/{{len}} {u} {{msg}}"),
    };
    bar.0.set_style(
        ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    run(&|p: Progress| {
        bar.0.set_length(p.total);
        bar.0.set_position(p.done);
        bar.0.set_message(p.message);
    })
}

/// A progress bar, cleared when dropped.
struct Bar(ProgressBar);

impl Drop for Bar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// `--json [FILE.json]` and `--report FILE.md`, shared by the benches.
#[derive(Args)]
pub struct Outputs {
    /// Also write the results as one JSON object: on stdout with --json alone or --json -
    /// (the tables then go to stderr), or in FILE.json (keys: the book's JSON page, docs/src/reference/json.md).
    #[arg(long, value_name = "FILE.json", num_args = 0..=1, default_missing_value = "-", value_parser = json_to)]
    pub json: Option<JsonTo>,
    #[command(flatten)]
    pub report: ReportArg,
}

impl Outputs {
    /// Where the tables go.
    pub fn say(&self) -> Say {
        Say::new(self.json.as_ref().is_some_and(JsonTo::is_stdout))
    }

    /// Checks every output path before work starts: the JSON file, the report and its
    /// charts, and `charts` (the --chart files).
    pub fn check<R: BenchReport>(&self, inputs: &[PathBuf], charts: &[&Path]) -> Result<()> {
        // One file for two outputs would keep only the last written.
        let json = match &self.json {
            Some(JsonTo::File(p)) => Some(p.as_path()),
            _ => None,
        };
        let pages = self
            .report
            .report
            .iter()
            .flat_map(|p| page::outputs::<R>(p));
        let mut all: Vec<PathBuf> = json
            .into_iter()
            .chain(charts.iter().copied())
            .map(Path::to_path_buf)
            .collect();
        all.extend(pages);
        for (i, a) in all.iter().enumerate() {
            if all[..i].iter().any(|b| lancer::output::same_output(a, b)) {
                return Err(lancer::Error::Usage(format!(
                    "{} is named for two outputs (--json, --chart, --report and its charts): \
                     give each its own file",
                    a.display()
                )));
            }
        }
        self.json.as_ref().map_or(Ok(()), |j| j.check(inputs))?;
        for c in charts {
            check_output(c, inputs)?;
        }
        self.report.check::<R>(inputs)
    }

    /// Prints the report's text, draws `charts` (the --chart files; naming those drawn),
    /// writes the JSON and the results page.
    pub fn finish<R: BenchReport>(&self, report: &R, charts: &[&Path]) -> Result<()> {
        let say = self.say();
        print_text(say, &report.text());
        if !charts.is_empty() {
            let paths: Vec<PathBuf> = charts.iter().map(|c| c.to_path_buf()).collect();
            let drawn = report.draw_charts(&paths)?;
            let names: Vec<String> = drawn.iter().map(|c| c.display().to_string()).collect();
            let s = if drawn.len() == 1 { "" } else { "s" };
            say!(say, "\nchart{s} -> {}", names.join(", "));
        }
        write_json(self.json.as_ref(), report, say)?;
        self.report.write(report, say)
    }
}

/// Prints a report's text, line by line.
pub fn print_text(say: Say, text: &str) {
    for line in text.lines() {
        say!(say, "{line}");
    }
}

/// Writes the report where --json asks (nowhere without it).
pub fn write_json(json: Option<&JsonTo>, report: &impl Serialize, say: Say) -> Result<()> {
    json.map_or(Ok(()), |j| j.write(report, say))
}

/// `--report FILE.md`.
#[derive(Args)]
pub struct ReportArg {
    /// Also write a dated results page: the machine, adapter and driver, lancer's commit, the
    /// date, this command, the tables, and the charts beside it (FILE.png or FILE-*.png); see
    /// the book's results index, docs/src/results/index.md.
    #[arg(long, value_name = "FILE.md", value_parser = md_file)]
    pub report: Option<PathBuf>,
}

impl ReportArg {
    /// Checks the page and its charts before work starts.
    pub fn check<R: BenchReport>(&self, inputs: &[PathBuf]) -> Result<()> {
        for path in self.report.iter().flat_map(|p| page::outputs::<R>(p)) {
            lancer::output::check_output(&path, inputs)?;
        }
        Ok(())
    }

    /// Writes the page and its charts; says where.
    pub fn write<R: BenchReport>(&self, report: &R, say: Say) -> Result<()> {
        if let Some(path) = &self.report {
            let command = page::shell_command(std::env::args().skip(1));
            page::write(path, report, &command)?;
            say!(say, "report -> {}", path.display());
        }
        Ok(())
    }
}

/// `--report FILE.md`: a markdown file name.
fn md_file(s: &str) -> std::result::Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match path.extension() {
        Some(e) if e.eq_ignore_ascii_case("md") => Ok(path),
        _ => Err(format!("{s} is not a .md file name: give FILE.md")),
    }
}

/// `--chart FILE.png`: a PNG file name (a chart is never written over a .json or .md).
pub fn png_file(s: &str) -> std::result::Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match path.extension() {
        Some(e) if e.eq_ignore_ascii_case("png") => Ok(path),
        _ => Err(format!("{s} is not a .png file name: give FILE.png")),
    }
}
