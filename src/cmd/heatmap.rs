use std::path::PathBuf;

use clap::Args;
use lancer::camera::Camera;
use lancer::render::heat_ramp;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{Error, Query, Ray, RayStats, Result, Tracer, TracerOptions, TraversalMode};
use serde::Serialize;

use super::out::{print_json, say, Say};
use super::{AccelArg, BuildArgs, DeviceArgs};
use lancer::bench::colour_bar::{with_colour_bar, ColourBar};
use lancer::render::load_geometry;

/// The colour of a pixel with no count: its primary ray missed, so it has no shadow ray.
/// A neutral grey, which the heat ramp (black, purple, orange, yellow) never takes.
pub const NO_RAY: [u8; 3] = [128, 128, 128];

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
    #[arg(long, value_enum, default_value_t = AccelArg::Bvh)]
    accel: AccelArg,
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

/// What a heatmap pixel counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Count {
    /// Nodes (or grid cells) visited.
    Nodes,
    /// Ray–triangle tests.
    Triangles,
}

impl Count {
    /// This count of one ray's statistics.
    fn of(self, s: &RayStats) -> u32 {
        match self {
            Count::Nodes => s.nodes,
            Count::Triangles => s.tris,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Count::Nodes => "nodes",
            Count::Triangles => "triangles",
        }
    }

    fn per_ray(self) -> &'static str {
        match self {
            Count::Nodes => "nodes visited",
            Count::Triangles => "triangles tested",
        }
    }
}

/// Which rays a heatmap traces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Rays {
    /// The default view's primary rays.
    Primary,
    /// Shadow rays from the primary hits to the benches' point light.
    Shadow,
}

impl Rays {
    fn name(self) -> &'static str {
        match self {
            Rays::Primary => "primary",
            Rays::Shadow => "shadow",
        }
    }
}

/// `heatmap --json`: one object a run.
#[derive(Serialize)]
struct HeatmapReport {
    /// `--accel` structure, e.g. "bvh (dfs-sign)".
    structure: String,
    /// `--layout`.
    layout: String,
    /// Traversal mode that ran.
    mode: String,
    /// "primary" or "shadow".
    rays: &'static str,
    /// "nodes" or "triangles".
    counted: &'static str,
    /// Map size in pixels (the PNG adds the colour bar).
    width: u32,
    height: u32,
    /// Pixels with a count (all for primary rays; those whose primary ray hit for shadow).
    traced: usize,
    /// Mean and largest count over the traced pixels.
    mean: f64,
    max: u32,
    /// The count drawn brightest: --max, or the largest count.
    scale: u32,
    /// Pixels at or over --max (null without it).
    saturated: Option<usize>,
    /// The PNG written.
    out: String,
}

/// The counts of a map and its scale.
struct Summary {
    traced: usize,
    mean: f64,
    max: u32,
    scale: u32,
    saturated: usize,
}

impl Summary {
    fn of(counts: &[Option<u32>], fixed: Option<u32>) -> Summary {
        let traced: Vec<u32> = counts.iter().flatten().copied().collect();
        let max = traced.iter().copied().max().unwrap_or(0);
        let scale = fixed.unwrap_or(max).max(1);
        Summary {
            traced: traced.len(),
            mean: traced.iter().map(|&c| c as f64).sum::<f64>() / traced.len().max(1) as f64,
            max,
            scale,
            saturated: traced.iter().filter(|&&c| c >= scale).count(),
        }
    }
}

impl HeatmapCmd {
    pub fn run(self) -> Result<()> {
        if !self
            .out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            return Err(Error::input(
                &self.out,
                None,
                "a heatmap is a PNG: use a .png file name",
            ));
        }
        let say = Say::new(self.json);
        let mesh = load_geometry(&self.mesh)?;
        lancer::output::check_output(
            &self.out,
            &[&mesh.sources[..], self.bvh.as_slice()].concat(),
        )?;
        let (w, h) = (self.width, self.height);
        // Rays (primary and shadow), hits, statistics and the image: about 120 bytes a pixel.
        lancer::limits::check_image(w, h, 120, "use a smaller --width/--height")?;
        let rays = Camera::default_view(&mesh.bounds(), w, h).primary_rays();
        let device = self.accel.open(&self.device)?;
        let layout = self.build.layout_on(&device);
        let options = TracerOptions {
            build: self.build.options(),
            layout: Some(layout),
            memory: self.device.bvh_memory,
            stats: true,
            mode: self.mode,
            ..TracerOptions::default()
        };
        let kind = self.accel.kind(layout);
        let mut tracer = match &self.bvh {
            Some(path) => {
                let file = super::input::load_bvh(path, &mesh)?;
                Tracer::with_layout(&device, file.layout, &options)?
            }
            None => Tracer::with_structure(&device, &mesh, kind, &options)?,
        };
        let light = default_light(&mesh.bounds());
        let (stats, mode) = pixel_stats(&mut tracer, &rays, self.rays, light)?;
        let counts: Vec<Option<u32>> = (stats.iter())
            .map(|s| s.as_ref().map(|s| self.count.of(s)))
            .collect();
        let summary = Summary::of(&counts, self.max);
        let map = paint_map(w, h, &counts, summary.scale)?;
        let what = format!("{} per {} ray", self.count.per_ray(), self.rays.name());
        let img = match self.no_bar {
            true => map,
            false => with_colour_bar(&self.out, &map, &self.colour_bar(&what, summary.scale))?,
        };
        lancer::output::write_atomic(&self.out, |w| {
            img.write_to(w, image::ImageFormat::Png)
                .map_err(std::io::Error::other)
        })?;
        if mode != self.mode {
            say!(
                say,
                "mode {mode} ({} asked for, see the warning)",
                self.mode
            );
        }
        let scale = match self.max {
            Some(n) => format!(
                "fixed scale 0 to {n} (--max): {} pixels saturated (≥ {n})",
                summary.saturated
            ),
            None => format!("scale 0 to {} (the largest count)", summary.scale),
        };
        say!(
            say,
            "{what}: mean {:.1}, max {}; {scale} -> {}",
            summary.mean,
            summary.max,
            self.out.display()
        );
        let missed = counts.len() - summary.traced;
        if self.rays == Rays::Shadow && missed > 0 {
            say!(
                say,
                "{missed} pixels have no shadow ray (primary ray missed): grey"
            );
        }
        if self.json {
            print_json(&HeatmapReport {
                structure: kind.to_string(),
                layout: layout.name().to_string(),
                mode: mode.name().to_string(),
                rays: self.rays.name(),
                counted: self.count.name(),
                width: w,
                height: h,
                traced: summary.traced,
                mean: summary.mean,
                max: summary.max,
                scale: summary.scale,
                saturated: self.max.map(|_| summary.saturated),
                out: self.out.display().to_string(),
            })?;
        }
        Ok(())
    }

    /// The colour bar of this map, from 0 to `scale`.
    fn colour_bar(&self, what: &str, scale: u32) -> ColourBar {
        ColourBar {
            caption: what.to_string(),
            max: scale,
            saturates: self.max.is_some(),
            no_count: (self.rays == Rays::Shadow)
                .then(|| (NO_RAY, "no shadow ray: the primary ray missed".to_string())),
        }
    }
}

/// Per-pixel statistics of `rays` (primary, one a pixel): the primary rays' own, or those
/// of the shadow rays from their hits to `light` (None where the primary ray missed); and
/// the traversal mode that ran.
fn pixel_stats(
    tracer: &mut Tracer,
    primary: &[Ray],
    rays: Rays,
    light: lancer::Vec3,
) -> Result<(Vec<Option<RayStats>>, TraversalMode)> {
    let result = tracer.trace(primary, Query::Closest)?;
    let stats = stats_of(result.stats, primary.len())?;
    if rays == Rays::Primary {
        return Ok((stats.into_iter().map(Some).collect(), result.mode));
    }
    // shadow_rays keeps the hits' order, one ray a hit.
    let shadow = shadow_rays(primary, &result.hits, light);
    let traced = tracer.trace(&shadow, Query::Any)?;
    let mut shadow_stats = stats_of(traced.stats, shadow.len())?.into_iter();
    let per_pixel = (result.hits.iter())
        .map(|h| h.is_hit().then(|| shadow_stats.next()).flatten())
        .collect();
    Ok((per_pixel, traced.mode))
}

/// The tracer's per-ray statistics, checked to be one a ray.
fn stats_of(stats: Option<Vec<RayStats>>, rays: usize) -> Result<Vec<RayStats>> {
    match stats {
        Some(s) if s.len() == rays => Ok(s),
        _ => Err(Error::Usage(
            "this structure gave no per-ray statistics: no heatmap".into(),
        )),
    }
}

/// The map: pixel i is `heat_ramp(min(count, scale) / scale)` of `counts[i]`, or
/// [`NO_RAY`] where it has no count.
fn paint_map(w: u32, h: u32, counts: &[Option<u32>], scale: u32) -> Result<image::RgbImage> {
    if counts.len() != w as usize * h as usize {
        return Err(Error::Usage(format!(
            "{} counts for a {w}×{h} map",
            counts.len()
        )));
    }
    let mut img = image::RgbImage::new(w, h);
    for (p, c) in img.pixels_mut().zip(counts) {
        *p = image::Rgb(match c {
            Some(c) => heat_ramp((*c).min(scale) as f32 / scale.max(1) as f32),
            None => NO_RAY,
        });
    }
    Ok(img)
}
