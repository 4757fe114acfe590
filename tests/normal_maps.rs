//! Tangent-space normal maps: a constant map tilts a lit quad's shading exactly as the
//! frame of its texture coordinates says (turning the coordinates turns the tilt), on the
//! CPU and the GPU; the effect is compiled in only where a material has a map; a mirrored
//! copy keeps its bumps the right way out (placed = flattened); bad keys are refused.

mod common;

use std::f32::consts::FRAC_1_PI;

use common::alike::assert_alike;
use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::render::{render, EffectSet, RenderOptions, RenderScene};
use lancer::Device;

/// A 2 × 2 quad in the XZ plane facing +Y, with texture coordinates `uv(x, z)` at its
/// corners.
fn quad_obj(dir: &Scratch, name: &str, uv: impl Fn(f32, f32) -> (f32, f32)) {
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut text = String::new();
    for (x, z) in corners {
        text += &format!("v {x} 0 {z}\n");
    }
    for (x, z) in corners {
        let (u, v) = uv(x, z);
        text += &format!("vt {u} {v}\n");
    }
    text += "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\n";
    dir.write(name, text);
}

/// [`quad_obj`] with the normal +Y at every corner (shading normals).
fn smooth_quad_obj(dir: &Scratch, name: &str, uv: impl Fn(f32, f32) -> (f32, f32)) {
    quad_obj(dir, name, uv);
    let text = std::fs::read_to_string(dir.path(name)).unwrap();
    let text = text.replace(
        "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\n",
        "vn 0 1 0\nf 1/1/1 3/3/1 2/2/1\nf 1/1/1 4/4/1 3/3/1\n",
    );
    dir.write(name, text);
}

/// The quad `mesh` seen from above, of a white diffuse material with the normal map
/// `map`, lit by a directional light arriving from `from` (unit), direct light only.
fn lit_quad(dir: &Scratch, mesh: &str, map: &str, from: Vec3) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 3.0, 0.3]
look_at = [0.0, 0.0, 0.0]
fov = 20.0
width = 16
height = 16

[render]
integrator = "direct"
spp = 1

[materials.bumpy]
type = "diffuse"
albedo = [1.0, 1.0, 1.0]
normal_texture = "{map}"

[[objects]]
mesh = "{mesh}"
material = "bumpy"

[[lights]]
type = "directional"
direction = [{}, {}, {}]
intensity = 2.0
"#,
        -from.x, -from.y, -from.z
    );
    RenderScene::from_file(&dir.write("quad.toml", text)).unwrap()
}

/// A texel's tangent-space normal as the renderer reads it: 8 bits, linear, ×2 − 1.
fn decoded(texel: [u8; 3]) -> Vec3 {
    Vec3::from(texel.map(|c| c as f32 / 255.0)) * 2.0 - Vec3::ONE
}

/// Asserts that every pixel of `scene` (a [`lit_quad`]) shows the radiance of the map's
/// normal `c` in the frame (t, b, +Y) lit from `light`, on the CPU and the GPU.
fn assert_lit_in_frame(what: &str, scene: &RenderScene, [t, b]: [Vec3; 2], c: Vec3, light: Vec3) {
    let fx = EffectSet::of(scene);
    assert!(fx.normal_maps && fx.shading_normals, "{what}: {fx}");
    let n = (t * c.x + b * c.y + Vec3::Y * c.z).normalize();
    let want = 2.0 * FRAC_1_PI * n.dot(light);
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        let px = render(scene, device, &RenderOptions::default())
            .unwrap()
            .image
            .pixels;
        let worst = (px.iter())
            .map(|p| ((p.x - want) / want).abs())
            .fold(0.0, f32::max);
        println!(
            "{what} ({name}): want {want:.5}, got {:.5}, worst {worst:.1e}",
            px[0].x
        );
        assert!(worst < 1e-4, "{what} ({name}): {} vs {want}", px[0].x);
    }
}

/// [`quad_obj`]'s quad with the plain coordinates (u along +x, v along −z), the normal +Y,
/// and the `TANGENT` `tangent` at every corner where given, as a glTF file.
fn quad_gltf(dir: &Scratch, name: &str, tangent: Option<[f32; 4]>) {
    let corners = [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut bin: Vec<u8> = Vec::new();
    let mut put = |xs: &[f32]| bin.extend(xs.iter().flat_map(|x| x.to_le_bytes()));
    for (x, z) in corners {
        put(&[x, 0.0, z]);
    }
    for _ in corners {
        put(&[0.0, 1.0, 0.0]);
    }
    // glTF's v runs down: 1 − the OBJ's.
    for (x, z) in corners {
        put(&[(x + 1.0) / 2.0, (1.0 + z) / 2.0]);
    }
    for _ in corners {
        put(&tangent.unwrap_or_default());
    }
    bin.extend([0u16, 2, 1, 0, 3, 2].iter().flat_map(|i| i.to_le_bytes()));
    let view = |offset: usize, length: usize| serde_json::json!({ "buffer": 0, "byteOffset": offset, "byteLength": length });
    let accessor = |view: usize, kind: &str, extra: serde_json::Value| {
        let mut a = serde_json::json!({ "bufferView": view, "componentType": 5126, "count": 4,
                                        "type": kind });
        a.as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        a
    };
    let mut attributes = serde_json::json!({ "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2 });
    if tangent.is_some() {
        attributes["TANGENT"] = 3.into();
    }
    let doc = serde_json::json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": attributes, "indices": 4 }] }],
        "buffers": [{ "byteLength": bin.len(), "uri": format!("data:application/octet-stream;base64,{}",
            base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &bin)) }],
        "bufferViews": [view(0, 48), view(48, 48), view(96, 32), view(128, 64), view(192, 12)],
        "accessors": [
            accessor(0, "VEC3", serde_json::json!({ "min": [-1, 0, -1], "max": [1, 0, 1] })),
            accessor(1, "VEC3", serde_json::json!({})),
            accessor(2, "VEC2", serde_json::json!({})),
            accessor(3, "VEC4", serde_json::json!({})),
            { "bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR" },
        ],
    });
    dir.write(name, serde_json::to_string(&doc).unwrap());
}

#[test]
fn a_gltf_tangent_attribute_sets_the_frame() {
    let dir = Scratch::new();
    let texel = [191, 128, 238];
    dir.png("tilt.png", 4, 4, |_, _| texel);
    let light = Vec3::new(1.0, 1.0, -0.5).normalize();
    // Without TANGENT: the coordinates' frame (t = +x, b = −z). With TANGENT (0, 0, −1, 1):
    // t = −z, b = n × t = −x, the frame the turned coordinates give above.
    quad_gltf(&dir, "own.gltf", None);
    quad_gltf(&dir, "given.gltf", Some([0.0, 0.0, -1.0, 1.0]));
    for (mesh, frame) in [
        ("own.gltf", [Vec3::X, -Vec3::Z]),
        ("given.gltf", [-Vec3::Z, -Vec3::X]),
    ] {
        let scene = lit_quad(&dir, mesh, "tilt.png", light);
        assert_lit_in_frame(mesh, &scene, frame, decoded(texel), light);
    }
}

#[test]
fn tangents_run_on_smoothly_across_a_smooth_spheres_edges() {
    let dir = Scratch::new();
    dir.png("tilt.png", 4, 4, |_, _| [191, 128, 238]);
    let text = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
width = 8
height = 8

[materials.bumpy]
type = "diffuse"
albedo = [1.0, 1.0, 1.0]
normal_texture = "tilt.png"

[[objects]]
shape = "sphere"
segments = 16
material = "bumpy"
"#;
    let scene = RenderScene::from_file(&dir.write("sphere.toml", text)).unwrap();
    // Every edge two triangles share with the same texture coordinates at both ends (off
    // the seam): the tangent at its midpoint, from either side.
    let key = |p: Vec3, uv: glam::Vec2| [p.x, p.y, p.z, uv.x, uv.y].map(|c| (c + 0.0).to_bits());
    let mut edges: std::collections::HashMap<_, Vec<(u32, [usize; 2])>> = Default::default();
    for prim in 0..scene.mesh.len() as u32 {
        let tri = scene.triangle(prim);
        let uv = scene.uvs[tri.shade];
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (a, b) = (key(tri.v[i], uv[i]), key(tri.v[j], uv[j]));
            let ends = if a < b { (a, b) } else { (b, a) };
            edges.entry(ends).or_default().push((prim, [i, j]));
        }
    }
    let at_midpoint = |prim: u32, [i, j]: [usize; 2]| {
        let mut w = [0.0; 3];
        (w[i], w[j]) = (0.5, 0.5);
        let (t, _) = scene
            .tangent(&scene.triangle(prim), w[0], w[1], w[2])
            .unwrap();
        t.normalize()
    };
    // Each face's own tangent, u's direction across it (what every corner had before
    // corners were welded).
    let own = |prim: u32| {
        let (v, uv) = (scene.triangle(prim).v, scene.uvs[prim as usize]);
        let (e1, e2, d1, d2) = (v[1] - v[0], v[2] - v[0], uv[1] - uv[0], uv[2] - uv[0]);
        (e1 * d2.y - e2 * d1.y).normalize()
    };
    let (mut shared, mut worst, mut worst_own) = (0, 1.0f32, 1.0f32);
    for sides in edges.values().filter(|s| s.len() == 2) {
        let (a, b) = (
            at_midpoint(sides[0].0, sides[0].1),
            at_midpoint(sides[1].0, sides[1].1),
        );
        worst = worst.min(a.dot(b));
        worst_own = worst_own.min(own(sides[0].0).dot(own(sides[1].0)));
        shared += 1;
    }
    println!(
        "{shared} shared edges, least cos between sides {worst} (each face's own: {worst_own})"
    );
    assert!(shared > 250, "{shared}");
    assert!(worst > 0.99999, "{worst}");
    // The test can fail: unwelded, the faces' tangents turn across the edges.
    assert!(worst_own < 0.99, "{worst_own}");
}

#[test]
fn a_constant_map_tilts_the_shading_along_the_texture_frame() {
    let dir = Scratch::new();
    // Tilted 30° toward +u: (sin 30°, 0, cos 30°) in 8 bits.
    let texel = [191, 128, 238];
    dir.png("tilt.png", 4, 4, |_, _| texel);
    dir.png("flat.png", 4, 4, |_, _| [128, 128, 255]);
    let c = decoded(texel);
    // u along +x and v along −z; then u along −z and v along −x (turned 90°).
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    quad_obj(&dir, "turned.obj", |x, z| {
        ((1.0 - z) / 2.0, (1.0 - x) / 2.0)
    });
    let light = Vec3::new(1.0, 1.0, -0.5).normalize();
    for (mesh, t, b) in [
        ("plain.obj", Vec3::X, -Vec3::Z),
        ("turned.obj", -Vec3::Z, -Vec3::X),
    ] {
        let scene = lit_quad(&dir, mesh, "tilt.png", light);
        assert_lit_in_frame(mesh, &scene, [t, b], c, light);
    }
    // The test can fail: the two frames tilt the normal different ways, and a flat map
    // (128, 128, 255) leaves it almost upright.
    let a = render(
        &lit_quad(&dir, "plain.obj", "tilt.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let b = render(
        &lit_quad(&dir, "turned.obj", "tilt.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let f = render(
        &lit_quad(&dir, "plain.obj", "flat.png", light),
        &Device::cpu(),
        &RenderOptions::default(),
    )
    .unwrap();
    let (a, b, f) = (
        a.image.pixels[0].x,
        b.image.pixels[0].x,
        f.image.pixels[0].x,
    );
    let upright = 2.0 * FRAC_1_PI * light.y;
    println!("tilted toward +x {a:.4}, toward −z {b:.4}, flat {f:.4}, unmapped {upright:.4}");
    assert!((a - b).abs() > 0.05 && (f - upright).abs() < 0.01 * upright);
}

#[test]
fn normal_maps_are_an_effect_only_where_a_material_has_one() {
    let dir = Scratch::new();
    dir.png("tilt.png", 4, 4, |_, _| [191, 128, 238]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let light = Vec3::new(1.0, 1.0, 0.0).normalize();
    let scene = lit_quad(&dir, "plain.obj", "tilt.png", light);
    let mut without = EffectSet::of(&scene);
    assert!(without.normal_maps);
    without.normal_maps = false;
    let options = RenderOptions {
        effects: Some(without),
        ..RenderOptions::default()
    };
    let on = render(&scene, &Device::cpu(), &RenderOptions::default()).unwrap();
    let off = render(&scene, &Device::cpu(), &options).unwrap();
    assert!(
        (on.image.pixels[0] - off.image.pixels[0])
            .abs()
            .max_element()
            > 0.05
    );
    // Without a map, no tangents and no effect.
    let text = std::fs::read_to_string(dir.path("quad.toml")).unwrap();
    let text = text.replace("normal_texture = \"tilt.png\"\n", "");
    let bare = RenderScene::from_file(&dir.write("bare.toml", text)).unwrap();
    assert!(bare.tangents.is_empty());
    assert!(!EffectSet::of(&bare).normal_maps && !EffectSet::of(&bare).shading_normals);
}

#[test]
fn a_mirrored_copy_keeps_its_bumps_the_right_way_out() {
    let dir = Scratch::new();
    // Bumps in every direction.
    dir.png("bumps.png", 8, 8, |x, y| {
        [(60 + 20 * x) as u8, (200 - 18 * y) as u8, 220]
    });
    quad_obj(&dir, "flat.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    smooth_quad_obj(&dir, "smooth.obj", |x, z| {
        ((x + 1.0) / 2.0, (1.0 - z) / 2.0)
    });
    let text = r#"
[camera]
position = [0.0, 3.0, 2.0]
look_at = [0.0, 0.0, 0.0]
fov = 50.0
width = 40
height = 24

[render]
integrator = "direct"
spp = 2

[materials.bumpy]
type = "principled"
base_color = [0.8, 0.8, 0.8]
roughness = 0.4
normal_texture = "bumps.png"
normal_scale = 0.8

[[objects]]
mesh = "MESH"
material = "bumpy"

[[objects.copies]]
translate = [-1.2, 0.0, 0.0]

[[objects.copies]]
scale = [-1.0, 1.0, 1.0]
translate = [1.2, 0.0, 0.0]

[[lights]]
type = "point"
position = [1.0, 2.0, 1.0]
intensity = 3.0
"#;
    // The sphere's tangents differ at every vertex: a kernel reading another triangle's
    // corners would show.
    for mesh in ["flat.obj", "smooth.obj", "sphere"] {
        let t = match mesh {
            "sphere" => text.replace("mesh = \"MESH\"", "shape = \"sphere\""),
            _ => text.replace("MESH", mesh),
        };
        let placed = RenderScene::from_file(&dir.write("copies.toml", t)).unwrap();
        assert!(placed.placements.is_some());
        let flat = placed.clone().flattened().unwrap();
        let options = RenderOptions::default();
        let a = render(&placed, &Device::cpu(), &options)
            .unwrap()
            .image
            .pixels;
        let b = render(&flat, &Device::cpu(), &options)
            .unwrap()
            .image
            .pixels;
        let g = render(&placed, gpu_device(), &options)
            .unwrap()
            .image
            .pixels;
        let lit = a.iter().filter(|c| c.max_element() > 0.02).count();
        assert!(lit > 300, "{mesh}: {lit} pixels lit");
        // The flattened scene's tangents are moved by the copy's map and packed again, the
        // placed scene's moved as it shades; the mirror turns the winding, and the
        // interpolated normal's side against it decides the handedness.
        assert_alike(&format!("{mesh}, placed vs flattened"), &a, &b);
        assert_alike(&format!("{mesh}, CPU vs GPU"), &a, &g);
    }
}

#[test]
fn normal_map_keys_are_checked() {
    let dir = Scratch::new();
    dir.png("tilt.png", 2, 2, |_, _| [128, 128, 255]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let _ = lit_quad(&dir, "plain.obj", "tilt.png", Vec3::Y);
    let text = std::fs::read_to_string(dir.path("quad.toml")).unwrap();
    for (from, to, want) in [
        (
            "type = \"diffuse\"",
            "type = \"mirror\"",
            "'normal_texture' applies to diffuse and principled",
        ),
        (
            "normal_texture = \"tilt.png\"",
            "normal_texture = \"gone.png\"",
            "gone.png",
        ),
        (
            "albedo = [1.0, 1.0, 1.0]",
            "albedo = [1.0, 1.0, 1.0]\nnormal_scale = nan",
            "normal_scale must be finite",
        ),
    ] {
        let t = text.replace(from, to);
        let e = RenderScene::from_file(&dir.write("bad.toml", t))
            .unwrap_err()
            .to_string();
        println!("{e}");
        assert!(e.contains(want) && e.contains("bad.toml:"), "{to}: {e}");
    }
}

#[test]
fn a_map_that_leans_below_the_surface_falls_back_to_the_untilted_normal() {
    let dir = Scratch::new();
    // (1, 0, −0.5): under the surface seen from its front; (0.6, 0, 0.8): above it.
    dir.png("under.png", 4, 4, |_, _| [255, 128, 64]);
    dir.png("above.png", 4, 4, |_, _| [204, 128, 230]);
    quad_obj(&dir, "plain.obj", |x, z| ((x + 1.0) / 2.0, (1.0 - z) / 2.0));
    let options = RenderOptions {
        aovs: true,
        ..RenderOptions::default()
    };
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        let under = lit_quad(&dir, "plain.obj", "under.png", Vec3::Y);
        let r = render(&under, device, &options).unwrap();
        let normals = r.aovs.unwrap().normal;
        assert!(
            normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-6),
            "{name}: {:?}",
            normals[0]
        );
        // A tilt above the surface is kept (the test can fail).
        let above = lit_quad(&dir, "plain.obj", "above.png", Vec3::Y);
        let n = render(&above, device, &options)
            .unwrap()
            .aovs
            .unwrap()
            .normal[0];
        println!("{name}: under → {}, above → {n}", normals[0]);
        assert!(n.x > 0.5 && n.y > 0.5, "{name}: {n}");
    }
}
