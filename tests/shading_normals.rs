//! Shading normals: read from OBJ `vn` and glTF `NORMAL` (and a sphere's own), moved with
//! their objects, interpolated across triangles on the CPU and the GPU alike; a smooth
//! sphere shades as Lambert's law predicts for the round sphere where the flat one does
//! not; light never reaches a surface through its geometric side; the effect is compiled
//! in only where a scene has normals.

mod common;

use std::path::PathBuf;

use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::geometry::{unpack_unit, NO_NORMAL};
use lancer::render::{render, EffectSet, RenderOptions, RenderScene};
use lancer::Device;

fn image(scene: &RenderScene, device: &Device) -> Vec<Vec3> {
    render(scene, device, &RenderOptions::default())
        .unwrap()
        .image
        .pixels
}

/// A lone sphere of 16 segments, albedo 0.8, under a directional light of irradiance 2,
/// direct light only, on black.
fn sphere_scene(dir: &Scratch, smooth: bool) -> RenderScene {
    let text = format!(
        r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 34.0
width = 48
height = 48

[render]
integrator = "direct"
spp = 16
background = [0.0, 0.0, 0.0]

[materials.white]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[[objects]]
shape = "sphere"
segments = 16
smooth = {smooth}
material = "white"

[[lights]]
type = "directional"
direction = [-0.5, -0.4, -0.6]
intensity = 2.0
"#
    );
    RenderScene::from_file(&dir.write(&format!("sphere-{smooth}.toml"), text)).unwrap()
}

#[test]
fn a_smooth_sphere_shades_as_lambert_predicts_for_the_round_one_and_a_flat_one_does_not() {
    let dir = Scratch::new();
    let light = -Vec3::new(-0.5, -0.4, -0.6).normalize();
    let expected_of = |scene: &RenderScene| -> Vec<Option<f32>> {
        // The round unit sphere's radiance at each pixel centre, where the pixel lies well
        // inside the silhouette and away from the terminator.
        let f = scene.camera.frame();
        let mut out = Vec::new();
        for y in 0..scene.camera.height {
            for x in 0..scene.camera.width {
                let r = f.ray(x, y, 0.5, 0.5);
                let b = r.origin.dot(r.dir);
                let disc = b * b - (r.origin.length_squared() - 1.0);
                let want = (disc > 0.0).then(|| {
                    let n = (r.origin + r.dir * (-b - disc.sqrt())).normalize();
                    (n, n.dot(-r.dir))
                });
                out.push(match want {
                    Some((n, facing)) if facing > 0.5 && n.dot(light) > 0.25 => {
                        Some(0.8 * std::f32::consts::FRAC_1_PI * 2.0 * n.dot(light))
                    }
                    _ => None,
                });
            }
        }
        out
    };
    let smooth = sphere_scene(&dir, true);
    let flat = sphere_scene(&dir, false);
    assert!(EffectSet::of(&smooth).shading_normals);
    assert!(!EffectSet::of(&flat).shading_normals);
    let expected = expected_of(&smooth);
    let compared = expected.iter().flatten().count();
    assert!(compared > 300, "{compared} pixels compared");
    let error = |img: &[Vec3]| {
        let sum: f64 = (img.iter().zip(&expected))
            .filter_map(|(got, want)| want.map(|w| ((got.x - w).abs() / w) as f64))
            .sum();
        sum / compared as f64
    };
    let cpu_smooth = image(&smooth, &Device::cpu());
    let cpu_flat = image(&flat, &Device::cpu());
    let gpu_smooth = image(&smooth, gpu_device());
    let (e_smooth, e_flat, e_gpu) = (error(&cpu_smooth), error(&cpu_flat), error(&gpu_smooth));
    println!("mean relative error against the round sphere: smooth {e_smooth:.4} (GPU {e_gpu:.4}), flat {e_flat:.4}");
    assert!(e_smooth < 0.03, "smooth: {e_smooth}");
    assert!(e_gpu < 0.03, "smooth on the GPU: {e_gpu}");
    assert!(
        e_flat > 4.0 * e_smooth,
        "flat {e_flat} vs smooth {e_smooth}"
    );
    let same = cpu_smooth
        .iter()
        .zip(&gpu_smooth)
        .filter(|(a, b)| a == b)
        .count();
    assert!(
        same * 10 >= cpu_smooth.len() * 9,
        "{same} of {} pixels equal",
        cpu_smooth.len()
    );
}

#[test]
fn light_never_reaches_a_surface_through_its_geometric_side() {
    // A quad facing +Z (the camera's side) whose vertex normals lean far down: lit from
    // behind, from below, its shading normal faces the light though its surface does not.
    let dir = Scratch::new();
    let ns = Vec3::new(0.0, -1.0, 0.05);
    let travel = Vec3::new(0.0, 0.3, 1.0);
    assert!(ns.dot(-travel) > 0.0, "the shading normal sees the light");
    assert!(Vec3::Z.dot(-travel) < 0.0, "the surface does not");
    let obj = dir.write(
        "leaning.obj",
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 -1 0.05\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n",
    );
    let text = format!(
        r#"
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
width = 16
height = 16

[render]
integrator = "path"
max_bounces = 2
spp = 4
background = [0.0, 0.0, 0.0]

[[objects]]
mesh = "{}"

[[lights]]
type = "directional"
direction = [0.0, 0.3, 1.0]
intensity = 3.0

[[lights]]
type = "point"
position = [0.0, -0.5, -1.0]
intensity = 3.0
"#,
        obj.file_name().unwrap().to_string_lossy()
    );
    let scene = RenderScene::from_file(&dir.write("leaning.toml", text)).unwrap();
    assert!(EffectSet::of(&scene).shading_normals);
    for (name, device) in [("cpu", &Device::cpu()), ("gpu", gpu_device())] {
        let img = image(&scene, device);
        let brightest = img.iter().map(|c| c.max_element()).fold(0.0, f32::max);
        assert_eq!(brightest, 0.0, "on the {name}");
    }
    // Lit from the front, the same quad shows: the test sees light where it arrives.
    let front = std::fs::read_to_string(dir.0.path().join("leaning.toml"))
        .unwrap()
        .replace(
            "direction = [0.0, 0.3, 1.0]",
            "direction = [0.0, 0.3, -1.0]",
        );
    let scene = RenderScene::from_file(&dir.write("front.toml", front)).unwrap();
    let img = image(&scene, &Device::cpu());
    assert!(img.iter().any(|c| c.max_element() > 0.01));
}

/// The scene's normals of triangle `i`, unpacked and normalised.
fn normals_of(scene: &RenderScene, i: usize) -> [Vec3; 3] {
    assert_ne!(scene.normals[i][0], NO_NORMAL, "triangle {i} has normals");
    scene.normals[i].map(|w| unpack_unit(w).normalize())
}

fn close(a: Vec3, b: Vec3) -> bool {
    a.dot(b.normalize()) > 0.99999
}

#[test]
fn obj_and_gltf_normals_are_read_and_move_with_their_objects() {
    let dir = Scratch::new();
    // Bulk reader (plain OBJ) and tobj's (with a material library).
    let plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 1 0 1\nvn 0 1 1\nf 1//1 2//2 3//3\n";
    let with_mtl = format!("mtllib m.mtl\nusemtl red\n{plain}");
    dir.write("m.mtl", "newmtl red\nKd 0.8 0.1 0.1\n");
    let a = dir.write("plain.obj", plain);
    let b = dir.write("mtl.obj", with_mtl);
    let want = [Vec3::Z, Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
    for p in [&a, &b] {
        let s = RenderScene::from_mesh(p, 8, 8).unwrap();
        let got = normals_of(&s, 0);
        for k in 0..3 {
            assert!(close(got[k], want[k]), "{}: {got:?}", p.display());
        }
    }
    // Scaled by 2 along x in a scene, a normal (1, 0, 1) leans to (1, 0, 2).
    let scene = |name: &str, extra: &str| {
        let text = format!(
            "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
             [[objects]]\nmesh = \"plain.obj\"\nscale = [2.0, 1.0, 1.0]\n{extra}\n"
        );
        RenderScene::from_file(&dir.write(name, text))
    };
    let s = scene("scaled.toml", "").unwrap();
    assert!(close(normals_of(&s, 0)[1], Vec3::new(1.0, 0.0, 2.0)));
    let s = scene("flat.toml", "smooth = false").unwrap();
    assert!(s.normals.is_empty());
    assert!(!EffectSet::of(&s).shading_normals);
    // 'smooth' on a flat shape is a mistake, named.
    let e = RenderScene::from_file(&dir.write(
        "box.toml",
        "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
         [[objects]]\nshape = \"box\"\nsmooth = true\n",
    ))
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("'smooth' applies to spheres and meshes"),
        "{e}"
    );

    // glTF: a NORMAL accessor after the positions and indices.
    let gltf = gltf_with_normals(&dir);
    let s = RenderScene::from_mesh(&gltf, 8, 8).unwrap();
    let got = normals_of(&s, 0);
    for k in 0..3 {
        assert!(close(got[k], want[k]), "glTF: {got:?}");
    }
}

/// A PLY of a quad (one face of four corners) and a triangle, with normals, texture
/// coordinates and colours, ASCII or binary little-endian.
fn ply(binary: bool) -> Vec<u8> {
    let verts: [[f32; 8]; 5] = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0],
        [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5],
    ];
    let faces: [&[u32]; 2] = [&[0, 1, 2, 3], &[1, 4, 2]];
    let format = if binary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property float s\nproperty float t\nproperty uchar red\n\
         element face 2\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    .into_bytes();
    for v in &verts {
        if binary {
            out.extend(v.iter().flat_map(|x| x.to_le_bytes()));
            out.push(200);
        } else {
            let words: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            out.extend(format!("{} 200\n", words.join(" ")).bytes());
        }
    }
    for f in faces {
        if binary {
            out.push(f.len() as u8);
            out.extend(f.iter().flat_map(|i| i.to_le_bytes()));
        } else {
            let words: Vec<String> = f.iter().map(|i| i.to_string()).collect();
            out.extend(format!("{} {}\n", f.len(), words.join(" ")).bytes());
        }
    }
    out
}

#[test]
fn ply_normals_and_texture_coordinates_are_read_by_both_readers_alike() {
    let dir = Scratch::new();
    let scenes: Vec<RenderScene> = [false, true]
        .map(|binary| {
            let p = dir.write(&format!("q{binary}.ply"), ply(binary));
            RenderScene::from_mesh(&p, 8, 8).unwrap()
        })
        .into();
    // The quad's two fan triangles (0 1 2, 0 2 3), then the triangle: the last has a zero
    // normal on a corner and shades flat.
    let (a, b) = (&scenes[0], &scenes[1]);
    assert_eq!(
        a.normals[..3],
        b.normals[..3],
        "ASCII (ply-rs) and binary (bulk) readers"
    );
    assert_eq!(a.uvs[..3], b.uvs[..3]);
    let n = normals_of(a, 1);
    assert!(close(n[0], Vec3::Z) && close(n[1], Vec3::new(0.0, 1.0, 1.0)) && close(n[2], Vec3::Z));
    assert_eq!(a.normals[2], [NO_NORMAL; 3]);
    assert_eq!(
        a.uvs[1],
        [glam::Vec2::ZERO, glam::Vec2::ONE, glam::Vec2::new(0.0, 1.0)]
    );
    assert_eq!(a.uvs[2][1], glam::Vec2::splat(0.5));
    assert!(EffectSet::of(a).shading_normals);
}

/// One triangle with the normals of the OBJ test, as glTF.
fn gltf_with_normals(dir: &Scratch) -> PathBuf {
    let positions: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let normals: [[f32; 3]; 3] = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(positions.iter().flatten().flat_map(|x| x.to_le_bytes()));
    bin.extend(normals.iter().flatten().flat_map(|x| x.to_le_bytes()));
    let doc = serde_json::json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0, "NORMAL": 1 } }] }],
        "buffers": [{ "byteLength": bin.len(), "uri": "n.bin" }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 36 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] },
            { "bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3" }
        ]
    });
    dir.write("n.bin", &bin);
    dir.write("n.gltf", serde_json::to_vec(&doc).unwrap())
}

#[test]
fn smooth_copies_render_as_their_flattened_scene_on_both_devices() {
    let dir = Scratch::new();
    let text = r#"
[camera]
position = [0.0, 1.0, 6.0]
look_at = [0.0, 0.0, 0.0]
width = 40
height = 30

[render]
integrator = "path"
max_bounces = 2
spp = 8

[materials.glass]
type = "glass"

[materials.mirror]
type = "mirror"

[[objects]]
shape = "quad"
scale = 8.0
translate = [0.0, -1.0, 0.0]

[[objects]]
shape = "sphere"
segments = 12
material = "glass"
scale = [1.0, 0.6, 0.8]
[[objects.copies]]
translate = [-1.2, 0.0, 0.0]
rotate = [0.0, 30.0, 20.0]
[[objects.copies]]
translate = [1.2, 0.0, 0.0]
scale = [0.7, 1.3, 1.0]

[[objects]]
shape = "sphere"
segments = 12
material = "mirror"
scale = 0.5
translate = [0.0, 0.2, -1.0]

[[lights]]
type = "point"
position = [1.0, 4.0, 3.0]
intensity = 40.0
"#;
    let placed = RenderScene::from_file(&dir.write("copies.toml", text)).unwrap();
    assert!(placed.placements.is_some());
    assert!(EffectSet::of(&placed).shading_normals);
    let flat = placed.clone().flattened().unwrap();
    let cpu = image(&placed, &Device::cpu());
    let gpu = image(&placed, gpu_device());
    let flattened = image(&flat, &Device::cpu());
    let mean = |a: &[Vec3], b: &[Vec3]| {
        let s: f32 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (*x - *y).abs().max_element())
            .sum();
        s / a.len() as f32
    };
    let same = cpu.iter().zip(&gpu).filter(|(a, b)| a == b).count();
    println!(
        "placed CPU vs GPU: {same}/{} equal, mean {:.5}; placed vs flattened: mean {:.5}",
        cpu.len(),
        mean(&cpu, &gpu),
        mean(&cpu, &flattened)
    );
    assert!(same * 10 >= cpu.len() * 9);
    assert!(mean(&cpu, &gpu) < 0.004);
    // The flattened normals are packed again after their map: within a shade, not bits.
    assert!(mean(&cpu, &flattened) < 0.01);
}
