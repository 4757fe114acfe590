//! The white furnace's scene, shared by the environment's and the materials' furnace tests.

use lancer::render::RenderScene;

use super::scratch::Scratch;

/// A lone sphere of `material` (flat facets: a convex polyhedron, so no bounce meets it
/// twice) filling the middle of a 32×32 image, under `environment`, path traced at `spp`;
/// written to `furnace.toml` in `dir`.
pub fn furnace(dir: &Scratch, material: &str, environment: &str, spp: u32) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 34.0
width = 32
height = 32

[render]
integrator = "path"
max_bounces = 4
spp = {spp}

[environment]
{environment}

[materials.m]
{material}

[[objects]]
shape = "sphere"
segments = 24
smooth = false
material = "m"
"#
    );
    RenderScene::from_file(&dir.write("furnace.toml", text)).unwrap()
}
