//! Subcommands of the `lancer` binary: parse, call the library, print.

mod adapters;
mod bench;
mod bench_accuracy;
mod bench_builders;
mod bench_instances;
mod bench_layouts;
mod bench_refit;
mod bench_render;
mod bench_scale;
mod bench_structures;
mod build;
mod check;
mod compare;
mod heatmap;
mod input;
pub mod interrupt;
mod merge;
mod out;
mod rays;
mod render;
mod trace;

use clap::{Args, Parser, Subcommand};
use lancer::accel::bvh::{BuildOptions, Builder, EXACT_BELOW, MAX_BINS};
use lancer::geometry::{Precision, RayOffset, SlabTest, TriangleTest};
use lancer::gpu::BvhMemory;
use lancer::{AccelKind, Device, DeviceChoice, LayoutKind, Result, Robustness};

#[derive(Parser)]
#[command(
    name = "lancer",
    version,
    about = "GPU compute ray tracer with a CPU reference"
)]
pub struct Cli {
    /// Print errors only: no warnings, summaries or progress bars (data — JSON, rays, hits —
    /// still goes out).
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// Print more about what happens (-v: info, -vv: debug).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Threads for the CPU tracers, renderer and builders (0: one per core).
    #[arg(long, global = true, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=4096))]
    pub threads: u16,
    #[command(subcommand)]
    cmd: Cmd,
}

impl Cli {
    /// Whether the command measures (a bench): it repeats builds that reuse freed memory.
    pub fn is_bench(&self) -> bool {
        matches!(self.cmd, Cmd::Bench(_))
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a TOML scene, or a mesh (.obj, .ply, .gltf, .glb) on a ground plane under a sun,
    /// to PNG or EXR.
    Render(render::RenderCmd),
    /// Build a BVH and print its statistics.
    Build(build::BuildCmd),
    /// Trace a ray file, write a hit file.
    Trace(trace::TraceCmd),
    /// Write the primary rays of a scene's camera or of a mesh's default view.
    Rays(rays::RaysCmd),
    /// Render nodes visited (or triangles tested) per pixel of the default view, primary or
    /// shadow rays, as a PNG with a colour bar.
    Heatmap(heatmap::HeatmapCmd),
    /// Measure speed.
    Bench(bench::BenchCmd),
    /// Trace the same rays on each layout's CPU twin and GPU kernel and compare the answers
    /// (exit code 1 on any disagreement); --device auto takes any adapter, lavapipe included.
    Check(check::CheckCmd),
    /// Compare two images (difference statistics and picture) or two hit files (judged by
    /// the f64 oracle with --mesh and --rays); exit code 1 when they differ.
    Compare(compare::CompareCmd),
    /// List every GPU adapter: type, backend, driver, limits and features.
    Adapters(adapters::AdaptersCmd),
    /// Join EXR tiles (`render --crop`) into the full image.
    Merge(merge::MergeCmd),
}

/// BVH builder options shared by the subcommands that build one.
#[derive(Args, Clone, Debug)]
pub struct BuilderArgs {
    /// BVH builder: sweep (the SAH over every split position on all three axes), binned (the
    /// SAH over --bins candidate splits per axis: a faster build), median (the object median
    /// of the longest axis: the fastest build, slower traversal), sbvh (the sweep plus spatial
    /// splits that cut long triangles: a slower build, a faster trace where triangles are
    /// long and thin), ploc (clustering along a Morton curve, on all threads) or lbvh (a
    /// radix tree over a Morton curve: the fastest, a poorer tree; `build --build-on gpu`
    /// builds the same tree on the GPU).
    #[arg(long, value_enum, default_value_t = Builder::Sweep, hide_possible_values = true)]
    builder: Builder,
    /// Bins per axis (binned builder), 2 to 64.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(2..=MAX_BINS as i64))]
    bins: u32,
    /// Largest leaf; bigger nodes are always split.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    max_leaf: u32,
    /// SAH cost of one box test (finite, > 0).
    #[arg(long, default_value_t = 1.0, value_parser = positive_finite)]
    t_cube: f32,
    /// SAH cost of one triangle test (finite, > 0).
    #[arg(long, default_value_t = 1.0, value_parser = positive_finite)]
    t_obj: f32,
    /// Sweep builder: nodes of more triangles than this split by 64 bins per axis, smaller
    /// ones by the exact sweep; 0 sweeps every node (the seed's build, about half as fast).
    #[arg(long, default_value_t = EXACT_BELOW as u64, value_name = "N")]
    exact_below: u64,
    /// After the builder, optimise the tree by reinsertion: the largest subtrees moved to
    /// where they cost least (Bittner et al. 2013); the SAH never rises.
    #[arg(long)]
    optimize: bool,
}

impl BuilderArgs {
    pub fn options(&self) -> BuildOptions {
        BuildOptions {
            builder: self.builder,
            t_cube: self.t_cube,
            t_obj: self.t_obj,
            max_leaf: self.max_leaf as usize,
            bins: self.bins as usize,
            exact_below: match self.exact_below {
                0 => usize::MAX,
                n => usize::try_from(n).unwrap_or(usize::MAX),
            },
            optimize: self.optimize,
            ..BuildOptions::default()
        }
    }
}

/// The builder options `--bvh FILE` is refused with (by their argument ids): the file holds
/// the structure, built already.
pub const BUILDER_IDS: [&str; 7] = [
    "builder",
    "bins",
    "max_leaf",
    "t_cube",
    "t_obj",
    "exact_below",
    "optimize",
];

/// The options `--bvh FILE` is refused with where a command has `--accel` and `--layout`:
/// the file holds the structure, its layout and how it was built.
pub const BVH_CONFLICTS: [&str; 9] = [
    "accel",
    "layout",
    BUILDER_IDS[0],
    BUILDER_IDS[1],
    BUILDER_IDS[2],
    BUILDER_IDS[3],
    BUILDER_IDS[4],
    BUILDER_IDS[5],
    BUILDER_IDS[6],
];

/// BVH builder options and the flattened layout.
#[derive(Args, Clone, Debug)]
pub struct BuildArgs {
    #[command(flatten)]
    builder: BuilderArgs,
    /// Flattened BVH layout (GPU arrays and their CPU twin); default: the device's fastest
    /// measured (bvh8 on the CPU, cwbvh on lavapipe, dfs-sign on a hardware GPU; see the
    /// book's "Defaults" page).
    #[arg(long, value_enum)]
    layout: Option<LayoutKind>,
}

impl BuildArgs {
    pub fn options(&self) -> BuildOptions {
        self.builder.options()
    }

    /// `--layout`, if given.
    pub fn layout(&self) -> Option<LayoutKind> {
        self.layout
    }

    /// `--layout`, else `device`'s default.
    pub fn layout_on(&self, device: &Device) -> LayoutKind {
        (self.layout).unwrap_or_else(|| lancer::trace::default_layout(device))
    }
}

/// `--accel NAME`: a structure of the registry ([`AccelKind::ALL`]), the BVH's layout
/// left to `--layout` ([`AccelKind::with_layout`]).
fn accel_arg() -> impl clap::builder::TypedValueParser<Value = AccelKind> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    let values = (AccelKind::ALL.iter()).map(|k| PossibleValue::new(k.name()).help(k.describe()));
    PossibleValuesParser::new(values).map(|s| AccelKind::from_name(&s).expect("a listed name"))
}

/// Where to run, and how the GPU reads the BVH.
#[derive(Args, Clone, Debug)]
pub struct DeviceArgs {
    /// Where to run. auto: a hardware GPU when one opens, else the CPU tracer, saying why
    /// (a software adapter such as lavapipe is slower than the CPU; --device gpu uses it).
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// GPU: where the kernels read the BVH and the shading triangles from (storage textures,
    /// or storage buffers: an array bigger than one binding is bound in parts).
    #[arg(long, value_enum, default_value_t = BvhMemory::default())]
    bvh_memory: BvhMemory,
}

impl DeviceArgs {
    /// Where the kernels read the BVH from.
    pub fn bvh_memory(&self) -> BvhMemory {
        self.bvh_memory
    }

    /// Opens the device for structure `accel`: only some have GPU kernels, so `auto` runs
    /// the others on the CPU (`gpu` is left to the library, which refuses it by name).
    pub fn open_for(&self, accel: AccelKind) -> Result<Device> {
        match !accel.has_gpu_form() && self.device == DeviceChoice::Auto {
            true => Ok(Device::cpu()),
            false => self.open(),
        }
    }

    /// Opens the device, saying why `auto` chose the CPU.
    pub fn open(&self) -> Result<Device> {
        let device = Device::open(self.device)?;
        device.log_choice();
        Ok(device)
    }

    /// Opens the device for a command that needs a GPU: `auto` takes any adapter, a
    /// software one included.
    pub fn open_any_gpu(&self) -> Result<Device> {
        lancer::bench::open_device(self.device)
    }
}

/// The robustness knobs on the command line.
#[derive(Args, Clone, Debug)]
pub struct RobustnessArgs {
    /// Ray–triangle test.
    #[arg(long, value_enum, default_value_t = TriangleTest::Watertight)]
    triangle_test: TriangleTest,
    /// Slab (ray–box) test.
    #[arg(long, value_enum, default_value_t = SlabTest::Robust)]
    slab_test: SlabTest,
    /// How secondary rays leave a surface: by the hit point's error bound (and near hits
    /// within a t error bound rejected), a fixed epsilon of 1e-4 of the scene's diagonal, or none.
    #[arg(long, value_enum, default_value_t = RayOffset::ErrorBound)]
    ray_offset: RayOffset,
    /// GPU: run the shader module without bounds checks / loop bounding (BVH validated first).
    #[arg(long)]
    trusted: bool,
    /// CPU: triangle tests in f32 (the GPU's arithmetic) or f64 (the oracle's, to price the
    /// f32 error); a GPU device refuses f64.
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    precision: Precision,
}

impl RobustnessArgs {
    pub fn robustness(&self) -> Robustness {
        Robustness {
            triangle_test: self.triangle_test,
            slab_test: self.slab_test,
            ray_offset: self.ray_offset,
            checked_module: !self.trusted,
            precision: self.precision,
        }
    }
}

/// Where the camera looks from and at, and its field of view.
#[derive(Args)]
pub struct ViewArgs {
    /// Put the eye at X,Y,Z (scene units), instead of the scene's or the default view's.
    #[arg(long, value_name = "X,Y,Z", value_parser = point, allow_hyphen_values = true)]
    look_from: Option<glam::Vec3>,
    /// Look at X,Y,Z (scene units).
    #[arg(long, value_name = "X,Y,Z", value_parser = point, allow_hyphen_values = true)]
    look_at: Option<glam::Vec3>,
    /// Vertical field of view in degrees; a mesh's default view moves to keep it framed.
    #[arg(long, value_name = "DEGREES", value_parser = positive_finite)]
    fov: Option<f32>,
    /// A glTF file's camera, by index (in node order) or name; by default its first, where
    /// it places one, else the default view.
    #[arg(long, value_name = "NAME|INDEX")]
    camera: Option<String>,
}

impl ViewArgs {
    pub fn change(&self) -> lancer::camera::ViewChange {
        lancer::camera::ViewChange {
            look_from: self.look_from,
            look_at: self.look_at,
            fov: self.fov,
            camera: self.camera.clone(),
        }
    }
}

/// Three finite numbers x,y,z.
pub(super) fn point(s: &str) -> std::result::Result<glam::Vec3, String> {
    let v: Vec<f32> = (s.split(','))
        .map(|x| x.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("{s}: {e}; give a point as x,y,z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::Vec3::new(x, y, z)),
        _ => Err(format!("{s}: give a point as three finite numbers x,y,z")),
    }
}

/// A finite number above zero.
fn positive_finite(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite number above 0")),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number at or above zero.
pub(super) fn non_negative_finite(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite number at or above 0")),
        Err(e) => Err(e.to_string()),
    }
}

pub use out::set_quiet;

pub fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Render(c) => c.run(),
        Cmd::Build(c) => c.run(),
        Cmd::Trace(c) => c.run(),
        Cmd::Rays(c) => c.run(),
        Cmd::Heatmap(c) => c.run(),
        Cmd::Bench(c) => c.run(),
        Cmd::Check(c) => c.run(),
        Cmd::Compare(c) => c.run(),
        Cmd::Adapters(c) => c.run(),
        Cmd::Merge(c) => c.run(),
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// The book's command-line reference, generated from the clap definitions above, so
    /// that it cannot drift from the code: this fails when the checked-in page differs from
    /// what the code generates. `LANCER_BLESS=1 cargo test --release --bin lancer
    /// cli_reference` writes the page anew.
    #[test]
    fn cli_reference() {
        let options = clap_markdown::MarkdownOptions::new()
            .title("Command-line reference".into())
            .show_footer(false);
        let generated = format!(
            "<!-- generated by: LANCER_BLESS=1 cargo test --release --bin lancer cli_reference \
             (from src/cmd; do not edit) -->\n\n{}",
            clap_markdown::help_markdown_custom::<super::Cli>(&options)
        );
        let page = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/src/reference/cli.md");
        if std::env::var_os("LANCER_BLESS").is_some() {
            std::fs::write(&page, &generated).unwrap();
        }
        let checked_in = std::fs::read_to_string(&page).unwrap_or_default();
        assert!(
            checked_in == generated,
            "{} differs from what the command-line definitions generate: run \
             LANCER_BLESS=1 cargo test --release --bin lancer cli_reference and commit it",
            page.display()
        );
    }
}
