//! Which reader a file goes to, by its extension: meshes (.obj, .ply, .gltf, .glb) and
//! scenes (.toml). An unknown extension is refused by name rather than guessed at.

use std::path::Path;

use crate::error::{Error, Result};

/// The kinds of file lancer reads as geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// Wavefront OBJ (with MTL materials).
    Obj,
    /// Stanford PLY, ASCII or binary.
    Ply,
    /// glTF 2.0, JSON (`.gltf`) or binary (`.glb`).
    Gltf,
    /// A lancer scene (TOML).
    Scene,
}

/// The extensions lancer reads, for messages.
pub const KNOWN_EXTENSIONS: &str = ".obj, .ply, .gltf, .glb (meshes) and .toml (scenes)";

impl FileKind {
    /// The kind of `path`, from its extension (any case); an unknown or missing extension
    /// is an input error naming it.
    pub fn of(path: &Path) -> Result<FileKind> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Ok(FileKind::Obj),
            Some("ply") => Ok(FileKind::Ply),
            Some("gltf" | "glb") => Ok(FileKind::Gltf),
            Some("toml") => Ok(FileKind::Scene),
            Some(e) => Err(Error::input(
                path,
                None,
                format!("unknown file type '.{e}': lancer reads {KNOWN_EXTENSIONS}"),
            )),
            None => Err(Error::input(
                path,
                None,
                format!("no file extension: lancer reads {KNOWN_EXTENSIONS}"),
            )),
        }
    }
}
