//! A temporary folder for a test's files, removed when the test ends.

use std::path::PathBuf;

/// A temporary folder (the `TempDir` is public for its path).
pub struct Scratch(pub tempfile::TempDir);

impl Scratch {
    /// A new empty folder.
    pub fn new() -> Self {
        Scratch(tempfile::tempdir().unwrap())
    }

    /// The path of `name` in the folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.path().join(name)
    }

    /// Writes `text` to `name` in the folder; its path.
    pub fn write(&self, name: &str, text: impl AsRef<[u8]>) -> PathBuf {
        let p = self.path(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// An OpenEXR image `name` of `width × height` texels from `f(column, row)`; its path.
    pub fn exr(
        &self,
        name: &str,
        width: u32,
        height: u32,
        f: impl Fn(u32, u32) -> [f32; 3],
    ) -> PathBuf {
        let p = self.path(name);
        let img = image::Rgb32FImage::from_fn(width, height, |x, y| image::Rgb(f(x, y)));
        img.save(&p).unwrap();
        p
    }

    /// An 8-bit RGB PNG image `name` of `width × height` pixels from `f(column, row)`; its
    /// path.
    pub fn png(
        &self,
        name: &str,
        width: u32,
        height: u32,
        f: impl Fn(u32, u32) -> [u8; 3],
    ) -> PathBuf {
        let p = self.path(name);
        let img = image::RgbImage::from_fn(width, height, |x, y| image::Rgb(f(x, y)));
        img.save(&p).unwrap();
        p
    }
}
