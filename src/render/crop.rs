//! Tiles: a render of part of the image (pixel bounds of the full image, half-open, like
//! pbrt's --pixelbounds) with exactly the full image's random numbers, so tiles rendered
//! anywhere join into the full render bit for bit.

use crate::error::{Error, Result};

/// Pixel bounds in the full image: columns x0..x1, rows y0..y1 (half-open).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Crop {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Crop {
    /// The whole of a `width × height` image.
    pub fn full(width: u32, height: u32) -> Crop {
        Crop {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    /// Columns in the tile.
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Rows in the tile.
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// Pixels in the tile.
    pub fn pixels(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// Refuses ([`Error::Usage`]) an empty tile or one reaching outside a `width × height`
    /// image.
    pub fn check(&self, width: u32, height: u32) -> Result<()> {
        let Crop { x0, y0, x1, y1 } = *self;
        if x0 >= x1 || y0 >= y1 {
            return Err(Error::Usage(format!(
                "--crop {x0} {y0} {x1} {y1} is empty: give X0 Y0 X1 Y1 with X0 < X1 and Y0 < Y1 \
                 (half-open pixel bounds)"
            )));
        }
        if x1 > width || y1 > height {
            return Err(Error::Usage(format!(
                "--crop {x0} {y0} {x1} {y1} reaches outside the {width}×{height} image: X1 must \
                 be at most {width} and Y1 at most {height}"
            )));
        }
        Ok(())
    }

    /// The full image's column and row of the tile's pixel `i` (row-major in the tile).
    pub fn pixel(&self, i: usize) -> (u32, u32) {
        let w = self.width().max(1) as usize;
        (self.x0 + (i % w) as u32, self.y0 + (i / w) as u32)
    }
}

/// Where a tile's pixels sit: its bounds in the full image and the full image's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// The tile's pixel bounds in the full image.
    pub bounds: Crop,
    /// The full image's width.
    pub full_width: u32,
    /// The full image's height.
    pub full_height: u32,
}
