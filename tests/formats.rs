//! Mesh file formats: one mesh written as OBJ, ASCII PLY, binary PLY (both byte orders),
//! glTF (embedded and external buffer) and GLB loads to the same triangles; glTF node
//! transforms are applied (checked against transforms computed here in f64); glTF
//! materials are mapped onto lancer's; the bunny as PLY traces to the same hits as the OBJ;
//! malformed files are errors naming the file, never panics.

mod common;

use std::path::{Path, PathBuf};

use common::writers::{self, Indexed};
use glam::{Vec2, Vec3};
use lancer::mesh::{load_gltf, load_mesh, load_obj, load_ply, Mesh, TriStatus};
use lancer::render::MaterialKind;
use lancer::{Device, Query, RenderScene, Tracer, TracerOptions};
use serde_json::json;

fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("lancer-formats-")
        .tempdir()
        .unwrap()
}

/// An octahedron, a quad (fan-triangulated by every reader) and a zero-area triangle.
fn sample() -> Indexed {
    Indexed {
        verts: vec![
            [1.25, 0.0, 0.0],
            [-1.0, 0.1, 0.0],
            [0.0, 1.5, 0.2],
            [0.0, -1.0, 0.0],
            [0.3, 0.0, 1.0],
            [0.0, 0.0, -0.7],
            [2.0, 2.0, 2.0],
            [3.0, 2.0, 2.0],
            [3.0, 3.0, 2.5],
            [2.0, 3.0, 2.5],
        ],
        faces: vec![
            vec![0, 2, 4],
            vec![2, 1, 4],
            vec![1, 3, 4],
            vec![3, 0, 4],
            vec![2, 0, 5],
            vec![1, 2, 5],
            vec![3, 1, 5],
            vec![0, 3, 5],
            vec![6, 7, 8, 9],
            vec![6, 6, 7],
        ],
    }
}

fn bits(m: &Mesh) -> Vec<[u32; 9]> {
    m.triangles
        .iter()
        .map(|t| {
            let f = [t.v[0], t.v[1], t.v[2]].map(|v| v.to_array());
            let mut b = [0u32; 9];
            for (k, x) in f.iter().flatten().enumerate() {
                b[k] = x.to_bits();
            }
            b
        })
        .collect()
}

/// Writes `sample()` in every format; returns (name, path).
fn every_format(dir: &Path) -> Vec<(&'static str, PathBuf)> {
    let m = sample();
    let bin = writers::gltf_buffer(&m);
    let w = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    std::fs::write(dir.join("mesh data.bin"), &bin).unwrap();
    vec![
        ("OBJ", w("m.obj", writers::obj(&m).as_bytes())),
        ("ASCII PLY", w("ascii.ply", &writers::ply_ascii(&m))),
        (
            "binary PLY (LE)",
            w("le.ply", &writers::ply_binary(&m, false)),
        ),
        (
            "binary PLY (BE)",
            w("be.PLY", &writers::ply_binary(&m, true)),
        ),
        (
            "glTF, embedded buffer",
            w(
                "embedded.gltf",
                &serde_json::to_vec(&writers::gltf_json(&m, Some(writers::data_uri(&bin))))
                    .unwrap(),
            ),
        ),
        (
            "glTF, external buffer",
            w(
                "external.gltf",
                &serde_json::to_vec(&writers::gltf_json(&m, Some("mesh%20data.bin".into())))
                    .unwrap(),
            ),
        ),
        (
            "GLB",
            w(
                "m.glb",
                &writers::glb(&writers::gltf_json(&m, None), Some(&bin)),
            ),
        ),
    ]
}

#[test]
fn every_format_loads_to_the_same_triangles() {
    let dir = scratch();
    let files = every_format(dir.path());
    let reference = load_obj(&files[0].1).unwrap();
    assert_eq!(reference.len(), 11);
    assert_eq!(reference.count(TriStatus::Degenerate), 1);
    for (name, path) in &files {
        let m = load_mesh(path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            bits(&m),
            bits(&reference),
            "{name}: triangles differ from the OBJ's"
        );
        assert_eq!(m.status, reference.status, "{name}: classification differs");
        assert!(m.sources.contains(path), "{name}: sources {:?}", m.sources);
    }
    // The external buffer is a source too (outputs may not overwrite it).
    let ext = load_mesh(&files[5].1).unwrap();
    assert!(ext.sources.contains(&dir.path().join("mesh data.bin")));
}

#[test]
fn unknown_and_missing_extensions_are_refused_by_name() {
    let dir = scratch();
    for name in ["m.stl", "m", "m.obj.bak"] {
        let p = dir.path().join(name);
        std::fs::write(&p, writers::obj(&sample())).unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let msg = e.to_string();
        assert!(msg.starts_with(&p.display().to_string()), "{msg}");
        assert!(msg.contains(".ply") && msg.contains(".glb"), "{msg}");
    }
}

// ---------------------------------------------------------------------------------------------
// glTF node transforms, computed here in f64 from the specification (T · R · S, parents first).

type M4 = [[f64; 4]; 4]; // row-major

fn mul(a: &M4, b: &M4) -> M4 {
    let mut c = [[0.0; 4]; 4];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn trs(t: [f64; 3], q: [f64; 4], s: [f64; 3]) -> M4 {
    let [x, y, z, w] = q;
    let r = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    let mut m = [[0.0; 4]; 4];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = r[i][j] * s[j];
        }
        m[i][3] = t[i];
    }
    m[3][3] = 1.0;
    m
}

fn apply(m: &M4, p: [f32; 3]) -> [f64; 3] {
    let p = p.map(f64::from);
    [0, 1, 2].map(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3])
}

#[test]
fn gltf_node_transforms_are_flattened_into_world_space() {
    let m = sample();
    let bin = writers::gltf_buffer(&m);
    let mut doc = writers::gltf_json(&m, None);
    // 60° about Y (a unit quaternion), a non-uniform scale, a translation.
    let (t0, q0, s0) = (
        [1.0, 2.0, 3.0],
        [0.0, 0.5, 0.0, 0.75f64.sqrt()],
        [2.0, 1.0, 0.5],
    );
    // A general affine child (column-major in the file), with shear.
    let child_rows: M4 = [
        [1.0, 0.5, 0.0, -1.0],
        [0.0, 1.0, 0.0, 0.25],
        [0.25, 0.0, 2.0, 4.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let child_cols: Vec<f64> = (0..16).map(|k| child_rows[k % 4][k / 4]).collect();
    doc["nodes"] = json!([
        { "translation": t0, "rotation": q0, "scale": s0, "children": [1] },
        { "matrix": child_cols, "mesh": 0 },
        { "mesh": 0, "scale": [-1.0, 1.0, 1.0], "translation": [0.0, -5.0, 0.0] },
        { "mesh": 0, "translation": [100.0, 0.0, 0.0] }
    ]);
    doc["scenes"] = json!([{ "nodes": [0, 2] }]);
    let dir = scratch();
    let path = dir.path().join("nodes.glb");
    std::fs::write(&path, writers::glb(&doc, Some(&bin))).unwrap();
    let got = load_gltf(&path).unwrap().mesh;

    let parent = trs(t0, q0, s0);
    let first = mul(&parent, &child_rows);
    let mirror = trs([0.0, -5.0, 0.0], [0.0, 0.0, 0.0, 1.0], [-1.0, 1.0, 1.0]);
    let tris: Vec<[u32; 3]> = m
        .triangle_indices()
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let mut want = Vec::new();
    for t in &tris {
        want.push(t.map(|i| apply(&first, m.verts[i as usize])));
    }
    for t in &tris {
        // A mirroring node reverses the winding to keep the front face (glTF 2.0, 3.7.4).
        want.push([t[0], t[2], t[1]].map(|i| apply(&mirror, m.verts[i as usize])));
    }
    assert_eq!(got.len(), want.len(), "node 3 is in no scene: not drawn");
    for (i, (g, w)) in got.triangles.iter().zip(&want).enumerate() {
        for k in 0..3 {
            for a in 0..3 {
                let (g, w) = (g.v[k][a] as f64, w[k][a]);
                assert!(
                    (g - w).abs() <= 1e-5 * w.abs().max(1.0),
                    "triangle {i} vertex {k} axis {a}: {g} vs {w}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// glTF materials.

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn gltf_materials_map_onto_lancers() {
    // A quad with texture coordinates, drawn once per material (and once with none).
    let pos: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let uv: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.25, 0.75]];
    let idx: [u32; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    bin.extend(uv.iter().flatten().flat_map(|x| x.to_le_bytes()));
    bin.extend(idx.iter().flat_map(|x| x.to_le_bytes()));
    let pixels: [[u8; 3]; 4] = [[255, 0, 0], [0, 128, 0], [0, 0, 64], [200, 200, 200]];
    let img = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(pixels[(y * 2 + x) as usize]));
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let png_uri = format!(
        "data:image/png;base64,{}",
        base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &png)
    );
    let prim = |mat: Option<usize>| {
        let mut p = json!({ "attributes": { "POSITION": 0, "TEXCOORD_0": 1 }, "indices": 2 });
        if let Some(m) = mat {
            p["material"] = json!(m);
        }
        p
    };
    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior",
                           "KHR_materials_emissive_strength"],
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [prim(Some(0)), prim(Some(1)), prim(Some(2)), prim(Some(3)),
                                    prim(Some(4)), prim(None), prim(Some(5))] }],
        "materials": [
            { "name": "paint", "pbrMetallicRoughness": { "baseColorFactor": [0.2, 0.4, 0.6, 1.0],
              "metallicFactor": 0.0 } },
            { "name": "lamp", "emissiveFactor": [1.0, 0.5, 0.25], "doubleSided": true,
              "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 } } },
            { "name": "glass", "pbrMetallicRoughness": { "baseColorFactor": [0.9, 1.0, 0.95, 1.0] },
              "extensions": { "KHR_materials_transmission": { "transmissionFactor": 1.0 },
                              "KHR_materials_ior": { "ior": 1.33 } } },
            { "name": "decal", "pbrMetallicRoughness": { "baseColorFactor": [0.5, 1.0, 1.0, 1.0],
              "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0 } },
            { "name": "chrome", "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.7, 0.6, 1.0],
              "metallicFactor": 1.0, "roughnessFactor": 0.0 } },
            { "name": "helmet", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 },
              "metallicRoughnessTexture": { "index": 0 }, "roughnessFactor": 0.5 },
              "emissiveFactor": [1.0, 1.0, 1.0], "emissiveTexture": { "index": 0 },
              "normalTexture": { "index": 0, "scale": 0.5 } }
        ],
        "textures": [{ "source": 0 }],
        "images": [{ "uri": png_uri }],
        "buffers": [{ "byteLength": bin.len(), "uri": writers::data_uri(&bin) }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 48, "byteLength": 32 },
            { "buffer": 0, "byteOffset": 80, "byteLength": 24 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] },
            { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2" },
            { "bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR" }
        ]
    });
    let dir = scratch();
    let path = dir.path().join("materials.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = RenderScene::from_mesh(&path, 8, 8).unwrap();
    let mat = |prim: usize| &scene.materials[scene.material_of[2 * prim] as usize];
    for p in 0..7 {
        assert_eq!(scene.material_of[2 * p], scene.material_of[2 * p + 1]);
    }
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-6;

    // glTF's metallic-roughness is lancer's principled, with glTF's default roughness 1.
    let paint = mat(0);
    assert_eq!(paint.kind, MaterialKind::Principled);
    assert!(close(paint.albedo, Vec3::new(0.2, 0.4, 0.6)), "{paint:?}");
    assert_eq!((paint.metallic, paint.roughness), (0.0, 1.0));
    assert_eq!(paint.texture, None);

    let lamp = mat(1);
    assert_eq!(lamp.kind, MaterialKind::Emissive);
    assert!(close(lamp.emission, Vec3::new(4.0, 2.0, 1.0)), "{lamp:?}");
    assert!(lamp.two_sided);
    assert!(scene.emitters.contains(&2) && scene.emitters.contains(&3));

    let glass = mat(2);
    assert_eq!(glass.kind, MaterialKind::Glass);
    assert!((glass.ior - 1.33).abs() < 1e-6, "{glass:?}");
    assert!(close(glass.albedo, Vec3::new(0.9, 1.0, 0.95)));

    // The base colour factor multiplies the texture as it is read.
    let decal = mat(3);
    assert_eq!(decal.kind, MaterialKind::Principled);
    assert!(close(decal.albedo, Vec3::new(0.5, 1.0, 1.0)), "{decal:?}");
    let tex = &scene.textures[decal.texture.expect("decal is textured")];
    assert_eq!((tex.width, tex.height), (2, 2));
    for (k, p) in pixels.iter().enumerate() {
        let want = Vec3::new(
            srgb_to_linear(p[0]),
            srgb_to_linear(p[1]),
            srgb_to_linear(p[2]),
        );
        assert!(
            close(tex.texels[k], want),
            "texel {k}: {} vs {want}",
            tex.texels[k]
        );
    }

    // A perfectly smooth metal is a mirror, tinted by its base colour.
    let chrome = mat(4);
    assert_eq!(chrome.kind, MaterialKind::Mirror);
    assert!(close(chrome.albedo, Vec3::new(0.8, 0.7, 0.6)));

    let none = mat(5);
    assert_eq!(none.kind, MaterialKind::Diffuse);
    assert_ne!(scene.material_of[10], scene.material_of[0]);

    // Emission that a texture varies: a principled surface that glows where hit (not an
    // area light); its metallic-roughness texture is data, read without the sRGB curve.
    let helmet = mat(6);
    assert_eq!(helmet.kind, MaterialKind::Principled);
    assert_eq!((helmet.metallic, helmet.roughness), (1.0, 0.5));
    assert_eq!(helmet.emission, Vec3::ONE);
    assert!(!scene.emitters.contains(&12));
    let (base, mr) = (
        helmet.texture.unwrap(),
        helmet.metallic_roughness_texture.unwrap(),
    );
    assert_eq!(
        helmet.emission_texture,
        Some(base),
        "the same image, read once"
    );
    assert_ne!(base, mr);
    // The normal map is data too (the same texture as the metallic-roughness read), with
    // its scale, and gives the material's triangles tangents: u grows along +x across
    // the first triangle, along (1.5, −0.5, 0) across the second (its skewed coordinates);
    // the corners they share (vertices 0 and 2, 45° in each) average the two.
    assert_eq!(
        (helmet.normal_texture, helmet.normal_scale),
        (Some(mr), 0.5)
    );
    let unit = |w: u32| lancer::geometry::unpack_tangent(w).unwrap().0.normalize();
    let shared = (Vec3::X + Vec3::new(1.5, -0.5, 0.0).normalize()).normalize();
    let [t0, t1, t2] = scene.tangents[12].map(unit);
    assert!(t1.abs_diff_eq(Vec3::X, 1e-3), "{t1}");
    assert!(
        t0.abs_diff_eq(shared, 1e-3) && t2.abs_diff_eq(shared, 1e-3),
        "{t0} {t2}"
    );
    assert_eq!(scene.tangents[0], [lancer::geometry::NO_TANGENT; 3]);
    for (k, p) in pixels.iter().enumerate() {
        let want = Vec3::from(p.map(|c| c as f32 / 255.0));
        assert!(close(scene.textures[mr].texels[k], want), "texel {k}");
        assert!(
            close(scene.textures[base].texels[k], tex.texels[k]),
            "texel {k}"
        );
    }

    // glTF's v runs down the image, lancer's up (as in OBJ).
    let flip = |k: usize| Vec2::new(uv[k][0], 1.0 - uv[k][1]);
    assert_eq!(scene.uvs[6], [flip(0), flip(1), flip(2)]);
    assert_eq!(scene.uvs[7], [flip(0), flip(2), flip(3)]);

    // The same file as a scene object: its materials, moved by the object's transform.
    let toml = dir.path().join("scene.toml");
    std::fs::write(
        &toml,
        "[camera]\nposition = [0.5, 0.5, 3.0]\nlook_at = [0.5, 0.5, 0.0]\n\n\
         [[objects]]\nmesh = \"materials.gltf\"\ntranslate = [0.0, 0.0, -1.0]\n",
    )
    .unwrap();
    let s2 = RenderScene::from_file(&toml).unwrap();
    assert_eq!(s2.mesh.len(), 14);
    assert_eq!(s2.mesh.triangles[0].v[1], Vec3::new(1.0, 0.0, -1.0));
    let k = |s: &RenderScene, i: usize| s.materials[s.material_of[i] as usize].kind;
    assert_eq!(k(&s2, 2), MaterialKind::Emissive);
    assert_eq!(k(&s2, 4), MaterialKind::Glass);
}

// ---------------------------------------------------------------------------------------------
// The bunny as PLY.

#[test]
fn bunny_as_binary_ply_traces_to_the_same_hits_as_the_obj() {
    let Some(path) = common::model("stanford-bunny.obj") else {
        return;
    };
    let obj = load_obj(&path).unwrap();
    // Shared vertices, as the Stanford PLY has them.
    let mut index = std::collections::HashMap::new();
    let mut m = Indexed {
        verts: Vec::new(),
        faces: Vec::new(),
    };
    for t in &obj.triangles {
        let f = t.v.map(|v| {
            let key = v.to_array().map(f32::to_bits);
            *index.entry(key).or_insert_with(|| {
                m.verts.push(v.to_array());
                m.verts.len() as u32 - 1
            })
        });
        m.faces.push(f.to_vec());
    }
    assert!(m.verts.len() < obj.len(), "vertices are shared");
    let dir = scratch();
    let ply = dir.path().join("bunny.ply");
    std::fs::write(&ply, writers::ply_binary(&m, false)).unwrap();
    let from_ply = load_ply(&ply).unwrap();
    assert_eq!(bits(&from_ply), bits(&obj));
    assert_eq!(from_ply.status, obj.status);

    let mut rng = common::Rng::new(15);
    let rays = common::random_rays(&mut rng, 4096, &obj);
    let cpu = Device::cpu();
    let trace = |mesh: &Mesh| {
        let mut t = Tracer::new(&cpu, mesh, &TracerOptions::default()).unwrap();
        t.trace(&rays, Query::Closest).unwrap().hits
    };
    let (a, b) = (trace(&obj), trace(&from_ply));
    assert!(
        a.iter()
            .filter(|h| h.prim != lancer::geometry::MISS)
            .count()
            > 100
    );
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(
            (x.prim, x.t.to_bits(), x.u.to_bits(), x.v.to_bits()),
            (y.prim, y.t.to_bits(), y.u.to_bits(), y.v.to_bits()),
            "ray {i}"
        );
    }
}

/// The PLY format name of a binary byte order (big-endian or little-endian).
fn binary_format(big: bool) -> &'static str {
    if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    }
}

/// Appends the bytes of `$x` to `$out` in the byte order `$big` says.
macro_rules! put_bytes {
    ($big:expr, $out:expr, $x:expr) => {
        $out.extend(if $big {
            $x.to_be_bytes()
        } else {
            $x.to_le_bytes()
        })
    };
}

/// The bulk binary reader (every property a scalar, one index list per face) against ply-rs
/// on the same content in ASCII: a leading element to skip, doubles and a byte colour in the
/// vertex record, unsigned 16-bit indices, polygons, a short face and an index past the end;
/// both byte orders. Bit for bit, status for status.
#[test]
fn binary_ply_read_in_bulk_equals_ply_rs_on_the_same_content() {
    let dir = scratch();
    let mut rng = common::Rng::new(17);
    let verts: Vec<[f64; 3]> = (0..50)
        .map(|_| [0; 3].map(|_| (rng.f32() as f64 - 0.5) * 1e3 + rng.f32() as f64 * 1e-9))
        .collect();
    let faces: Vec<Vec<u16>> = (0..200)
        .map(|k| {
            let n = [3, 3, 4, 5, 2][k % 5];
            let bad = k % 37 == 0;
            (0..n)
                .map(|_| {
                    if bad {
                        60
                    } else {
                        (rng.f32() * 50.0) as u16 % 50
                    }
                })
                .collect()
        })
        .collect();
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\ncomment made by a test\nelement camera 2\n\
             property float view\nproperty int id\nelement vertex {}\nproperty double x\n\
             property uchar red\nproperty double y\nproperty double z\nelement face {}\n\
             property list uchar ushort vertex_indices\nend_header\n",
            verts.len(),
            faces.len()
        )
    };
    let mut ascii = head("ascii");
    ascii += "1.5 7\n2.5 8\n";
    for v in &verts {
        ascii += &format!("{:?} 200 {:?} {:?}\n", v[0], v[1], v[2]);
    }
    for f in &faces {
        let list: Vec<String> = f.iter().map(|i| i.to_string()).collect();
        ascii += &format!("{} {}\n", f.len(), list.join(" "));
    }
    let p = dir.path().join("ascii.ply");
    std::fs::write(&p, &ascii).unwrap();
    let want = load_ply(&p).unwrap();
    assert_eq!(want.short_faces, 40);
    assert!(want.status.contains(&TriStatus::OutOfRange));
    for big in [false, true] {
        let format = binary_format(big);
        let mut bin = head(format).into_bytes();
        for (view, id) in [(1.5f32, 7i32), (2.5, 8)] {
            put_bytes!(big, bin, view);
            put_bytes!(big, bin, id);
        }
        for v in &verts {
            put_bytes!(big, bin, v[0]);
            bin.push(200);
            put_bytes!(big, bin, v[1]);
            put_bytes!(big, bin, v[2]);
        }
        for f in &faces {
            bin.push(f.len() as u8);
            for &i in f {
                put_bytes!(big, bin, i);
            }
        }
        let p = dir.path().join(format!("{format}.ply"));
        std::fs::write(&p, &bin).unwrap();
        let got = load_ply(&p).unwrap();
        assert_eq!(bits(&got), bits(&want), "{format}");
        assert_eq!(got.status, want.status, "{format}");
        assert_eq!(got.short_faces, want.short_faces, "{format}");
    }
}

/// The bulk reader's fast paths against ply-rs on the same content in ASCII: every face a
/// triangle (each record placed without a walk) and positions in f32 (read without the
/// types' dispatch; big-endian ones through it), with a colour byte in the vertex record, an
/// index past the last vertex, a degenerate triangle, one too far out, and an element after
/// the faces. Bit for bit, status for status.
#[test]
fn binary_ply_of_triangles_read_in_bulk_equals_ply_rs() {
    let dir = scratch();
    let mut rng = common::Rng::new(29);
    let mut verts: Vec<[f32; 3]> = (0..64)
        .map(|_| [0; 3].map(|_| (rng.f32() - 0.5) * 1e3))
        .collect();
    verts[5] = [1e30, 0.0, 0.0];
    let mut faces: Vec<[i32; 3]> = (0..300)
        .map(|_| [0; 3].map(|_| (rng.f32() * 64.0) as i32 % 64))
        .collect();
    faces[7] = [1, 2, 64];
    faces[8] = [3, 3, 4];
    faces[9] = [5, 6, 7];
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property uchar red\nproperty float z\nelement face {}\n\
             property list uchar int vertex_indices\nelement edge 2\nproperty int vertex1\n\
             property int vertex2\nend_header\n",
            verts.len(),
            faces.len()
        )
    };
    let mut ascii = head("ascii");
    for v in &verts {
        ascii += &format!("{:?} {:?} 9 {:?}\n", v[0], v[1], v[2]);
    }
    for f in &faces {
        ascii += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    ascii += "0 1\n1 2\n";
    let p = dir.path().join("ascii.ply");
    std::fs::write(&p, &ascii).unwrap();
    let want = load_ply(&p).unwrap();
    assert_eq!(want.len(), faces.len());
    for s in [
        TriStatus::OutOfRange,
        TriStatus::Degenerate,
        TriStatus::TooFar,
    ] {
        assert!(want.status.contains(&s), "{s:?}");
    }
    for big in [false, true] {
        let format = binary_format(big);
        let mut bin = head(format).into_bytes();
        for v in &verts {
            put_bytes!(big, bin, v[0]);
            put_bytes!(big, bin, v[1]);
            bin.push(9);
            put_bytes!(big, bin, v[2]);
        }
        for f in &faces {
            bin.push(3);
            for &i in f {
                put_bytes!(big, bin, i);
            }
        }
        for e in [0i32, 1, 1, 2] {
            put_bytes!(big, bin, e);
        }
        let p = dir.path().join(format!("{format}.ply"));
        std::fs::write(&p, &bin).unwrap();
        let got = load_ply(&p).unwrap();
        assert_eq!(bits(&got), bits(&want), "{format}");
        assert_eq!(got.status, want.status, "{format}");
        assert_eq!(got.short_faces, 0, "{format}");
        // Cut short: no longer what the header says, so ply-rs reads it and says so.
        std::fs::write(&p, &bin[..bin.len() - 9]).unwrap();
        assert!(load_ply(&p).is_err(), "{format} cut short");
    }
}

// ---------------------------------------------------------------------------------------------
// What is left out is counted, never dropped.

#[test]
fn ply_faces_that_name_no_vertex_keep_their_place_and_are_counted() {
    let dir = scratch();
    let p = dir.path().join("bad.ply");
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n\
                property double z\nproperty uchar red\nelement face 5\n\
                property list uchar uint vertex_indices\nelement edge 1\nproperty int vertex1\n\
                property int vertex2\nend_header\n\
                0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n\
                3 0 1 2\n3 0 1 9\n2 0 1\n4 0 1 2 3\n3 2 3 4\n0 1\n";
    std::fs::write(&p, text).unwrap();
    let m = load_ply(&p).unwrap();
    assert_eq!(m.len(), 5, "1 + 1 placeholder + 2 (quad) + 1 placeholder");
    assert_eq!(
        m.status,
        [
            TriStatus::Ok,
            TriStatus::OutOfRange,
            TriStatus::Ok,
            TriStatus::Ok,
            TriStatus::OutOfRange
        ]
    );
    assert_eq!(m.short_faces, 1);
    assert_eq!(
        m.triangles[3].v,
        [
            Vec3::ZERO,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0)
        ]
    );
    let summary = m.exclusion_summary().unwrap();
    assert!(summary.contains("2 with out-of-range") && summary.contains("1 faces with fewer"));
}

#[test]
fn gltf_indices_past_the_vertices_keep_their_place_and_are_counted() {
    let mut m = sample();
    m.faces[1] = vec![2, 1, 40];
    let bin = writers::gltf_buffer(&m);
    let dir = scratch();
    let p = dir.path().join("bad.glb");
    std::fs::write(&p, writers::glb(&writers::gltf_json(&m, None), Some(&bin))).unwrap();
    let g = load_gltf(&p).unwrap();
    assert_eq!(g.mesh.len(), 11);
    assert_eq!(g.mesh.status[1], TriStatus::OutOfRange);
    assert_eq!(g.mesh.count(TriStatus::OutOfRange), 1);
}

// ---------------------------------------------------------------------------------------------
// Malformed files: one line naming the file, exit code 2, never a panic.

fn refused(path: &Path, needle: &str) {
    let r = std::panic::catch_unwind(|| load_mesh(path));
    let e = r
        .unwrap_or_else(|_| panic!("{}: the reader panicked", path.display()))
        .expect_err("a malformed file must be refused");
    let msg = e.to_string();
    assert_eq!(e.exit_code(), 2, "{msg}");
    assert!(msg.starts_with(&path.display().to_string()), "{msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");
    assert!(msg.contains(needle), "{msg:?} should say {needle:?}");
}

#[test]
fn gltf_texture_transforms_move_the_base_colour_coordinates() {
    let pos: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let uv: [[f32; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    bin.extend(uv.iter().flatten().flat_map(|x| x.to_le_bytes()));
    let png = {
        let mut v = Vec::new();
        image::RgbImage::new(1, 1)
            .write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)
            .unwrap();
        v
    };
    let transform = json!({ "offset": [0.5, 0.25], "scale": [2.0, 3.0],
                            "rotation": std::f32::consts::FRAC_PI_2 });
    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_texture_transform"],
        "extensionsRequired": ["KHR_texture_transform"],
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0, "TEXCOORD_0": 1 },
                                      "material": 0 }] }],
        "materials": [{ "pbrMetallicRoughness": { "metallicFactor": 0.0, "baseColorTexture":
            { "index": 0, "extensions": { "KHR_texture_transform": transform } } } }],
        "textures": [{ "source": 0 }],
        "images": [{ "uri": writers::data_uri(&png) }],
        "buffers": [{ "byteLength": bin.len(), "uri": writers::data_uri(&bin) }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 24 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] },
            { "bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2" }
        ]
    });
    let dir = scratch();
    let p = dir.path().join("transformed.gltf");
    std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
    let g = lancer::mesh::load_gltf(&p).unwrap();
    // Scaled by (2, 3), turned a quarter (u' = v·3, v' = −u·2), offset by (0.5, 0.25); then
    // v flipped to point up as in OBJ.
    let want = [[0.5, 0.25], [0.5, 0.25 - 2.0], [0.5 + 3.0, 0.25]]
        .map(|[u, v]: [f32; 2]| glam::Vec2::new(u, 1.0 - v));
    for (got, want) in g.uvs[0].iter().zip(want) {
        assert!(
            (*got - want).length() < 1e-5,
            "{:?} against {want:?}",
            g.uvs[0]
        );
    }
}

#[test]
fn gltf_files_requiring_an_unsupported_extension_are_named_as_such() {
    let m = sample();
    let bin = writers::gltf_buffer(&m);
    let dir = scratch();
    for (ext, what) in [
        ("KHR_draco_mesh_compression", "decompress its meshes"),
        ("EXT_meshopt_compression", "decompress its meshes"),
        ("KHR_texture_basisu", "convert its textures to PNG or JPEG"),
        ("EXT_texture_webp", "convert its textures to PNG or JPEG"),
    ] {
        let mut doc = writers::gltf_json(&m, None);
        doc["extensionsUsed"] = json!([ext]);
        doc["extensionsRequired"] = json!([ext]);
        let p = dir.path().join(format!("{ext}.glb"));
        std::fs::write(&p, writers::glb(&doc, Some(&bin))).unwrap();
        refused(
            &p,
            &format!(
                "a glTF 2.0 file that requires an extension lancer does not support: {ext} ({what}"
            ),
        );
        assert!(!load_mesh(&p)
            .unwrap_err()
            .to_string()
            .contains("not a valid"));
    }
    // Used but not required: read without it.
    let mut doc = writers::gltf_json(&m, None);
    doc["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    let p = dir.path().join("optional.glb");
    std::fs::write(&p, writers::glb(&doc, Some(&bin))).unwrap();
    assert!(load_mesh(&p).is_ok());
}

#[test]
fn truncated_binary_files_are_errors() {
    let m = sample();
    let dir = scratch();
    let bin = writers::gltf_buffer(&m);
    let cases = [
        ("le.ply", writers::ply_binary(&m, false)),
        ("be.ply", writers::ply_binary(&m, true)),
        (
            "m.glb",
            writers::glb(&writers::gltf_json(&m, None), Some(&bin)),
        ),
    ];
    for (name, bytes) in &cases {
        let p = dir.path().join(name);
        for cut in 0..bytes.len() {
            // The GLB's binary chunk is zero-padded: cutting padding only still loads.
            if name.ends_with("glb") && cut >= bytes.len() - 3 {
                continue;
            }
            std::fs::write(&p, &bytes[..cut]).unwrap();
            let r = std::panic::catch_unwind(|| load_mesh(&p));
            let r = r.unwrap_or_else(|_| panic!("{name} cut at {cut}: panicked"));
            let e = r.expect_err(&format!("{name} cut at {cut} must be refused"));
            assert!(e.to_string().starts_with(&p.display().to_string()), "{e}");
        }
    }
}

#[test]
fn ascii_ply_cut_anywhere_never_panics() {
    let bytes = writers::ply_ascii(&sample());
    let dir = scratch();
    let p = dir.path().join("a.ply");
    for cut in 0..bytes.len() {
        std::fs::write(&p, &bytes[..cut]).unwrap();
        let r = std::panic::catch_unwind(|| load_ply(&p));
        assert!(r.is_ok(), "cut at {cut}: panicked");
    }
}

#[test]
fn malformed_ply_headers_are_refused_with_the_reason() {
    let dir = scratch();
    let w = |name: &str, text: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let head = "ply\nformat binary_little_endian 1.0\n";
    // A count the bytes cannot hold: refused at the end of the data, not allocated.
    let huge = w(
        "huge.ply",
        format!("{head}element vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 4000000000\nproperty list uchar int vertex_indices\nend_header\n\0\0\0\0")
            .as_bytes(),
    );
    refused(&huge, "PLY parse error");
    let no_z = w(
        "noz.ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n",
    );
    refused(&no_z, "'z'");
    let no_face = w(
        "cloud.ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n",
    );
    refused(&no_face, "no 'face' element");
    // A scan of a billion points (its header; the body cut short) is refused from the
    // header alone, before its points are read.
    let cloud = w(
        "scan.ply",
        format!("{head}element vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nend_header\n\0\0\0\0").as_bytes(),
    );
    refused(&cloud, "scan.ply: no 'face' element");
    let float_idx = w(
        "floatidx.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar float vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    );
    refused(&float_idx, "PLY parse error");
    // What ply-rs read past without a word: a property twice (the columns shifted), a value
    // too many on an ASCII line, a list counted by floats (refused only in binary before).
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let twice = w("twice.ply", ascii.replace("float y", "float x").as_bytes());
    refused(
        &twice,
        "twice.ply:5: the 'vertex' element names property 'x' twice",
    );
    let extra = w(
        "extra.ply",
        format!("{ascii}0 0 0\n1 0 0 5\n0 1 0\n3 0 1 2\n").as_bytes(),
    );
    refused(
        &extra,
        "extra.ply:11: 1 more values than the 'vertex' element",
    );
    for format in ["ascii", "binary_little_endian"] {
        let text = ascii
            .replace("ascii", format)
            .replace("list uchar", "list float");
        let counted = w("floatcount.ply", text.as_bytes());
        refused(
            &counted,
            "floatcount.ply:8: list vertex_indices: its count is a float",
        );
    }
    let garbage = w("garbage.ply", b"solid ascii stl\nfacet normal 0 0 1\n");
    refused(&garbage, "PLY parse error");
    let bad_number = w(
        "badnum.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n",
    );
    refused(&bad_number, "PLY parse error");
}

/// A valid one-mesh glTF document and its buffer, to be broken one way at a time.
fn base_gltf() -> (serde_json::Value, Vec<u8>) {
    let m = sample();
    (writers::gltf_json(&m, None), writers::gltf_buffer(&m))
}

#[test]
fn malformed_gltf_is_refused_with_the_reason() {
    let dir = scratch();
    let case = |name: &str,
                edit: &dyn Fn(&mut serde_json::Value),
                bin_len: Option<usize>,
                needle: &str| {
        let (mut doc, mut bin) = base_gltf();
        edit(&mut doc);
        if let Some(n) = bin_len {
            bin.truncate(n);
        }
        let p = dir.path().join(name);
        std::fs::write(&p, writers::glb(&doc, Some(&bin))).unwrap();
        refused(&p, needle);
    };
    case("short.glb", &|_| {}, Some(40), "truncated");
    case(
        "count.glb",
        &|d| d["accessors"][0]["count"] = json!(1000),
        None,
        "reach past the end of bufferView",
    );
    case(
        "stride.glb",
        &|d| d["bufferViews"][0]["byteStride"] = json!(4),
        None,
        "byteStride",
    );
    case(
        "view.glb",
        &|d| d["bufferViews"][1]["byteLength"] = json!(1 << 30),
        None,
        "reaches past the end of buffer",
    );
    case(
        "cycle.glb",
        &|d| d["nodes"] = json!([{ "mesh": 0, "children": [1] }, { "children": [0] }]),
        None,
        "the nodes 0 → 1 → 0 form a cycle",
    );
    // A cycle the scene does not reach is named too (it was "no usable triangle").
    case(
        "unreached-cycle.glb",
        &|d| d["nodes"] = json!([{ "mesh": 0 }, { "children": [2] }, { "children": [1] }]),
        None,
        "the nodes 1 → 2 → 1 form a cycle",
    );
    case(
        "version-3.glb",
        &|d| d["asset"]["version"] = json!("3.0"),
        None,
        "asset.version \"3.0\"",
    );
    case(
        "position-5.glb",
        &|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(5),
        None,
        "POSITION: index 5, but there are 2 accessors",
    );
    case(
        "image-without-mime.glb",
        &|d| d["images"] = json!([{ "bufferView": 1 }]),
        None,
        "needs a mimeType",
    );
    case(
        "image-empty.glb",
        &|d| d["images"] = json!([{}]),
        None,
        "neither uri nor bufferView",
    );
    // A GLB whose header gives a length other than the file's.
    let (doc, bin) = base_gltf();
    let mut glb = writers::glb(&doc, Some(&bin));
    glb[8..12].copy_from_slice(&12u32.to_le_bytes());
    let p = dir.path().join("glb-length.glb");
    std::fs::write(&p, glb).unwrap();
    refused(&p, "the GLB header gives a length of 12 bytes");
    case(
        "parents.glb",
        &|d| {
            d["nodes"] = json!([{ "children": [2] }, { "children": [2] }, { "mesh": 0 }]);
            d["scenes"] = json!([{ "nodes": [0, 1] }]);
        },
        None,
        "trees",
    );
    case(
        "type.glb",
        &|d| d["accessors"][0]["componentType"] = json!(5123),
        None,
        "lancer reads",
    );
    case(
        "sparse.glb",
        &|d| {
            d["accessors"][0]["sparse"] = json!({ "count": 1,
                "indices": { "bufferView": 1, "componentType": 5125 },
                "values": { "bufferView": 0 } })
        },
        None,
        "sparse",
    );
    case(
        "json.glb",
        &|d| d["meshes"] = json!(7),
        None,
        "not a valid glTF",
    );
    let p = dir.path().join("missing-bin.gltf");
    let (mut doc, _) = base_gltf();
    doc["buffers"][0]["uri"] = json!("nowhere.bin");
    std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
    refused(&p, "nowhere.bin");
    let p = dir.path().join("bad64.gltf");
    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@");
    std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
    refused(&p, "base64");
}

#[test]
fn gltf_strips_and_fans_follow_the_specification_and_points_are_left_out() {
    // Five vertices drawn as a strip, a fan and points, all from one index list.
    let m = Indexed {
        verts: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.25],
            [0.0, 2.0, 0.5],
        ],
        faces: vec![vec![0, 1, 2, 3, 4]],
    };
    let mut bin: Vec<u8> = m
        .verts
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    bin.extend((0u32..5).flat_map(|i| i.to_le_bytes()));
    let mut doc = writers::gltf_json(&m, None);
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    doc["bufferViews"][1]["byteLength"] = json!(20);
    doc["accessors"][1]["count"] = json!(5);
    let prim = |mode: u32| json!({ "attributes": { "POSITION": 0 }, "indices": 1, "mode": mode });
    doc["meshes"] = json!([{ "primitives": [prim(5), prim(6), prim(0)] }]);
    let dir = scratch();
    let p = dir.path().join("strips.glb");
    std::fs::write(&p, writers::glb(&doc, Some(&bin))).unwrap();
    let got = load_gltf(&p).unwrap().mesh;
    // glTF 2.0, 3.7.2.1: strip triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}); fan
    // triangle i is (v_{i+1}, v_{i+2}, v_0). Written out by hand:
    let want: [[usize; 3]; 6] = [
        [0, 1, 2],
        [1, 3, 2],
        [2, 3, 4],
        [1, 2, 0],
        [2, 3, 0],
        [3, 4, 0],
    ];
    assert_eq!(got.len(), want.len());
    for (t, w) in got.triangles.iter().zip(want) {
        assert_eq!(t.v, w.map(|k| Vec3::from(m.verts[k])));
    }
}
