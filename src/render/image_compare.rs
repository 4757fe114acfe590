//! Two images compared pixel by pixel (`lancer compare`): how far apart they are, how many
//! pixels differ by more than a threshold, and a picture of where.

use std::path::Path;

use glam::Vec3;

use super::image::{check_pixels, heat_ramp, image_kind, Image, ImageKind};
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

    /// Writes [`picture`](Self::picture) at `scale` to `path` as a PNG (atomically).
    pub fn write_picture(&self, path: &Path, scale: f32) -> Result<()> {
        let picture = self.picture(scale);
        crate::output::write_atomic(path, |w| {
            (picture.write_to(w, image::ImageFormat::Png)).map_err(std::io::Error::other)
        })
    }

    /// Whether more than `tolerance` % of the pixels are over the threshold.
    pub fn differ(&self, tolerance: f32) -> bool {
        self.over_percent() > tolerance as f64
    }

    /// One line saying how the images differ (or that they are bit-identical).
    pub fn summary(&self) -> String {
        if self.differing == 0 {
            return format!("{}×{} pixels: bit-identical", self.width, self.height);
        }
        let pixels = self.per_pixel.len().max(1) as f64;
        format!(
            "{}×{} pixels: {} differ ({:.3} %), max difference {:.3e}, mean {:.3e}, RMSE \
             {:.3e}; {} pixels ({:.3} %) over the threshold {:e}",
            self.width,
            self.height,
            self.differing,
            100.0 * self.differing as f64 / pixels,
            self.max,
            self.mean,
            self.rmse,
            self.over,
            self.over_percent(),
            self.threshold
        )
    }

    /// The `compare --json` object of this difference, judged against `tolerance` (%), with
    /// the difference picture written to `out`, if any.
    pub fn report(&self, tolerance: f32, out: Option<&Path>) -> ImagesReport {
        ImagesReport {
            kind: "images",
            width: self.width,
            height: self.height,
            max: self.max,
            mean: self.mean,
            rmse: self.rmse,
            over: self.over,
            differing: self.differing,
            over_percent: self.over_percent(),
            threshold: self.threshold,
            tolerance,
            differ: self.differ(tolerance),
            out: out.map(|p| p.display().to_string()),
        }
    }
}

/// `compare --json` on two images: one object a run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ImagesReport {
    /// "images".
    pub kind: &'static str,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Largest difference of a channel (linear radiance).
    pub max: f32,
    /// Mean over pixels of each pixel's largest channel difference.
    pub mean: f64,
    /// Root mean square difference over every channel of every pixel.
    pub rmse: f64,
    /// Pixels whose difference exceeds the threshold.
    pub over: usize,
    /// Pixels not bit-identical in every channel (0: the images are bit-identical).
    pub differing: usize,
    /// `over` in % of the pixels.
    pub over_percent: f64,
    /// The threshold.
    pub threshold: f32,
    /// The tolerance (%).
    pub tolerance: f32,
    /// Whether more than `tolerance` % of pixels differ (exit code 1).
    pub differ: bool,
    /// The difference PNG written, or null.
    pub out: Option<String>,
}

/// Reads a PNG (8 or 16 bit, sRGB: linearised) or an EXR (linear) as linear radiance, chosen
/// by the extension.
pub fn load_image(path: &Path) -> Result<Image> {
    let kind = image_kind(path)?;
    let bytes = crate::input::read(path)?;
    let bad = |e: image::ImageError| Error::input(path, None, format!("not a readable image: {e}"));
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
            .with_guessed_format()
            .map_err(|e| Error::read(path, e))
    };
    // The size from the header first: the decoded image (at most 16 bytes a pixel) and
    // its f32 copy must fit before anything is decoded.
    let (w, h) = reader()?.into_dimensions().map_err(bad)?;
    crate::limits::check_image(w, h, 16 + 12, "not an image this machine can compare")
        .map_err(|e| Error::input(path, None, e.to_string()))?;
    let decoded =
        crate::limits::decode_checked(reader()?, 16 * w as u64 * h as u64).map_err(bad)?;
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
/// which a pixel counts as different. Each image must hold width × height pixels.
pub fn compare_images(a: &Image, b: &Image, threshold: f32) -> Result<ImageDiff> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::Usage(format!(
            "the images differ in size ({}×{} and {}×{}): compare renders of one size",
            a.width, a.height, b.width, b.height
        )));
    }
    check_pixels(&a.pixels, a.width, a.height)?;
    check_pixels(&b.pixels, b.width, b.height)?;
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
