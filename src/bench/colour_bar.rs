//! A colour bar under a heatmap: the heat ramp from 0 to the top of the scale with numbered
//! ticks, what the numbers count, and the colour of pixels that have no number. The map's
//! own pixels are copied unchanged into the top-left corner, so they stay the ramp of their
//! counts; the text is drawn by plotters with the charts' embedded font.

use std::path::Path;

use crate::error::Result;
use crate::render::heat_ramp;
use image::{Rgb, RgbImage};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::chart::{chart_error, register_font, FAMILY};

/// The narrowest image with a bar: its caption and tick labels need this much room even
/// under a tiny map.
const MIN_WIDTH: u32 = 380;
/// Space left and right of the ramp.
const MARGIN: u32 = 14;
/// Rows of the bar, in pixels below the map: caption, ramp, tick marks, tick labels, and
/// the line that explains the no-count colour.
const CAPTION_Y: u32 = 6;
const RAMP_Y: u32 = 26;
const RAMP_H: u32 = 14;
const TICK_H: u32 = 4;
const LABEL_Y: u32 = RAMP_Y + RAMP_H + TICK_H + 2;
const NO_COUNT_Y: u32 = LABEL_Y + 20;
const SWATCH: u32 = 12;
/// Height of the bar without and with the no-count line.
const BAR_H: u32 = LABEL_Y + 22;
const BAR_H_NO_COUNT: u32 = NO_COUNT_Y + SWATCH + 8;
/// Text sizes in pixels.
const CAPTION_SIZE: u32 = 14;
const LABEL_SIZE: u32 = 12;

/// What a colour bar shows.
#[derive(Clone, Debug)]
pub struct ColourBar {
    /// What a value counts, e.g. "nodes visited per primary ray".
    pub caption: String,
    /// The top of the scale (at least 1): the brightest colour.
    pub max: u32,
    /// Whether larger values were clipped to `max` (a fixed scale): the top tick reads ≥ max.
    pub saturates: bool,
    /// The colour of pixels without a value, and what it means (drawn as a swatch).
    pub no_count: Option<([u8; 3], String)>,
}

/// The map with the colour bar below it: the map in the top-left corner, unchanged; the
/// image is at least `MIN_WIDTH` pixels wide, the room right of a narrow map left white. `path`
/// names the file in errors.
pub fn with_colour_bar(path: &Path, map: &RgbImage, bar: &ColourBar) -> Result<RgbImage> {
    register_font().map_err(|e| chart_error(path, e))?;
    let bar_h = match bar.no_count {
        Some(_) => BAR_H_NO_COUNT,
        None => BAR_H,
    };
    let (w, h) = (map.width().max(MIN_WIDTH), map.height() + bar_h);
    // The map passed the image-size check; the bar adds a fixed strip.
    crate::limits::check_image(w, h, 3, "use a smaller --width/--height")?;
    let top = map.height();
    let ramp = (MARGIN, w - MARGIN - 1);
    let mut buf = vec![255u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw_text(&root, bar, top, ramp).map_err(|e| chart_error(path, e))?;
    }
    let mut img = RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| chart_error(path, "the image buffer has the wrong size"))?;
    image::imageops::replace(&mut img, map, 0, 0);
    let span = (ramp.1 - ramp.0) as f32;
    for x in ramp.0..=ramp.1 {
        let c = Rgb(heat_ramp((x - ramp.0) as f32 / span));
        for y in top + RAMP_Y..top + RAMP_Y + RAMP_H {
            img.put_pixel(x, y, c);
        }
    }
    for v in ticks(bar.max) {
        let x = tick_x(v, bar.max, ramp);
        for y in top + RAMP_Y + RAMP_H..top + RAMP_Y + RAMP_H + TICK_H {
            img.put_pixel(x, y, Rgb([0, 0, 0]));
        }
    }
    if let Some((colour, _)) = &bar.no_count {
        for y in top + NO_COUNT_Y..top + NO_COUNT_Y + SWATCH {
            for x in MARGIN..MARGIN + SWATCH {
                img.put_pixel(x, y, Rgb(*colour));
            }
        }
    }
    Ok(img)
}

/// The caption, the tick labels and the no-count line.
fn draw_text(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    bar: &ColourBar,
    top: u32,
    ramp: (u32, u32),
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let ink = |size: u32, h: HPos| {
        TextStyle::from((FAMILY, size).into_font())
            .color(&BLACK)
            .pos(Pos::new(h, VPos::Top))
    };
    let at = |x: u32, y: u32| (x as i32, (top + y) as i32);
    root.draw(&Text::new(
        bar.caption.as_str(),
        at(MARGIN, CAPTION_Y),
        ink(CAPTION_SIZE, HPos::Left),
    ))?;
    let label = |v: u32| match (v == bar.max, bar.saturates) {
        (true, true) => format!("≥{v}"),
        _ => v.to_string(),
    };
    // The ends are anchored inside the image; a middle tick too close to the top's label
    // is left unlabelled rather than overprinted.
    let top_label = label(bar.max);
    let (top_w, _) = root.estimate_text_size(&top_label, &ink(LABEL_SIZE, HPos::Right))?;
    let top_x = tick_x(bar.max, bar.max, ramp);
    for v in ticks(bar.max) {
        let x = tick_x(v, bar.max, ramp);
        let (text, anchor) = match v {
            0 => (label(0), HPos::Left),
            v if v == bar.max => (top_label.clone(), HPos::Right),
            v => {
                let text = label(v);
                let (tw, _) = root.estimate_text_size(&text, &ink(LABEL_SIZE, HPos::Center))?;
                if x + tw / 2 + 6 + top_w > top_x || x < ramp.0 + tw {
                    continue;
                }
                (text, HPos::Center)
            }
        };
        root.draw(&Text::new(text, at(x, LABEL_Y), ink(LABEL_SIZE, anchor)))?;
    }
    if let Some((_, meaning)) = &bar.no_count {
        root.draw(&Text::new(
            meaning.as_str(),
            at(MARGIN + SWATCH + 6, NO_COUNT_Y - 1),
            ink(LABEL_SIZE, HPos::Left),
        ))?;
    }
    root.present()?;
    Ok(())
}

/// Column of value `v` on the ramp spanning columns `ramp` (inclusive), 0 to `max`.
fn tick_x(v: u32, max: u32, ramp: (u32, u32)) -> u32 {
    let f = v.min(max) as f64 / max.max(1) as f64;
    ramp.0 + (f * (ramp.1 - ramp.0) as f64).round() as u32
}

/// Tick values: 0, multiples of a round step (1, 2 or 5 × 10ᵏ, about a quarter of the
/// scale), and the top of the scale.
fn ticks(max: u32) -> Vec<u32> {
    let max = max.max(1);
    let raw = u64::from(max).div_ceil(4);
    let mut p = 1u64;
    while p * 10 <= raw {
        p *= 10;
    }
    let step = [1, 2, 5, 10]
        .into_iter()
        .map(|m| m * p)
        .find(|&s| s >= raw)
        .unwrap_or(10 * p);
    let mut v: Vec<u32> = (0..)
        .map(|k| k * step)
        .take_while(|&t| t < u64::from(max))
        .filter_map(|t| u32::try_from(t).ok())
        .collect();
    v.push(max);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_start_at_zero_end_at_the_top_and_step_evenly() {
        for max in [1, 2, 3, 7, 10, 37, 100, 999, 123_456, u32::MAX] {
            let t = ticks(max);
            assert_eq!((t[0], *t.last().unwrap()), (0, max), "{t:?}");
            assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
            assert!((2..=6).contains(&t.len()), "{max}: {t:?}");
            if t.len() > 2 {
                let step = t[1];
                assert!(t[1..t.len() - 1].iter().all(|v| v % step == 0), "{t:?}");
            }
        }
    }

    #[test]
    fn the_bar_keeps_the_map_and_shows_the_ramp_and_the_no_count_colour() {
        let mut map = RgbImage::new(20, 10);
        for (x, y, p) in map.enumerate_pixels_mut() {
            *p = Rgb([x as u8, y as u8, 7]);
        }
        let grey = [128, 128, 128];
        let bar = ColourBar {
            caption: "nodes visited per primary ray".into(),
            max: 40,
            saturates: true,
            no_count: Some((grey, "no shadow ray".into())),
        };
        let img = with_colour_bar(Path::new("x.png"), &map, &bar).unwrap();
        assert_eq!(
            (img.width(), img.height()),
            (MIN_WIDTH, 10 + BAR_H_NO_COUNT)
        );
        for (x, y, p) in map.enumerate_pixels() {
            assert_eq!(img.get_pixel(x, y), p);
        }
        let row = 10 + RAMP_Y + RAMP_H / 2;
        assert_eq!(img.get_pixel(MARGIN, row).0, heat_ramp(0.0));
        assert_eq!(img.get_pixel(MIN_WIDTH - MARGIN - 1, row).0, heat_ramp(1.0));
        let swatch = img.get_pixel(MARGIN + 1, 10 + NO_COUNT_Y + 1).0;
        assert_eq!(swatch, grey);
        // Text was drawn: dark pixels among the caption and the labels.
        let ink = |y0: u32, y1: u32| {
            (y0..y1)
                .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0.iter().all(|&v| v < 100))
                .count()
        };
        assert!(ink(10 + CAPTION_Y, 10 + RAMP_Y) > 50);
        assert!(ink(10 + LABEL_Y, 10 + NO_COUNT_Y) > 20);
        assert!(ink(10 + NO_COUNT_Y, img.height()) > 20);
    }
}
