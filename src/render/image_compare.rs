//! Two images compared pixel by pixel (`lancer compare`): how far apart they are, how many
//! pixels differ by more than a threshold, and a picture of where.

use std::path::Path;

use glam::Vec3;

use super::image::{heat_ramp, image_kind, Image, ImageKind};
use crate::error::{Error, Result};

/// How two images of one size differ, in linear radiance (a PNG's sRGB values are
/// linearised first, so a PNG and an EXR of the same render compare).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDiff {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Per pixel, the largest difference over the three channels.
    pub per_pixel: Vec<f32>,
    /// The largest per-pixel difference.
    pub max: f32,
    /// The mean per-pixel difference.
    pub mean: f64,
    /// Root mean square over every channel of every pixel.
    pub rmse: f64,
    /// Pixels whose difference exceeds the threshold.
    pub over: usize,
    /// Pixels not bit-identical in every channel (NaN and ±∞ compared by their bits).
    pub differing: usize,
    /// The threshold `over` counts against.
    pub threshold: f32,
}

impl ImageDiff {
    /// Percentage of pixels over the threshold.
    pub fn over_percent(&self) -> f64 {
        100.0 * self.over as f64 / self.per_pixel.len().max(1) as f64
    }

    /// The difference as a picture: black where equal, through purple and orange to yellow
    /// at `scale` (the largest difference when `scale` is 0).
    pub fn picture(&self, scale: f32) -> image::RgbImage {
        let s = if scale > 0.0 { scale } else { self.max };
        image::RgbImage::from_fn(self.width, self.height, |x, y| {
            let d = self.per_pixel[(y * self.width + x) as usize];
            image::Rgb(heat_ramp(if s > 0.0 { d / s } else { 0.0 }))
        })
    }
}

/// Reads a PNG (8 or 16 bit, sRGB: linearised) or an EXR (linear) as linear radiance, chosen
/// by the extension.
pub fn load_image(path: &Path) -> Result<Image> {
    let kind = image_kind(path)?;
    let decoded = image::ImageReader::open(path)
        .map_err(|e| Error::read(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::read(path, e))?
        .decode()
        .map_err(|e| Error::input(path, None, format!("not a readable image: {e}")))?;
    let rgb = decoded.to_rgb32f();
    let linear = |c: f32| match kind {
        ImageKind::Exr => c,
        ImageKind::Png if c <= 0.04045 => c / 12.92,
        ImageKind::Png => ((c + 0.055) / 1.055).powf(2.4),
    };
    Ok(Image {
        width: rgb.width(),
        height: rgb.height(),
        pixels: (rgb.pixels())
            .map(|p| Vec3::from_array(p.0.map(linear)))
            .collect(),
        tile: None,
    })
}

/// Compares two images of the same size; `threshold` is the per-pixel difference above
/// which a pixel counts as different.
pub fn compare_images(a: &Image, b: &Image, threshold: f32) -> Result<ImageDiff> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::Usage(format!(
            "the images differ in size ({}×{} and {}×{}): compare renders of one size",
            a.width, a.height, b.width, b.height
        )));
    }
    let per_pixel: Vec<f32> = (a.pixels.iter().zip(&b.pixels))
        .map(|(p, q)| {
            (0..3)
                .map(|c| channel_difference(p[c], q[c]))
                .fold(0.0, f32::max)
        })
        .collect();
    let n = per_pixel.len().max(1) as f64;
    let sq: f64 = (a.pixels.iter().zip(&b.pixels))
        .map(|(p, q)| {
            (0..3)
                .map(|c| (channel_difference(p[c], q[c]) as f64).powi(2))
                .sum::<f64>()
        })
        .sum();
    let over = per_pixel.iter().filter(|d| **d > threshold).count();
    let differing = (a.pixels.iter().zip(&b.pixels))
        .filter(|(p, q)| (0..3).any(|c| p[c].to_bits() != q[c].to_bits()))
        .count();
    Ok(ImageDiff {
        width: a.width,
        height: a.height,
        differing,
        max: per_pixel.iter().copied().fold(0.0, f32::max),
        mean: per_pixel.iter().map(|&d| d as f64).sum::<f64>() / n,
        rmse: (sq / (3.0 * n)).sqrt(),
        over,
        threshold,
        per_pixel,
    })
}

/// How far apart two values of a channel are: 0 where their bits are the same (NaN and ±∞
/// included), +∞ where they differ and either is not finite (a NaN or an infinity that the
/// other image does not have is as different as can be), else |a − b|.
fn channel_difference(a: f32, b: f32) -> f32 {
    if a.to_bits() == b.to_bits() {
        0.0
    } else if !a.is_finite() || !b.is_finite() {
        f32::INFINITY
    } else {
        (a - b).abs()
    }
}
