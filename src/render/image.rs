//! Writing renders: PNG (sRGB, 8- or 16-bit) or OpenEXR (linear, float), by the file
//! extension.
//! A tile's EXR records where the tile sits in the full image (see [`ExrImage`]).

use std::path::Path;

use glam::Vec3;

use super::crop::{Crop, Tile};
use super::exr::ExrImage;
use crate::error::{Error, Result};

/// Linear → sRGB-encoded, in [0, 1] (values clipped, NaN as 0).
fn srgb_encoded(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

fn srgb(x: f32) -> u8 {
    (srgb_encoded(x) * 255.0).round() as u8
}

/// Refuses pixels that are not `width · height` (an image made in code).
pub(super) fn check_pixels(px: &[Vec3], width: u32, height: u32) -> Result<()> {
    if px.len() as u64 != width as u64 * height as u64 {
        return Err(Error::Usage(format!(
            "{} pixels for a {width}×{height} image: give width · height pixels, row by row",
            px.len()
        )));
    }
    Ok(())
}

/// The pixel at (x, y) of a `width`-wide image, black where `px` is too short.
fn pixel(px: &[Vec3], width: u32, x: u32, y: u32) -> Vec3 {
    let i = y as u64 * width as u64 + x as u64;
    usize::try_from(i)
        .ok()
        .and_then(|i| px.get(i))
        .copied()
        .unwrap_or(Vec3::ZERO)
}

/// Linear radiance → a 16-bit sRGB image (values clipped to [0, 1]; pixels missing from
/// `px` black).
pub fn to_rgb16(
    px: &[Vec3],
    width: u32,
    height: u32,
) -> image::ImageBuffer<image::Rgb<u16>, Vec<u16>> {
    let q = |x: f32| (srgb_encoded(x) * 65535.0).round() as u16;
    image::ImageBuffer::from_fn(width, height, |x, y| {
        let c = pixel(px, width, x, y);
        image::Rgb([q(c.x), q(c.y), q(c.z)])
    })
}

/// Linear radiance → an 8-bit sRGB image (values clipped to [0, 1]; pixels missing from
/// `px` black).
pub fn to_rgb8(px: &[Vec3], width: u32, height: u32) -> image::RgbImage {
    image::RgbImage::from_fn(width, height, |x, y| {
        let c = pixel(px, width, x, y);
        image::Rgb([srgb(c.x), srgb(c.y), srgb(c.z)])
    })
}

/// Black → purple → orange → yellow for t in [0, 1] (clamped): heatmaps and difference
/// pictures.
pub fn heat_ramp(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.02],
        [0.34, 0.06, 0.43],
        [0.73, 0.21, 0.33],
        [0.98, 0.55, 0.04],
        [0.99, 1.0, 0.64],
    ];
    let x = if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) } * 4.0;
    let i = (x as usize).min(3);
    let f = x - i as f32;
    let c = |k: usize| STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * f;
    [0, 1, 2].map(|k| (c(k) * 255.0).round() as u8)
}

/// The output formats, by lower-case extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// PNG, sRGB 8-bit.
    Png,
    /// OpenEXR, linear float.
    Exr,
}

/// The format a file name asks for; checked before rendering so no work is lost.
pub fn image_kind(path: &Path) -> Result<ImageKind> {
    let ext = (path.extension().and_then(|e| e.to_str()))
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "png" => Ok(ImageKind::Png),
        "exr" => Ok(ImageKind::Exr),
        _ => Err(Error::input(
            path,
            None,
            "unknown image type: use a .png (sRGB) or .exr (linear) file name",
        )),
    }
}

/// A rendered image: linear RGB radiance per pixel, row-major from the top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` linear RGB values.
    pub pixels: Vec<Vec3>,
    /// For a tile of a larger image (a render with a crop): where it sits. None: the
    /// whole image.
    pub tile: Option<Tile>,
}

impl Image {
    /// Saves the image as PNG (sRGB 8-bit) or EXR (linear float), chosen by the extension,
    /// written atomically. A tile's EXR has its bounds as data window and the full image as
    /// display window; a tile's PNG holds the tile's pixels only.
    pub fn save(&self, path: &Path) -> Result<()> {
        match image_kind(path)? {
            ImageKind::Png => save_image(path, &self.pixels, self.width, self.height),
            ImageKind::Exr => {
                check_pixels(&self.pixels, self.width, self.height)?;
                self.to_exr().write(path)
            }
        }
    }

    /// Saves the image as a 16-bit sRGB PNG, written atomically.
    pub fn save_png16(&self, path: &Path) -> Result<()> {
        check_pixels(&self.pixels, self.width, self.height)?;
        let png = to_rgb16(&self.pixels, self.width, self.height);
        crate::output::write_atomic(path, |w| {
            png.write_to(w, image::ImageFormat::Png)
                .map_err(std::io::Error::other)
        })
    }

    /// The image as EXR channels R, G, B, placed as its tile says.
    pub fn to_exr(&self) -> ExrImage {
        let tile = self.tile.unwrap_or(Tile {
            bounds: Crop::full(self.width, self.height),
            full_width: self.width,
            full_height: self.height,
        });
        let channel = |k: usize| self.pixels.iter().map(|c| c[k]).collect();
        ExrImage {
            tile,
            channels: vec![
                ("B".into(), channel(2)),
                ("G".into(), channel(1)),
                ("R".into(), channel(0)),
            ],
        }
    }

    /// The image as 8-bit sRGB (values clipped to [0, 1]).
    pub fn to_rgb8(&self) -> image::RgbImage {
        to_rgb8(&self.pixels, self.width, self.height)
    }
}

/// Saves linear radiance as PNG (sRGB) or EXR (linear float), chosen by extension, written
/// atomically (a temporary file in the same folder, then a rename).
pub fn save_image(path: &Path, px: &[Vec3], width: u32, height: u32) -> Result<()> {
    let kind = image_kind(path)?;
    check_pixels(px, width, height)?;
    let encode = |w: &mut std::io::BufWriter<std::fs::File>| {
        let r = match kind {
            ImageKind::Png => to_rgb8(px, width, height).write_to(w, image::ImageFormat::Png),
            ImageKind::Exr => image::Rgb32FImage::from_fn(width, height, |x, y| {
                image::Rgb(pixel(px, width, x, y).to_array())
            })
            .write_to(w, image::ImageFormat::OpenExr),
        };
        r.map_err(std::io::Error::other)
    };
    crate::output::write_atomic(path, encode)
}
