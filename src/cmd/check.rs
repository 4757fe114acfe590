//! `lancer check`: the CPU-vs-GPU equivalence test as a command (`lancer::trace::check`
//! runs it): per layout, mode and query, how many answers are identical, agree, are genuine
//! ties (named by the f64 oracle) or disagree.

use std::path::PathBuf;

use clap::Args;
use lancer::mesh::load_mesh;
use lancer::trace::check::{self, CheckConfig, CheckProgress, CheckRays, TABLE_HEADER};
use lancer::{DeviceChoice, Error, Result};

use super::input::load_bvh;
use super::out::{is_std, print_json, read_rays, say, Say};
use super::{BuilderArgs, DeviceArgs, RobustnessArgs, BUILDER_IDS};

pub use lancer::trace::check::{layout_choice, mode_choice, LayoutChoice, ModeChoice};

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
    /// refused with it), its answers are also judged by the f64 oracle (`oracle` rows), and
    /// MESH must be the mesh it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = BUILDER_IDS, conflicts_with = "layouts")]
    bvh: Option<PathBuf>,
    /// Print the results as one JSON object on stdout, the table on stderr (keys: the
    /// book's JSON page, docs/src/reference/json.md).
    #[arg(long)]
    json: bool,
}

impl CheckCmd {
    pub fn run(self) -> Result<()> {
        // Refused before anything is read: a check compares a GPU with the CPU.
        if self.device.device == DeviceChoice::Cpu {
            return Err(Error::Usage(
                "check compares GPU kernels with their CPU twins, and --device cpu leaves no \
                 GPU to check: use --device gpu or auto (lavapipe counts)"
                    .into(),
            ));
        }
        let say = Say::new(self.json);
        let mesh = load_mesh(&self.mesh)?;
        // A check needs a GPU: auto takes any adapter here, a software one included.
        let device = self.device.open_any_gpu()?;
        check::require_gpu(&device)?;
        let bvh = (self.bvh.as_ref())
            .map(|p| load_bvh(p, &mesh))
            .transpose()?;
        let rays = match &self.rays {
            Some(path) => CheckRays::Given {
                name: match is_std(path) {
                    true => "<stdin>".into(),
                    false => path.display().to_string(),
                },
                rays: read_rays(path)?,
            },
            None => CheckRays::View {
                width: self.width,
                height: self.height,
            },
        };
        let config = CheckConfig {
            rays,
            layouts: self.layouts.kinds(),
            mode: self.modes.mode(),
            build: self.build.options(),
            bvh,
            memory: self.device.bvh_memory(),
            robustness: self.robustness.robustness(),
        };
        let report = check::run(&device, &mesh, &config, |p| match p {
            CheckProgress::Started { adapter } => {
                say!(say, "adapter {adapter}");
                TABLE_HEADER.iter().for_each(|l| say!(say, "{l}"));
            }
            CheckProgress::Row(row) => {
                say!(say, "{}", row.markdown());
                row.disagreement_lines()
                    .iter()
                    .for_each(|l| eprintln!("{l}"));
            }
        })?;
        if !report.driver {
            say!(
                say,
                "(no driver rows: {} offers no ray queries; lavapipe from Mesa 25 does)",
                report.adapter_name
            );
        }
        if self.json {
            print_json(&report)?;
        }
        if report.disagree > 0 {
            return Err(Error::Differ(format!(
                "{} answers disagree (the GPU with the CPU twin, or a BVH file's with the f64 \
                 oracle; listed above)",
                report.disagree
            )));
        }
        if !report.not_run.is_empty() {
            return Err(Error::Gpu(format!(
                "{} could not run on {} (the warning above says why)",
                report.not_run.join(", "),
                report.adapter_name
            )));
        }
        say!(say, "every answer agrees or is a genuine tie");
        Ok(())
    }
}
