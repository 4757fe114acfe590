use std::path::Path;

use super::{load_gltf, load_obj, load_ply, FileKind, Mesh};
use crate::error::{Error, Result};

/// Loads a mesh for tracing, the reader chosen by the file's extension (.obj, .ply, .gltf,
/// .glb): refuses a file with no usable triangle, and logs a warning counting what was left
/// out of the BVH. A scene (.toml) is refused here: it is assembled by the renderer's scene
/// module.
pub fn load_mesh(path: &Path) -> Result<Mesh> {
    let start = std::time::Instant::now();
    let mesh = match FileKind::of(path)? {
        FileKind::Obj => load_obj(path)?,
        FileKind::Ply => load_ply(path)?,
        FileKind::Gltf => load_gltf(path)?.mesh,
        FileKind::Scene => {
            return Err(Error::input(
                path,
                None,
                "a scene, not a mesh: load it with RenderScene::from_file",
            ))
        }
    };
    check_usable(path, &mesh)?;
    let seconds = start.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    log::info!(
        "{}: {} triangles read and checked in {:.0} ms ({:.0} MB/s)",
        path.display(),
        mesh.len(),
        seconds * 1e3,
        bytes as f64 / 1e6 / seconds.max(1e-9)
    );
    Ok(mesh)
}

/// Logs a warning counting what was left out of the BVH, and refuses a mesh with no
/// usable triangle.
pub fn check_usable(path: &Path, mesh: &Mesh) -> Result<()> {
    warn_exclusions(path, mesh);
    check_traceable(path, mesh)
}

/// Logs one warning naming `path` and counting what was left out of the BVH, if anything.
pub fn warn_exclusions(path: &Path, mesh: &Mesh) {
    if let Some(s) = mesh.exclusion_summary() {
        log::warn!("{}: {s}", path.display());
    }
}

/// Refuses a mesh with no usable triangle, or one too small to trace (see
/// [`MIN_EXTENT`](crate::limits::MIN_EXTENT)).
pub fn check_traceable(path: &Path, mesh: &Mesh) -> Result<()> {
    let usable = mesh.status.contains(&super::TriStatus::Ok);
    if usable {
        check_extent(path, "mesh", mesh.bounds().extent().length())?;
    }
    if !usable {
        return Err(Error::input(
            path,
            None,
            format!(
                "no usable triangle ({} faces read): nothing to trace",
                mesh.len()
            ),
        ));
    }
    Ok(())
}

/// Refuses geometry (`what`: "mesh", "scene") whose bounds are `extent` across (their
/// diagonal) where that is below [`MIN_EXTENT`](crate::limits::MIN_EXTENT).
pub(crate) fn check_extent(path: &Path, what: &str, extent: f32) -> Result<()> {
    if extent < crate::limits::MIN_EXTENT {
        return Err(Error::input(
            path,
            None,
            format!(
                "the {what} is {extent:e} across; lancer traces meshes at least {:e} across \
                 (f32 intersection arithmetic underflows below): scale it up",
                crate::limits::MIN_EXTENT
            ),
        ));
    }
    Ok(())
}
