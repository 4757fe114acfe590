//! OpenEXR files as lancer writes and reads them: one part of 32-bit float channels (R, G, B
//! and any AOV channels such as `depth.Z`), whose data window is the tile's pixel bounds
//! inside a display window of the full image's size (a whole image: both the same).

use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, ImageAttributes, IntegerBounds, Layer,
    LayerAttributes, ReadChannels, ReadLayers, Vec2, WritableImage,
};

use super::crop::{Crop, Tile};
use crate::error::{Error, Result};

/// Float channels over a tile of a full image.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrImage {
    /// Where the data sits in the full image, and the full image's size.
    pub tile: Tile,
    /// (name, one value per pixel of the tile, row-major), sorted by name.
    pub channels: Vec<(String, Vec<f32>)>,
}

impl ExrImage {
    /// Writes the channels atomically (a temporary file in the same folder, then a rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        let b = self.tile.bounds;
        let (full_w, full_h) = (self.tile.full_width, self.tile.full_height);
        // OpenEXR windows are in i32 coordinates.
        if [b.x1, b.y1, full_w, full_h]
            .iter()
            .any(|&v| v > i32::MAX as u32)
        {
            return Err(Error::Usage(format!(
                "a {full_w}×{full_h} image does not fit OpenEXR's i32 pixel coordinates: \
                 write a PNG"
            )));
        }
        // Every channel one value a pixel of the tile (the encoder reads that many).
        let pixels = b.width() as u64 * b.height() as u64;
        if let Some((name, values)) = (self.channels.iter()).find(|(_, v)| v.len() as u64 != pixels)
        {
            return Err(Error::Usage(format!(
                "channel {name} holds {} values for a {}×{} tile: give one a pixel, row by row",
                values.len(),
                b.width(),
                b.height()
            )));
        }
        let size = Vec2(b.width() as usize, b.height() as usize);
        let channels = (self.channels.iter())
            .map(|(name, values)| AnyChannel::new(name.as_str(), FlatSamples::F32(values.clone())))
            .collect();
        let attributes = LayerAttributes {
            layer_position: Vec2(b.x0 as i32, b.y0 as i32),
            ..LayerAttributes::default()
        };
        let layer = Layer::new(
            size,
            attributes,
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(channels),
        );
        let display = IntegerBounds::new(Vec2(0, 0), Vec2(full_w as usize, full_h as usize));
        let image = exr::image::Image::new(ImageAttributes::new(display), layer);
        crate::output::write_atomic(path, |w| {
            image.write().to_buffered(w).map_err(std::io::Error::other)
        })
    }

    /// Reads the first part of an EXR: its float channels, data and display windows.
    /// Refuses (naming the file) what lancer does not write: windows outside u32 pixel
    /// coordinates, a display window not at the origin, non-float channels.
    pub fn read(path: &Path) -> Result<ExrImage> {
        let bad = |msg: String| Error::input(path, None, msg);
        let open = || crate::input::open(path).map(|(file, _)| file);
        // Sizes from the header first: a hostile header must not size an allocation.
        let meta = exr::meta::MetaData::read_from_buffered(std::io::BufReader::new(open()?), false)
            .map_err(|e| bad(format!("not a readable OpenEXR image: {e}")))?;
        for h in meta.headers.iter() {
            let (w, hh) = (h.layer_size.0, h.layer_size.1);
            let bytes = w as u128 * hh as u128 * 4 * h.channels.list.len().max(1) as u128;
            crate::limits::check_memory(
                &format!("{}: a {w}×{hh} OpenEXR part", path.display()),
                bytes,
                "not an image this machine can read",
            )?;
        }
        let file = open()?;
        let image = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::BufReader::new(file))
            .map_err(|e| bad(format!("not a readable OpenEXR image: {e}")))?;
        let display = image.attributes.display_window;
        let layer = image.layer_data;
        let u32_of = |x: i64, what: &str| {
            u32::try_from(x).map_err(|_| bad(format!("{what} {x} is outside 0..2^32")))
        };
        if display.position != Vec2(0, 0) {
            return Err(bad(format!(
                "the display window starts at {:?}, not at the origin: not a lancer image",
                display.position
            )));
        }
        let (x0, y0) = (
            layer.attributes.layer_position.0,
            layer.attributes.layer_position.1,
        );
        let bounds = Crop {
            x0: u32_of(x0 as i64, "the data window's x")?,
            y0: u32_of(y0 as i64, "the data window's y")?,
            x1: u32_of(
                x0 as i64 + layer.size.0 as i64,
                "the data window's right edge",
            )?,
            y1: u32_of(
                y0 as i64 + layer.size.1 as i64,
                "the data window's bottom edge",
            )?,
        };
        let tile = Tile {
            bounds,
            full_width: u32_of(display.size.0 as i64, "the display window's width")?,
            full_height: u32_of(display.size.1 as i64, "the display window's height")?,
        };
        let mut channels = Vec::new();
        for c in layer.channel_data.list {
            match c.sample_data {
                FlatSamples::F32(values) => channels.push((c.name.to_string(), values)),
                _ => {
                    return Err(bad(format!(
                        "channel {} is not 32-bit float: not a lancer image",
                        c.name
                    )))
                }
            }
        }
        channels.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(ExrImage { tile, channels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Image;
    use glam::Vec3;

    /// A channel shorter or longer than its tile, written directly or through an image
    /// whose tile does not match its pixels, is refused with its name, nothing written.
    #[test]
    fn channels_must_fill_their_tile() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.exr");
        let tile = Tile {
            bounds: Crop::full(2, 2),
            full_width: 2,
            full_height: 2,
        };
        let with = |values: Vec<f32>| ExrImage {
            tile,
            channels: vec![("R".into(), values)],
        };
        with(vec![0.5; 4]).write(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        for n in [0, 3, 5] {
            let e = with(vec![0.5; n]).write(&path).unwrap_err().to_string();
            assert!(
                e.contains(&format!("channel R holds {n} values for a 2×2 tile")),
                "{e}"
            );
        }
        let image = Image {
            width: 1,
            height: 1,
            pixels: vec![Vec3::ZERO],
            tile: Some(tile),
        };
        let e = image.save(&path).unwrap_err().to_string();
        assert!(e.contains("holds 1 values for a 2×2 tile"), "{e}");
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert!(left.is_empty(), "files left: {left:?}");
    }
}
