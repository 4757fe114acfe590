use std::path::PathBuf;

use clap::Args;
use lancer::bench::heatmap::{check_png, check_size, run, Count, HeatmapConfig, Rays};
use lancer::render::load_geometry;
use lancer::{Result, TracerOptions, TraversalMode};

use super::out::{print_json, say, Say};
use super::{BuildArgs, DeviceArgs};

#[derive(Args)]
pub struct HeatmapCmd {
    /// Mesh (.obj, .ply, .gltf, .glb) or scene (.toml: its assembled mesh).
    mesh: PathBuf,
    /// Output PNG: the map (top left, one pixel a ray) with a colour bar below it.
    #[arg(short, long)]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    #[command(flatten)]
    device: DeviceArgs,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure (all but the BVH, the kd-tree and the BIH run on the CPU); the map
    /// counts its nodes or cells visited.
    #[arg(long, value_parser = super::accel_arg(), default_value = "bvh")]
    accel: lancer::AccelKind,
    /// GPU traversal: one ray per invocation, or the lanes of a subgroup together (falls
    /// back to per-ray, with a warning, where the adapter or layout has no subgroup mode).
    #[arg(long, value_enum, default_value_t = TraversalMode::PerRay)]
    mode: TraversalMode,
    /// A fixed scale: counts of N and more get the brightest colour, so maps of different
    /// layouts or structures drawn with the same N compare pixel for pixel (default: the
    /// image's own largest count).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    max: Option<u32>,
    /// What a pixel counts: nodes (or cells) visited, or ray–triangle tests.
    #[arg(long, value_enum, default_value_t = Count::Nodes)]
    count: Count,
    /// Which rays: the default view's primary rays (closest hit), or shadow rays (any hit)
    /// from each primary hit to the point light the benches use (in front of the mesh, up
    /// and to the right); pixels whose primary ray missed have no shadow ray and are grey.
    #[arg(long, value_enum, default_value_t = Rays::Primary)]
    rays: Rays,
    /// The map alone, without the colour bar.
    #[arg(long)]
    no_bar: bool,
    /// Print the summary as one JSON object on stdout, the text on stderr; the keys are
    /// described in the book's JSON page, docs/src/reference/json.md.
    #[arg(long)]
    json: bool,
    /// Map the BVH in this file (`build --out`) instead of building one (--accel, --layout
    /// and the builder options are refused with it); MESH must be the one it was built from.
    #[arg(long, value_name = "FILE", conflicts_with_all = super::BVH_CONFLICTS)]
    bvh: Option<PathBuf>,
}

impl HeatmapCmd {
    pub fn run(self) -> Result<()> {
        check_png(&self.out)?;
        let say = Say::new(self.json);
        let mesh = load_geometry(&self.mesh)?;
        lancer::output::check_output(
            &self.out,
            &[&mesh.sources[..], self.bvh.as_slice()].concat(),
        )?;
        check_size(self.width, self.height)?;
        let device = self.device.open_for(self.accel)?;
        let layout = self.build.layout_on(&device);
        let bvh = match &self.bvh {
            Some(path) => Some(super::input::load_bvh(path, &mesh)?.layout),
            None => None,
        };
        let config = HeatmapConfig {
            width: self.width,
            height: self.height,
            structure: self.accel.with_layout(layout),
            layout,
            options: TracerOptions {
                build: self.build.options(),
                layout: Some(layout),
                memory: self.device.bvh_memory,
                stats: true,
                mode: self.mode,
                ..TracerOptions::default()
            },
            bvh,
            max: self.max,
            count: self.count,
            rays: self.rays,
            bar: !self.no_bar,
            out: self.out.clone(),
        };
        let map = run(&device, &mesh, &config)?;
        map.save(&self.out)?;
        for line in map.text() {
            say!(say, "{line}");
        }
        if self.json {
            print_json(&map.report)?;
        }
        Ok(())
    }
}
