//! Joining EXR tiles into the full image: every pixel from exactly one tile, all tiles of the
//! same full image with the same channels.

use std::path::PathBuf;

use super::crop::{Crop, Tile};
use super::exr::ExrImage;
use crate::error::{Error, Result};

/// No tile owns the pixel yet.
const NONE: u32 = u32::MAX;

/// Joins `tiles` (each with the file it came from, for messages) into the full image.
/// Refuses, naming the file: a full size or channel list unlike the first tile's, a tile
/// reaching outside the full image, a tile overlapping an earlier one; and a pixel that no
/// tile covers.
pub fn merge_tiles(tiles: &[(PathBuf, ExrImage)]) -> Result<ExrImage> {
    let Some((first_path, first)) = tiles.first() else {
        return Err(Error::Usage("merge: give at least one tile".into()));
    };
    let (w, h) = (first.tile.full_width, first.tile.full_height);
    let names: Vec<&str> = first.channels.iter().map(|c| c.0.as_str()).collect();
    if tiles.len() > NONE as usize {
        return Err(Error::Usage(format!(
            "merge: {} tiles is too many",
            tiles.len()
        )));
    }
    // Everything the tiles' headers and sizes tell, before the full image is allocated.
    let mut covered: u64 = 0;
    for (path, t) in tiles {
        let bad = |msg: String| Error::input(path, None, msg);
        if (t.tile.full_width, t.tile.full_height) != (w, h) {
            return Err(bad(format!(
                "is a tile of a {}×{} image, {} of a {w}×{h} one: tiles of different renders",
                t.tile.full_width,
                t.tile.full_height,
                first_path.display()
            )));
        }
        let these: Vec<&str> = t.channels.iter().map(|c| c.0.as_str()).collect();
        if these != names {
            return Err(bad(format!(
                "has channels [{}], {} has [{}]: tiles of different renders",
                these.join(", "),
                first_path.display(),
                names.join(", ")
            )));
        }
        let b = t.tile.bounds;
        if b.x1 > w || b.y1 > h {
            return Err(bad(format!(
                "covers pixels {}..{} × {}..{}, outside its {w}×{h} image",
                b.x0, b.x1, b.y0, b.y1
            )));
        }
        for (_, values) in &t.channels {
            if values.len() != b.pixels() {
                return Err(bad(format!(
                    "holds {} values a channel for {} pixels",
                    values.len(),
                    b.pixels()
                )));
            }
        }
        covered += b.pixels() as u64;
    }
    // Tiles inside the image that do not overlap cover it exactly when their pixels add up
    // to its own: fewer means a tile is missing, found here without the full image.
    let full = w as u64 * h as u64;
    if covered < full {
        let at = uncovered(tiles)
            .map(|(x, y)| format!("no tile covers pixel ({x}, {y}), "))
            .unwrap_or_default();
        return Err(Error::Usage(format!(
            "merge: {at}the tiles cover {covered} of the {w}×{h} image's {full} pixels: a tile \
             is missing"
        )));
    }
    // The owner map and the output channels.
    crate::limits::check_image(
        w,
        h,
        4 + 4 * names.len() as u64,
        "the tiles' full image is too large to merge here",
    )?;
    let pixels = w as usize * h as usize;
    let mut owner = vec![NONE; pixels];
    let mut out: Vec<(String, Vec<f32>)> = (names.iter())
        .map(|n| (n.to_string(), vec![0.0; pixels]))
        .collect();
    for (k, (path, t)) in tiles.iter().enumerate() {
        let b = t.tile.bounds;
        for i in 0..b.pixels() {
            let (x, y) = b.pixel(i);
            let at = y as usize * w as usize + x as usize;
            if owner[at] != NONE {
                return Err(Error::input(
                    path,
                    None,
                    format!(
                        "overlaps {} at pixel ({x}, {y}): give tiles that do not overlap",
                        tiles[owner[at] as usize].0.display()
                    ),
                ));
            }
            owner[at] = k as u32;
            for (o, (_, values)) in out.iter_mut().zip(&t.channels) {
                o.1[at] = values[i];
            }
        }
    }
    if let Some(at) = owner.iter().position(|&o| o == NONE) {
        let (x, y) = (at as u32 % w, at as u32 / w);
        return Err(Error::Usage(format!(
            "merge: no tile covers pixel ({x}, {y}) of the {w}×{h} image: a tile is missing"
        )));
    }
    Ok(ExrImage {
        tile: Tile {
            bounds: Crop::full(w, h),
            full_width: w,
            full_height: h,
        },
        channels: out,
    })
}

/// The first pixel (by row, then column) no tile covers, found from the tiles' rectangles
/// alone: it lies at column 0 or just right of a tile, and at row 0 or just below one. None
/// when every pixel is covered, or for more tiles than this search is quick for.
fn uncovered(tiles: &[(PathBuf, ExrImage)]) -> Option<(u32, u32)> {
    if tiles.len() > 256 {
        return None;
    }
    let (w, h) = tiles
        .first()
        .map(|(_, t)| (t.tile.full_width, t.tile.full_height))?;
    let bounds: Vec<Crop> = tiles.iter().map(|(_, t)| t.tile.bounds).collect();
    let mut xs: Vec<u32> = bounds
        .iter()
        .map(|b| b.x1)
        .chain([0])
        .filter(|&x| x < w)
        .collect();
    let mut ys: Vec<u32> = bounds
        .iter()
        .map(|b| b.y1)
        .chain([0])
        .filter(|&y| y < h)
        .collect();
    xs.sort_unstable();
    ys.sort_unstable();
    let inside = |b: &Crop, x: u32, y: u32| (b.x0..b.x1).contains(&x) && (b.y0..b.y1).contains(&y);
    ys.iter().find_map(|&y| {
        xs.iter()
            .find(|&&x| !bounds.iter().any(|b| inside(b, x, y)))
            .map(|&x| (x, y))
    })
}
