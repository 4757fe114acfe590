//! A scene file's `[environment]` table (or `[render] background`, its shorthand) made
//! into the scene's environment light.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::file::{line_of, SceneFile};
use crate::error::{Error, Result};
use crate::render::environment::Environment;

/// The environment `f` describes (read from the file `path`, whose text is `src`): None
/// where it is black or absent. A map's file is read relative to `dir` and added to
/// `sources`.
pub(super) fn environment_of(
    path: &Path,
    src: &str,
    f: &SceneFile,
    dir: &Path,
    sources: &mut Vec<PathBuf>,
) -> Result<Option<Environment>> {
    let background = Vec3::from(f.render.background);
    let Some(def) = &f.environment else {
        let rln = line_of(src, src.find("[render]").unwrap_or(0));
        if !(background.is_finite() && background.min_element() >= 0.0) {
            return Err(Error::input(
                path,
                Some(rln),
                format!("background must be finite and non-negative, got {background}"),
            ));
        }
        return Ok((background != Vec3::ZERO).then(|| Environment::uniform(background)));
    };
    let ln = line_of(src, def.span().start);
    let bad = |msg: String| Error::input(path, Some(ln), format!("environment: {msg}"));
    if background != Vec3::ZERO {
        return Err(bad(
            "give either [environment] or [render] background, not both (background is \
             [environment] radiance)"
                .into(),
        ));
    }
    let def = def.get_ref();
    let rgb_ok = |c: Vec3| c.is_finite() && c.min_element() >= 0.0;
    if !def.rotate.iter().all(|x| x.is_finite()) {
        return Err(bad("'rotate' must be finite numbers".into()));
    }
    match (&def.radiance, &def.map) {
        (Some(r), None) => {
            if def.scale.is_some() || def.rotate != [0.0; 3] {
                return Err(bad(
                    "'scale' and 'rotate' go with a 'map': a uniform radiance needs neither".into(),
                ));
            }
            let r = Vec3::from(*r);
            if !rgb_ok(r) {
                return Err(bad(format!("radiance must be finite and ≥ 0, got {r}")));
            }
            Ok((r != Vec3::ZERO).then(|| Environment::uniform(r)))
        }
        (None, Some(file)) => {
            let scale = def.scale.unwrap_or(1.0);
            if !(scale.is_finite() && scale >= 0.0) {
                return Err(bad(format!("scale must be finite and ≥ 0, got {scale}")));
            }
            let map_path = dir.join(file);
            sources.push(map_path.clone());
            Environment::from_map_file(&map_path, scale, def.rotate)
        }
        _ => Err(bad(
            "give 'radiance = [r, g, b]' (uniform) or 'map = \"FILE.exr\"' (.exr or .hdr)".into(),
        )),
    }
}
