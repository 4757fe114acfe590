//! `lancer heatmap` as library code: trace the default view's primary rays (or shadow rays
//! from their hits to the benches' point light) with per-ray statistics, and paint each
//! pixel the [`heat_ramp`] of its count (nodes visited or triangles tested), with the
//! colour bar below it (the `charts` feature). [`run`] returns the image and the
//! [`HeatmapReport`] (`heatmap --json`); [`Heatmap::text`] gives the summary lines the CLI
//! prints.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::camera::Camera;
use crate::device::Device;
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::render::heat_ramp;
use crate::trace::files::{default_light, shadow_rays};
use crate::{
    AccelKind, GpuForm, LayoutKind, Query, Ray, RayStats, Tracer, TracerOptions, TraversalMode,
};

/// The colour of a pixel with no count: its primary ray missed, so it has no shadow ray.
/// A neutral grey, which the heat ramp (black, purple, orange, yellow) never takes.
pub const NO_RAY: [u8; 3] = [128, 128, 128];

/// What a heatmap pixel counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Count {
    /// Nodes (or grid cells) visited.
    #[default]
    Nodes,
    /// Ray–triangle tests.
    Triangles,
}

impl Count {
    /// This count of one ray's statistics.
    pub fn of(self, s: &RayStats) -> u32 {
        match self {
            Count::Nodes => s.nodes,
            Count::Triangles => s.tris,
        }
    }

    /// "nodes" or "triangles".
    pub fn name(self) -> &'static str {
        match self {
            Count::Nodes => "nodes",
            Count::Triangles => "triangles",
        }
    }

    /// What one ray's count is, in words.
    pub fn per_ray(self) -> &'static str {
        match self {
            Count::Nodes => "nodes visited",
            Count::Triangles => "triangles tested",
        }
    }
}

/// Which rays a heatmap traces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Rays {
    /// The default view's primary rays.
    #[default]
    Primary,
    /// Shadow rays from the primary hits to the benches' point light.
    Shadow,
}

impl Rays {
    /// "primary" or "shadow".
    pub fn name(self) -> &'static str {
        match self {
            Rays::Primary => "primary",
            Rays::Shadow => "shadow",
        }
    }
}

/// What to map and how.
#[derive(Clone)]
pub struct HeatmapConfig {
    /// Map width in pixels (one ray a pixel).
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// The structure traced (built from the mesh unless `bvh` is given).
    pub structure: AccelKind,
    /// The BVH's flattened layout (reported; a BVH's own is in `structure`).
    pub layout: LayoutKind,
    /// Builder, GPU memory and traversal mode; statistics are always on.
    pub options: TracerOptions,
    /// A layout read from a BVH file (`build --out`), traced instead of building one.
    pub bvh: Option<Arc<dyn GpuForm>>,
    /// A fixed scale: counts of N and more get the brightest colour (None: the largest).
    pub max: Option<u32>,
    /// What a pixel counts.
    pub count: Count,
    /// Which rays.
    pub rays: Rays,
    /// Add the colour bar below the map (needs the `charts` feature).
    pub bar: bool,
    /// The PNG the image goes to: named in the report, the text and errors.
    pub out: PathBuf,
}

impl HeatmapConfig {
    /// A config for `width`×`height` with the defaults: the BVH in `layout`, nodes visited
    /// per primary ray, the image's own scale, no colour bar.
    pub fn new(width: u32, height: u32, layout: LayoutKind, out: impl Into<PathBuf>) -> Self {
        HeatmapConfig {
            width,
            height,
            structure: AccelKind::Bvh(layout),
            layout,
            options: TracerOptions {
                layout: Some(layout),
                ..TracerOptions::default()
            },
            bvh: None,
            max: None,
            count: Count::Nodes,
            rays: Rays::Primary,
            bar: false,
            out: out.into(),
        }
    }

    /// What a count means, e.g. "nodes visited per primary ray" (the bar's caption).
    pub fn caption(&self) -> String {
        format!("{} per {} ray", self.count.per_ray(), self.rays.name())
    }
}

/// `heatmap --json`: one object a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeatmapReport {
    /// `--accel` structure, e.g. "bvh (dfs-sign)".
    pub structure: String,
    /// `--layout`.
    pub layout: String,
    /// Traversal mode that ran.
    pub mode: String,
    /// "primary" or "shadow".
    pub rays: &'static str,
    /// "nodes" or "triangles".
    pub counted: &'static str,
    /// Map width in pixels (the PNG adds the colour bar).
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// Pixels with a count (all for primary rays; those whose primary ray hit for shadow).
    pub traced: usize,
    /// Mean count over the traced pixels.
    pub mean: f64,
    /// Largest count over the traced pixels.
    pub max: u32,
    /// The count drawn brightest: --max, or the largest count.
    pub scale: u32,
    /// Pixels at or over --max (null without it).
    pub saturated: Option<usize>,
    /// The PNG written.
    pub out: String,
}

/// A heatmap: the counts, the image and the report.
pub struct Heatmap {
    /// One a pixel, row by row: the count, or None where the pixel has no ray.
    pub counts: Vec<Option<u32>>,
    /// The map (with the colour bar below it when asked for).
    pub image: image::RgbImage,
    /// The traversal mode that ran.
    pub mode: TraversalMode,
    /// The traversal mode asked for (`options.mode`).
    pub asked: TraversalMode,
    /// What a count means.
    pub caption: String,
    /// Pixels at or over the scale (reported only with a fixed scale).
    pub saturated: usize,
    /// The summary.
    pub report: HeatmapReport,
}

impl Heatmap {
    /// The summary lines `lancer heatmap` prints.
    pub fn text(&self) -> Vec<String> {
        let r = &self.report;
        let mut lines = Vec::new();
        if self.mode != self.asked {
            lines.push(format!(
                "mode {} ({} asked for, see the warning)",
                self.mode, self.asked
            ));
        }
        let scale = match r.saturated {
            Some(n) => format!(
                "fixed scale 0 to {} (--max): {n} pixels saturated (≥ {})",
                r.scale, r.scale
            ),
            None => format!("scale 0 to {} (the largest count)", r.scale),
        };
        lines.push(format!(
            "{}: mean {:.1}, max {}; {scale} -> {}",
            self.caption, r.mean, r.max, r.out
        ));
        let missed = self.counts.len() - r.traced;
        if r.rays == Rays::Shadow.name() && missed > 0 {
            lines.push(format!(
                "{missed} pixels have no shadow ray (primary ray missed): grey"
            ));
        }
        lines
    }

    /// Writes the image as a PNG to `path`, atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::output::write_atomic(path, |w| {
            (self.image.write_to(w, image::ImageFormat::Png)).map_err(std::io::Error::other)
        })
    }
}

/// Refuses an output that is not a .png file name.
pub fn check_png(path: &Path) -> Result<()> {
    match path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        true => Ok(()),
        false => Err(Error::input(
            path,
            None,
            "a heatmap is a PNG: use a .png file name",
        )),
    }
}

/// Refuses a map too large to hold: rays (primary and shadow), hits, statistics and the
/// image take about 120 bytes a pixel.
pub fn check_size(width: u32, height: u32) -> Result<()> {
    crate::limits::check_image(width, height, 120, "use a smaller --width/--height")
}

/// Maps `mesh` on `device` as `config` says.
pub fn run(device: &Device, mesh: &Mesh, config: &HeatmapConfig) -> Result<Heatmap> {
    let (w, h) = (config.width, config.height);
    check_size(w, h)?;
    let rays = Camera::default_view(&mesh.bounds(), w, h).primary_rays();
    let options = TracerOptions {
        stats: true,
        ..config.options
    };
    let mut tracer = match &config.bvh {
        Some(layout) => Tracer::with_layout(device, layout.clone(), &options)?,
        None => Tracer::with_structure(device, mesh, config.structure, &options)?,
    };
    let light = default_light(&mesh.bounds());
    let (stats, mode) = pixel_stats(&mut tracer, &rays, config.rays, light)?;
    let counts: Vec<Option<u32>> = (stats.iter())
        .map(|s| s.as_ref().map(|s| config.count.of(s)))
        .collect();
    let traced: Vec<u32> = counts.iter().flatten().copied().collect();
    let max = traced.iter().copied().max().unwrap_or(0);
    let scale = config.max.unwrap_or(max).max(1);
    let saturated = traced.iter().filter(|&&c| c >= scale).count();
    let mean = traced.iter().map(|&c| c as f64).sum::<f64>() / traced.len().max(1) as f64;
    let caption = config.caption();
    let map = paint_map(w, h, &counts, scale)?;
    let image = match config.bar {
        false => map,
        true => with_bar(config, &map, &caption, scale)?,
    };
    let report = HeatmapReport {
        structure: config.structure.to_string(),
        layout: config.layout.name().to_string(),
        mode: mode.name().to_string(),
        rays: config.rays.name(),
        counted: config.count.name(),
        width: w,
        height: h,
        traced: traced.len(),
        mean,
        max,
        scale,
        saturated: config.max.map(|_| saturated),
        out: config.out.display().to_string(),
    };
    Ok(Heatmap {
        counts,
        image,
        mode,
        asked: config.options.mode,
        caption,
        saturated,
        report,
    })
}

/// The map with its colour bar, from 0 to `scale`.
#[cfg(feature = "charts")]
fn with_bar(
    config: &HeatmapConfig,
    map: &image::RgbImage,
    caption: &str,
    scale: u32,
) -> Result<image::RgbImage> {
    use super::colour_bar::{with_colour_bar, ColourBar};
    let bar = ColourBar {
        caption: caption.to_string(),
        max: scale,
        saturates: config.max.is_some(),
        no_count: (config.rays == Rays::Shadow)
            .then(|| (NO_RAY, "no shadow ray: the primary ray missed".to_string())),
    };
    with_colour_bar(&config.out, map, &bar)
}

/// Without the `charts` feature there is no colour bar to draw.
#[cfg(not(feature = "charts"))]
fn with_bar(_: &HeatmapConfig, _: &image::RgbImage, _: &str, _: u32) -> Result<image::RgbImage> {
    Err(Error::Usage(
        "the colour bar needs the `charts` feature: build with it, or map without the bar".into(),
    ))
}

/// Per-pixel statistics of `rays` (primary, one a pixel): the primary rays' own, or those
/// of the shadow rays from their hits to `light` (None where the primary ray missed); and
/// the traversal mode that ran.
fn pixel_stats(
    tracer: &mut Tracer,
    primary: &[Ray],
    rays: Rays,
    light: crate::Vec3,
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
pub fn paint_map(w: u32, h: u32, counts: &[Option<u32>], scale: u32) -> Result<image::RgbImage> {
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
