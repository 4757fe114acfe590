//! PNG charts for the benches: grouped bars, and x–y plots (lines or points, linear or log
//! axes), each with its legend beside the plot (never over the data). Drawn in memory by
//! plotters with an embedded font — a fresh machine may have no fonts and no fontconfig —
//! encoded by `image` and written atomically by `lancer::output`.

use std::path::Path;
use std::sync::OnceLock;

use crate::error::{Error, Result};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// DejaVu Sans (Bitstream Vera licence: assets/fonts/LICENSE-DejaVu.txt).
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
/// The family plotters asks for by default; the embedded font is registered under it.
pub const FAMILY: &str = "sans-serif";
/// Plot area size in pixels (the legend panel is added to the width).
const PLOT: (u32, u32) = (900, 600);
/// Width given to each category of a bar chart, so its name fits under its bars.
const CATEGORY_WIDTH: u32 = 110;
/// Height of one legend line.
const LEGEND_LINE: u32 = 22;
/// Charts wider or taller are refused (a bench with thousands of categories or series).
const MAX_SIDE: u32 = 8192;

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type Drawn = std::result::Result<(), Box<dyn std::error::Error>>;

/// A grouped bar chart: one group of bars per category, one bar (and colour) per series,
/// `series[s].1[c]` the height of series `s` in category `c` (NaN: no bar). The y axis
/// starts at 0 (or below, for negative values); `y_label` should name the units.
pub fn bar_chart(
    path: &Path,
    title: &str,
    y_label: &str,
    categories: &[String],
    series: &[(String, Vec<f64>)],
) -> Result<()> {
    let none = vec![vec![[f64::NAN; 2]; categories.len()]; series.len()];
    bar_chart_with_ranges(path, title, y_label, categories, series, &none)
}

/// [`bar_chart`] with a whisker on each bar from `ranges[s][c][0]` to `ranges[s][c][1]`
/// (the spread of the runs a bar is the median of; NaN: no whisker). The title should say
/// what the whiskers are.
pub fn bar_chart_with_ranges(
    path: &Path,
    title: &str,
    y_label: &str,
    categories: &[String],
    series: &[(String, Vec<f64>)],
    ranges: &[Vec<[f64; 2]>],
) -> Result<()> {
    if ranges.len() != series.len() {
        return Err(chart_error(
            path,
            format!("{} ranges for {} series", ranges.len(), series.len()),
        ));
    }
    if let Some((name, v)) = series.iter().find(|(_, v)| v.len() != categories.len()) {
        return Err(chart_error(
            path,
            format!(
                "series {name} has {} values for {} categories",
                v.len(),
                categories.len()
            ),
        ));
    }
    if let Some(r) = ranges.iter().find(|r| r.len() != categories.len()) {
        return Err(chart_error(
            path,
            format!("{} ranges for {} categories", r.len(), categories.len()),
        ));
    }
    let ends = ranges.iter().flatten().flatten();
    let heights = (series.iter().flat_map(|(_, v)| v).chain(ends)).filter(|y| y.is_finite());
    let (lo, hi) = heights.fold((0.0f64, 0.0f64), |(lo, hi), &y| (lo.min(y), hi.max(y)));
    let pad = if hi > lo { 0.08 * (hi - lo) } else { 1.0 };
    let (lo, hi) = (if lo < 0.0 { lo - pad } else { 0.0 }, hi + pad);
    let n = categories.len();
    let plot_w = PLOT.0.max(80 + CATEGORY_WIDTH * n as u32);
    let names: Vec<&str> = series.iter().map(|(s, _)| s.as_str()).collect();
    draw_png(path, plot_w, &names, |root, plot| {
        let mut chart = ChartBuilder::on(plot)
            .caption(title, (FAMILY, 22))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..n.max(1) as f64, lo..hi)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .max_light_lines(1)
            .x_labels(0)
            .y_desc(y_label)
            .y_label_formatter(&|v| tick(*v))
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        // Each category is one unit wide: its bars fill the middle 80 %.
        let w = 0.8 / series.len().max(1) as f64;
        for (s, (_, values)) in series.iter().enumerate() {
            let style = colour(s).filled();
            chart.draw_series(
                values
                    .iter()
                    .enumerate()
                    .filter(|(_, y)| y.is_finite())
                    .map(|(c, &y)| {
                        let x0 = c as f64 + 0.1 + s as f64 * w;
                        Rectangle::new([(x0, 0.0), (x0 + w, y)], style)
                    }),
            )?;
        }
        // Whiskers: a vertical line through the bar's middle, capped at both ends.
        for (s, r) in ranges.iter().enumerate() {
            for (c, &[a, b]) in r.iter().enumerate() {
                if !(a.is_finite() && b.is_finite()) {
                    continue;
                }
                let x = c as f64 + 0.1 + (s as f64 + 0.5) * w;
                let cap = 0.25 * w;
                for line in [
                    vec![(x, a), (x, b)],
                    vec![(x - cap, a), (x + cap, a)],
                    vec![(x - cap, b), (x + cap, b)],
                ] {
                    chart.draw_series(std::iter::once(PathElement::new(
                        line,
                        BLACK.stroke_width(2),
                    )))?;
                }
            }
        }
        // Category names centred under their groups (plotters puts numeric ticks at
        // round numbers, not at group centres).
        let style = TextStyle::from((FAMILY, 14).into_font())
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Top));
        for (c, name) in categories.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(c as f64 + 0.5, lo));
            root.draw(&Text::new(name.as_str(), (x, y + 8), style.clone()))?;
        }
        let plot_width = plot.dim_in_pixel().0;
        for s in 0..series.len() {
            legend_swatch(root, plot_width, s, |at| {
                Rectangle::new(
                    [(at.0 - 6, at.1 - 6), (at.0 + 6, at.1 + 6)],
                    colour(s).filled(),
                )
            })?;
        }
        Ok(())
    })
}

/// The categories of a bench's bar chart: each ray set on the CPU, and on the GPU where
/// there is one ("primary CPU", "primary GPU", …).
pub fn device_categories(sets: &[&str], gpu: bool) -> Vec<String> {
    let mut categories = Vec::new();
    for name in sets {
        categories.push(format!("{name} CPU"));
        if gpu {
            categories.push(format!("{name} GPU"));
        }
    }
    categories
}

/// An x–y chart: one series per colour (and marker shape), joined by lines unless
/// `points_only`. On a log axis, points at or below zero cannot be shown and are left out;
/// non-finite points are left out everywhere. Refused when no point is left to draw.
#[allow(clippy::too_many_arguments)] // one plain argument per property of the chart
pub fn xy_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    log_x: bool,
    log_y: bool,
    series: &[(String, Vec<(f64, f64)>)],
    points_only: bool,
) -> Result<()> {
    let shown = |x: f64, log: bool| x.is_finite() && (!log || x > 0.0);
    let kept: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(name, pts)| {
            let pts = pts.iter().copied();
            let pts = pts.filter(|&(x, y)| shown(x, log_x) && shown(y, log_y));
            (name.clone(), pts.collect())
        })
        .collect();
    let all = || kept.iter().flat_map(|(_, p)| p.iter().copied());
    let (Some(xr), Some(yr)) = (
        axis_range(all().map(|p| p.0), log_x),
        axis_range(all().map(|p| p.1), log_y),
    ) else {
        return Err(chart_error(
            path,
            format!(
                "no point to draw (finite{})",
                if log_x || log_y {
                    ", and above zero on a log axis"
                } else {
                    ""
                }
            ),
        ));
    };
    let names: Vec<&str> = kept.iter().map(|(s, _)| s.as_str()).collect();
    let labels = Labels {
        title,
        x: x_label,
        y: y_label,
    };
    draw_png(path, PLOT.0, &names, |root, plot| {
        let (x, y) = (xr.0..xr.1, yr.0..yr.1);
        match (log_x, log_y) {
            (false, false) => plot_xy(root, plot, &labels, x, y, &kept, points_only),
            (true, false) => plot_xy(root, plot, &labels, x.log_scale(), y, &kept, points_only),
            (false, true) => plot_xy(root, plot, &labels, x, y.log_scale(), &kept, points_only),
            (true, true) => plot_xy(
                root,
                plot,
                &labels,
                x.log_scale(),
                y.log_scale(),
                &kept,
                points_only,
            ),
        }
    })
}

/// The texts of an x–y chart.
struct Labels<'a> {
    title: &'a str,
    x: &'a str,
    y: &'a str,
}

/// The x–y chart on axes of any kind (linear or log).
fn plot_xy<X, Y>(
    root: &Area,
    plot: &Area,
    labels: &Labels,
    x: X,
    y: Y,
    series: &[(String, Vec<(f64, f64)>)],
    points_only: bool,
) -> Drawn
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(plot)
        .caption(labels.title, (FAMILY, 22))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .max_light_lines(1)
        .x_desc(labels.x)
        .y_desc(labels.y)
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 16))
        .draw()?;
    for (s, (_, pts)) in series.iter().enumerate() {
        if !points_only {
            chart.draw_series(LineSeries::new(
                pts.iter().copied(),
                colour(s).stroke_width(2),
            ))?;
        }
        let area = chart.plotting_area();
        for &p in pts {
            draw_marker(area, s, p)?;
        }
    }
    let plot_width = plot.dim_in_pixel().0;
    for s in 0..series.len() {
        legend_marker(root, plot_width, s, points_only)?;
    }
    Ok(())
}

/// Draws a chart: `draw` gets the whole image (for the legend and free text) and the plot
/// area left of the legend panel; the legend lists `names` top to bottom. Then encodes the
/// image as PNG and writes it atomically.
fn draw_png(
    path: &Path,
    plot_width: u32,
    names: &[&str],
    draw: impl FnOnce(&Area, &Area) -> Drawn,
) -> Result<()> {
    register_font().map_err(|e| chart_error(path, e))?;
    let legend_w = legend_width(names);
    let (w, h) = (
        plot_width + legend_w,
        PLOT.1.max(80 + LEGEND_LINE * names.len() as u32),
    );
    if w > MAX_SIDE || h > MAX_SIDE {
        return Err(chart_error(
            path,
            format!("a {w}×{h} chart is larger than {MAX_SIDE} pixels on a side"),
        ));
    }
    let mut buf = vec![0u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let drawn: Drawn = (|| {
            root.fill(&WHITE)?;
            let (plot, _) = root.split_horizontally(plot_width);
            draw(&root, &plot)?;
            let text = TextStyle::from((FAMILY, 14).into_font()).color(&BLACK);
            for (i, name) in names.iter().enumerate() {
                let (x, y) = legend_at(plot_width, i);
                root.draw(&Text::new(
                    *name,
                    (x + 14, y),
                    text.pos(Pos::new(HPos::Left, VPos::Center)),
                ))?;
            }
            root.present()?;
            Ok(())
        })();
        drawn.map_err(|e| chart_error(path, e))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| chart_error(path, "the image buffer has the wrong size"))?;
    crate::output::write_atomic(path, |out| {
        img.write_to(out, image::ImageFormat::Png)
            .map_err(std::io::Error::other)
    })
}

/// Width of the legend panel: the longest name plus its marker and margins.
fn legend_width(names: &[&str]) -> u32 {
    // DejaVu Sans at 14 px: at most about 9 px per character.
    let longest = names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
    40 + 9 * longest.min(60) as u32
}

/// Centre of legend line `i`'s marker, in image pixels.
fn legend_at(plot_width: u32, i: usize) -> (i32, i32) {
    (
        plot_width as i32 + 16,
        48 + (LEGEND_LINE as usize * i) as i32,
    )
}

/// Draws the legend marker of series `s`: the element `swatch` makes at the marker's centre
/// (`plot_width`: where the legend panel starts).
fn legend_swatch<DB, E>(
    root: &DrawingArea<DB, Shift>,
    plot_width: u32,
    s: usize,
    swatch: impl Fn((i32, i32)) -> E,
) -> Drawn
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    E: Drawable<DB>,
    for<'b> &'b E: PointCollection<'b, (i32, i32)>,
{
    root.draw(&swatch(legend_at(plot_width, s)))?;
    Ok(())
}

/// The legend marker of an x–y series: its point marker, on a short line unless points only.
fn legend_marker(root: &Area, plot_width: u32, s: usize, points_only: bool) -> Drawn {
    if !points_only {
        legend_swatch(root, plot_width, s, |(x, y)| {
            PathElement::new(vec![(x - 8, y), (x + 8, y)], colour(s).stroke_width(2))
        })?;
    }
    draw_marker(root, s, legend_at(plot_width, s))
}

/// Draws series `s`'s marker at `at`: its colour, and one of three shapes (so that series of
/// similar colours still differ).
fn draw_marker<DB, CT>(area: &DrawingArea<DB, CT>, s: usize, at: CT::From) -> Drawn
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
    CT::From: Clone,
{
    let style = colour(s).filled();
    match s % 3 {
        0 => area.draw(&Circle::new(at, 5, style))?,
        1 => area.draw(&TriangleMarker::new(at, 7, style))?,
        _ => area.draw(&(EmptyElement::at(at) + Rectangle::new([(-4, -4), (4, 4)], style)))?,
    }
    Ok(())
}

/// Colour of series `s`.
fn colour(s: usize) -> RGBColor {
    // Tableau 20: the ten strong colours, then their light shades (`bench layouts` draws 12
    // series); distinct for the first twenty series, then repeated (with another shape).
    const TABLEAU: [(u8, u8, u8); 20] = [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
        (174, 199, 232),
        (255, 187, 120),
        (152, 223, 138),
        (255, 152, 150),
        (197, 176, 213),
        (196, 156, 148),
        (247, 182, 210),
        (199, 199, 199),
        (219, 219, 141),
        (158, 218, 229),
    ];
    let (r, g, b) = TABLEAU[s % TABLEAU.len()];
    RGBColor(r, g, b)
}

/// The data range of one axis, padded; on a log axis only values above zero count.
fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold(None, |r: Option<(f64, f64)>, v| match r {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })?;
    Some(if log {
        // A tenth of a decade (at least) of room on either side.
        let f = (hi / lo).powf(0.05).max(1.26);
        (lo / f, hi * f)
    } else {
        let pad = if hi > lo {
            0.05 * (hi - lo)
        } else {
            0.1 * lo.abs().max(1.0)
        };
        (lo - pad, hi + pad)
    })
}

/// A tick label: short, exponent notation for very large or small magnitudes.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        s.replace(".0e", "e")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Registers the embedded font under [`FAMILY`], once.
pub fn register_font() -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err("the embedded font does not load".into())
    }
}

/// A chart that could not be drawn or written: an I/O error naming the file.
pub fn chart_error(path: &Path, why: impl std::fmt::Display) -> Error {
    Error::io(path, std::io::Error::other(format!("chart: {why}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixels_of(img: &image::RgbImage, c: RGBColor) -> usize {
        img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count()
    }

    /// Dark pixels (text) in the legend panel, right of the plot.
    fn legend_ink(img: &image::RgbImage, plot_width: u32) -> usize {
        img.enumerate_pixels()
            .filter(|(x, _, p)| *x > plot_width && p.0.iter().all(|&v| v < 100))
            .count()
    }

    #[test]
    fn twenty_series_get_twenty_colours() {
        let colours: std::collections::HashSet<_> = (0..20)
            .map(|s| (colour(s).0, colour(s).1, colour(s).2))
            .collect();
        assert_eq!(colours.len(), 20);
        assert_eq!(colour(20), colour(0));
    }

    #[test]
    fn bar_chart_draws_every_series_and_its_legend_text() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bars.png");
        let cats: Vec<String> = ["sweep", "binned 16", "median"].map(String::from).into();
        let series = vec![
            ("cpu".to_string(), vec![3.0, 2.5, 4.0]),
            ("gpu".to_string(), vec![1.0, f64::NAN, 0.5]),
        ];
        bar_chart(&out, "build time", "time (ms)", &cats, &series).unwrap();
        let img = image::open(&out).unwrap().to_rgb8();
        assert!(img.height() >= PLOT.1 && img.width() > PLOT.0);
        for s in 0..2 {
            assert!(pixels_of(&img, colour(s)) > 500, "series {s} has no bars");
        }
        assert!(legend_ink(&img, PLOT.0) > 50, "no legend text drawn");
        // Only the chart in the folder: no temporary left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let bad = vec![("cpu".to_string(), vec![1.0])];
        let e = bar_chart(&out, "t", "ms", &cats, &bad).unwrap_err();
        assert!(e.to_string().contains("1 values for 3 categories"), "{e}");
    }

    #[test]
    fn whiskers_are_drawn_where_a_bar_has_a_range_and_reach_past_it() {
        let dir = tempfile::tempdir().unwrap();
        let (plain, whiskers) = (dir.path().join("plain.png"), dir.path().join("w.png"));
        let cats: Vec<String> = ["1M", "4M"].map(String::from).into();
        let series = vec![("binned".to_string(), vec![2.0, 3.0])];
        // A whisker on the first bar only, reaching above every bar (the y axis takes it
        // in); against the same chart whose whisker has no length (the same axes and labels).
        let (nil, ranges) = (
            vec![vec![[6.0, 6.0], [f64::NAN; 2]]],
            vec![vec![[1.5, 6.0], [f64::NAN; 2]]],
        );
        bar_chart_with_ranges(&plain, "build", "ms", &cats, &series, &nil).unwrap();
        bar_chart_with_ranges(&whiskers, "build", "ms", &cats, &series, &ranges).unwrap();
        let (with, without) = (
            image::open(&whiskers).unwrap().to_rgb8(),
            image::open(&plain).unwrap().to_rgb8(),
        );
        assert_eq!(with.dimensions(), without.dimensions());
        // The whisker is a vertical run of dark pixels the other chart lacks: count them
        // per column (its caps add a few to many columns, not a tall run to one).
        let dark = |p: &image::Rgb<u8>| p.0.iter().all(|&c| c < 60);
        let tallest = (0..with.width())
            .map(|x| {
                (0..with.height())
                    .filter(|&y| dark(with.get_pixel(x, y)) && !dark(without.get_pixel(x, y)))
                    .count()
            })
            .max()
            .unwrap_or(0);
        assert!(
            tallest > 150,
            "no whisker drawn: {tallest} new dark pixels in a column"
        );
        let bad = vec![vec![[1.0, 2.0]]];
        let e = bar_chart_with_ranges(&whiskers, "b", "ms", &cats, &series, &bad).unwrap_err();
        assert!(e.to_string().contains("1 ranges for 2 categories"), "{e}");
        let e = bar_chart_with_ranges(&whiskers, "b", "ms", &cats, &series, &[]).unwrap_err();
        assert!(e.to_string().contains("0 ranges for 1 series"), "{e}");
    }

    #[test]
    fn xy_chart_on_log_axes_leaves_out_what_it_cannot_show() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("xy.png");
        let series = vec![
            (
                "rmse".to_string(),
                vec![(1.0, 0.5), (4.0, 0.25), (16.0, 0.125)],
            ),
            (
                "zero".to_string(),
                vec![(2.0, 0.0), (0.0, 1.0), (f64::NAN, 1.0)],
            ),
            ("bias".to_string(), vec![(1.0, 0.01), (16.0, 0.011)]),
        ];
        for points_only in [false, true] {
            xy_chart(
                &out,
                "convergence",
                "spp",
                "RMSE",
                true,
                true,
                &series,
                points_only,
            )
            .unwrap();
            let img = image::open(&out).unwrap().to_rgb8();
            assert!(pixels_of(&img, colour(0)) > 40 && pixels_of(&img, colour(2)) > 40);
            assert!(legend_ink(&img, PLOT.0) > 50, "no legend text drawn");
        }
        let nothing = vec![("zero".to_string(), vec![(1.0, 0.0), (2.0, -1.0)])];
        let e = xy_chart(&out, "t", "x", "y", false, true, &nothing, true).unwrap_err();
        assert!(e.to_string().contains("no point to draw"), "{e}");
        xy_chart(&out, "t", "x", "y", false, false, &nothing, false).unwrap();
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(100.0), "100");
        assert_eq!(tick(1e-5), "1e-5");
        assert_eq!(tick(2.5e7), "2.5e7");
    }
}
