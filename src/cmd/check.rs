//! `lancer check`: the CPU-vs-GPU equivalence test as a command. Traces the same rays on
//! each layout's CPU twin and GPU kernel (in each traversal mode) and prints, per layout, mode
//! and query, how many answers are identical, agree, are genuine ties (named by the f64
//! oracle) or disagree.

use std::path::PathBuf;
use std::sync::Arc;

use clap::Args;
use lancer::accel::bvh::build;
use lancer::layout::{flatten, Layout, LayoutKind};
use lancer::mesh::load_mesh;
use lancer::trace::compare::compare_hits;
use lancer::trace::files::read_rays;
use lancer::{Device, Error, Query, Ray, Result, Tracer, TracerOptions, TraversalMode};

use super::{view_ray_sets, BuilderArgs, DeviceArgs, RobustnessArgs};

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
    /// OBJ mesh.
    mesh: PathBuf,
    /// Ray file (32 bytes a ray); by default the primary rays of the default view
    /// (--width × --height) and the shadow and diffuse bounce rays from their hits.
    #[arg(long)]
    rays: Option<PathBuf>,
    /// Layout to check: a name or all.
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
}

impl CheckCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let device = self.device.open()?;
        let Some(ctx) = device.gpu_context() else {
            return Err(Error::Gpu(
                "check compares the GPU with the CPU and no GPU adapter opened: install a Vulkan \
                 driver (lavapipe: mesa-vulkan-drivers) or run on a machine with a GPU"
                    .into(),
            ));
        };
        let tree = build(&mesh, &self.build.options());
        let sets: Vec<(String, Query, Vec<Ray>)> = match &self.rays {
            Some(path) => {
                let rays = read_rays(path)?;
                let name = path.display().to_string();
                vec![
                    (name.clone(), Query::Closest, rays.clone()),
                    (name, Query::Any, rays),
                ]
            }
            None => {
                let reference = flatten(LayoutKind::default(), &tree, &mesh);
                let rob = self.robustness.robustness();
                view_ray_sets(&mesh, reference.as_ref(), self.width, self.height, &rob)?
            }
        };
        println!("adapter {}", ctx.adapter);
        println!(
            "| layout | mode | rays | query | count | identical | agree | genuine ties | disagree |"
        );
        println!("|---|---|---|---|---|---|---|---|---|");
        let cpu = Device::cpu();
        let mut bad = 0usize;
        let mut not_run = Vec::new();
        for kind in self.layouts.kinds() {
            let layout: Arc<dyn Layout> = flatten(kind, &tree, &mesh).into();
            let options = TracerOptions {
                layout: kind,
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
                    println!("| {kind} | {mode} | – | – | – | – | – | – | not run |");
                    if let ModeChoice::One(_) = self.modes {
                        not_run.push(format!("{kind} {mode}"));
                    }
                    continue;
                }
                for ((name, query, rays), c) in sets.iter().zip(&twin_hits) {
                    let g = gpu.trace(rays, *query)?.hits;
                    let cmp = compare_hits(&mesh, rays, *query, c, &g);
                    println!(
                        "| {kind} | {mode} | {name} | {query:?} | {} | {} | {} | {} | {} |",
                        rays.len(),
                        cmp.identical,
                        cmp.agree,
                        cmp.ties,
                        cmp.disagree.len()
                    );
                    for d in cmp.disagree.iter().take(3) {
                        eprintln!(
                            "  {kind} {mode} {name} ray {}: CPU {:?}, GPU {:?}: {}",
                            d.ray, d.reference, d.other, d.why
                        );
                    }
                    bad += cmp.disagree.len();
                }
            }
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
        println!("every answer agrees or is a genuine tie");
        Ok(())
    }
}
