//! Writing renders: PNG (sRGB, 8-bit) or OpenEXR (linear, float), by the file extension.

use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};

fn srgb(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Linear radiance → an 8-bit sRGB image (values clipped to [0, 1]).
pub fn to_rgb8(px: &[Vec3], width: u32, height: u32) -> image::RgbImage {
    image::RgbImage::from_fn(width, height, |x, y| {
        let c = px[(y * width + x) as usize];
        image::Rgb([srgb(c.x), srgb(c.y), srgb(c.z)])
    })
}

/// The output formats, by lower-case extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    Png,
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

/// Saves linear radiance as PNG (sRGB) or EXR (linear float), chosen by extension.
pub fn save_image(path: &Path, px: &[Vec3], width: u32, height: u32) -> Result<()> {
    let fail = |e: image::ImageError| Error::input(path, None, format!("cannot write image: {e}"));
    match image_kind(path)? {
        ImageKind::Png => to_rgb8(px, width, height).save(path).map_err(fail),
        ImageKind::Exr => {
            let img = image::Rgb32FImage::from_fn(width, height, |x, y| {
                image::Rgb(px[(y * width + x) as usize].to_array())
            });
            img.save(path).map_err(fail)
        }
    }
}
