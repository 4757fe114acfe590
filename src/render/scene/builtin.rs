//! Scenes built into the library, so that a command needing a scene works from any folder:
//! the Cornell box of `scenes/` (its TOML, OBJ and MTL files, compiled in).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use super::RenderScene;
use crate::error::{Error, Result};

/// The shipped Cornell box's files, by name.
const CORNELL: [(&str, &str); 3] = [
    ("cornell.toml", include_str!("../../../scenes/cornell.toml")),
    (
        "cornell-box.obj",
        include_str!("../../../scenes/cornell-box.obj"),
    ),
    (
        "cornell-box.mtl",
        include_str!("../../../scenes/cornell-box.mtl"),
    ),
];

/// The name the built-in Cornell box goes by in messages and reports.
pub const CORNELL_NAME: &str = "the built-in Cornell box (scenes/cornell.toml)";

/// The Cornell box of `scenes/cornell.toml`, whatever the working folder. Its files are
/// written to a fresh folder under the system's temporary folder, read the way every
/// scene is read, and removed.
pub fn cornell_box() -> Result<RenderScene> {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "lancer-builtin-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    let written = write_files(&dir);
    let scene = written.and_then(|()| RenderScene::from_file(&dir.join(CORNELL[0].0)));
    let _ = std::fs::remove_dir_all(&dir);
    let mut scene = scene?;
    // Its files are gone: nothing of it is an input an output could overwrite.
    scene.mesh.sources.clear();
    Ok(scene)
}

fn write_files(dir: &Path) -> Result<()> {
    std::fs::create_dir(dir).map_err(|e| Error::io(dir, e))?;
    for (name, text) in CORNELL {
        let path: PathBuf = dir.join(name);
        std::fs::write(&path, text).map_err(|e| Error::io(&path, e))?;
    }
    Ok(())
}
