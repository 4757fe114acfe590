//! Opening what a user names to render, a scene file or a mesh, at the image size they ask
//! for: one side alone keeps the scene's aspect ratio, and a scale multiplies the result.

use std::path::Path;

use super::RenderScene;
use crate::camera::ViewChange;
use crate::mesh::FileKind;
use crate::{Error, Result};

/// Overrides of a scene's image size (`lancer render --width/--height/--scale`); the default
/// keeps the scene's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageSize {
    /// Width in pixels; alone, the height follows the scene's aspect ratio.
    pub width: Option<u32>,
    /// Height in pixels; alone, the width follows the scene's aspect ratio.
    pub height: Option<u32>,
    /// A factor on the size (the scene's or the one given), e.g. 0.25 for a preview.
    pub scale: Option<f32>,
}

impl ImageSize {
    /// The size of a scene whose own is `scene` (width, height): never below 1 pixel a side.
    pub fn of(&self, scene: (u32, u32)) -> (u32, u32) {
        let aspect = scene.0 as f64 / scene.1.max(1) as f64;
        let (w, h) = match (self.width, self.height) {
            (Some(w), Some(h)) => (w as f64, h as f64),
            (Some(w), None) => (w as f64, w as f64 / aspect),
            (None, Some(h)) => (h as f64 * aspect, h as f64),
            (None, None) => (scene.0 as f64, scene.1 as f64),
        };
        let scale = self.scale.unwrap_or(1.0) as f64;
        let side = |x: f64| (x * scale).round().clamp(1.0, u32::MAX as f64) as u32;
        (side(w), side(h))
    }
}

/// A mesh's own image size (its default view) when it is rendered as a scene.
const MESH_SIZE: (u32, u32) = (640, 480);

impl RenderScene {
    /// What `lancer render PATH` renders: a scene file (.toml), or a mesh (.obj, .ply,
    /// .gltf, .glb) from its default view at 640×480 ([`RenderScene::from_mesh`]; from a
    /// glTF camera with an aspect ratio, 640 wide at that ratio), at the image size `size`
    /// asks for, seen as `view` changes it. A mesh's default view fits
    /// the final image size, and a new field of view alone keeps it framed.
    pub fn open(path: &Path, size: &ImageSize, view: &ViewChange) -> Result<RenderScene> {
        if size.width == Some(0) || size.height == Some(0) {
            return Err(Error::Usage(
                "the image width and height must be positive".into(),
            ));
        }
        if size.scale.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
            return Err(Error::Usage(
                "the image scale must be a positive finite number".into(),
            ));
        }
        let mesh = FileKind::of(path)? != FileKind::Scene;
        let (mut scene, default_view) = if mesh {
            let (w, h) = size.of(MESH_SIZE);
            let (mut scene, from_file) =
                RenderScene::from_mesh_with_camera(path, w, h, view.camera.as_deref())?;
            // A file's camera with an aspect ratio gives the mesh's own size its shape.
            if let Some(own) = from_file.as_ref().and_then(|c| c.shaped(MESH_SIZE.0)) {
                let camera = &mut scene.camera;
                (camera.width, camera.height) = size.of(own);
            }
            (scene, from_file.is_none())
        } else {
            if let Some(c) = &view.camera {
                return Err(Error::Usage(format!(
                    "--camera {c} picks a camera of a glTF file; a scene file has one [camera]"
                )));
            }
            let mut scene = RenderScene::from_file(path)?;
            let camera = &mut scene.camera;
            (camera.width, camera.height) = size.of((camera.width, camera.height));
            (scene, false)
        };
        view.apply(&mut scene.camera, default_view)
            .map_err(Error::Usage)?;
        // A view given here holds in every frame; only the file's own camera is animated.
        let (look_from, look_at, fov) = (view.look_from, view.look_at, view.fov);
        if look_from.is_some() || look_at.is_some() || fov.is_some() {
            if let Some(pl) = &mut scene.placements {
                pl.stop_camera();
            }
        }
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::ImageSize;

    fn size(width: Option<u32>, height: Option<u32>, scale: Option<f32>) -> ImageSize {
        ImageSize {
            width,
            height,
            scale,
        }
    }

    #[test]
    fn one_side_keeps_the_aspect_ratio_and_scale_multiplies() {
        assert_eq!(size(Some(320), None, None).of((640, 480)), (320, 240));
        assert_eq!(size(None, Some(96), None).of((640, 480)), (128, 96));
        assert_eq!(size(Some(100), Some(100), None).of((640, 480)), (100, 100));
        assert_eq!(size(None, None, Some(0.25)).of((256, 192)), (64, 48));
        assert_eq!(size(None, None, Some(1e-9)).of((256, 192)), (1, 1));
    }
}
