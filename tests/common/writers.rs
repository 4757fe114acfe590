//! Writers of small mesh files for the reader tests, written here from the formats'
//! specifications (not by lancer): OBJ, PLY (ASCII, binary either byte order) and glTF 2.0
//! (`.gltf` with an embedded or external buffer, `.glb`).

use base64::Engine;
use serde_json::{json, Value};

/// An indexed mesh: positions and polygons (index lists).
#[derive(Clone, Debug)]
pub struct Indexed {
    pub verts: Vec<[f32; 3]>,
    pub faces: Vec<Vec<u32>>,
}

impl Indexed {
    /// The polygons fan-triangulated, as glTF needs them.
    pub fn triangle_indices(&self) -> Vec<u32> {
        self.faces
            .iter()
            .flat_map(|f| (1..f.len() - 1).flat_map(move |k| [f[0], f[k], f[k + 1]]))
            .collect()
    }
}

pub fn obj(m: &Indexed) -> String {
    let mut s = String::new();
    for v in &m.verts {
        s += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    for f in &m.faces {
        let idx: Vec<String> = f.iter().map(|i| (i + 1).to_string()).collect();
        s += &format!("f {}\n", idx.join(" "));
    }
    s
}

pub fn ply_ascii(m: &Indexed) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment written by the test\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        m.verts.len(),
        m.faces.len()
    );
    for v in &m.verts {
        s += &format!("{} {} {}\n", v[0], v[1], v[2]);
    }
    for f in &m.faces {
        let idx: Vec<String> = f.iter().map(u32::to_string).collect();
        s += &format!("{} {}\n", f.len(), idx.join(" "));
    }
    s.into_bytes()
}

pub fn ply_binary(m: &Indexed, big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.verts.len(),
        m.faces.len()
    )
    .into_bytes();
    let f32b = |x: f32| {
        if big_endian {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    let i32b = |x: i32| {
        if big_endian {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    for v in &m.verts {
        for x in v {
            out.extend(f32b(*x));
        }
    }
    for f in &m.faces {
        out.push(f.len() as u8);
        for &i in f {
            out.extend(i32b(i as i32));
        }
    }
    out
}

/// The binary buffer of a one-mesh glTF: positions (f32 VEC3) then u32 indices.
pub fn gltf_buffer(m: &Indexed) -> Vec<u8> {
    let mut bin: Vec<u8> = m
        .verts
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    bin.extend(m.triangle_indices().iter().flat_map(|i| i.to_le_bytes()));
    bin
}

/// A glTF document for `m` (buffer 0 as [`gltf_buffer`] lays it out, given `uri` or none
/// for a GLB's binary chunk), one mesh of one primitive, one node, one scene.
pub fn gltf_json(m: &Indexed, uri: Option<String>) -> Value {
    let pos_bytes = m.verts.len() * 12;
    let n_idx = m.triangle_indices().len();
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for v in &m.verts {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let mut buffer = json!({ "byteLength": pos_bytes + n_idx * 4 });
    if let Some(uri) = uri {
        buffer["uri"] = json!(uri);
    }
    json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 }, "indices": 1 }] }],
        "buffers": [buffer],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": pos_bytes },
            { "buffer": 0, "byteOffset": pos_bytes, "byteLength": n_idx * 4 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": m.verts.len(), "type": "VEC3",
              "min": lo, "max": hi },
            { "bufferView": 1, "componentType": 5125, "count": n_idx, "type": "SCALAR" }
        ]
    })
}

/// A data URI holding `bytes`.
pub fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A GLB container: the JSON chunk (space-padded) and, if any, the binary chunk
/// (zero-padded), each to 4 bytes.
pub fn glb(doc: &Value, bin: Option<&[u8]>) -> Vec<u8> {
    let mut j = serde_json::to_vec(doc).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut chunks = Vec::new();
    chunks.extend((j.len() as u32).to_le_bytes());
    chunks.extend(0x4E4F_534Au32.to_le_bytes());
    chunks.extend(j);
    if let Some(b) = bin {
        let mut b = b.to_vec();
        while !b.len().is_multiple_of(4) {
            b.push(0);
        }
        chunks.extend((b.len() as u32).to_le_bytes());
        chunks.extend(0x004E_4942u32.to_le_bytes());
        chunks.extend(b);
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((12 + chunks.len() as u32).to_le_bytes());
    out.extend(chunks);
    out
}

/// A glTF document (buffer embedded) of a unit cube drawn by node 1, a child of node 0,
/// with one animation: node 0 moves from the origin to `to` over the first second
/// (`LINEAR`), node 1 turns a quarter about +Y at 1 s (`STEP`), and with `vanish` node 1
/// also scales from 1 to 0 over the first second (`LINEAR`). Node 2 places a perspective
/// camera at (0, 0, 5) looking along −Z; with `dolly` it moves to (0, 0, 3) over the
/// first second (`LINEAR`).
pub fn animated_cube(to: [f32; 3], vanish: bool, dolly: bool) -> Value {
    let cube = Indexed {
        verts: (0..8)
            .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|b| b as f32 - 0.5))
            .collect(),
        faces: vec![
            vec![0, 2, 3, 1],
            vec![4, 5, 7, 6],
            vec![0, 1, 5, 4],
            vec![2, 6, 7, 3],
            vec![0, 4, 6, 2],
            vec![1, 3, 7, 5],
        ],
    };
    let mut bin = gltf_buffer(&cube);
    let mut doc = gltf_json(&cube, None);
    // Keys appended after the mesh: (accessor type, count, f32 values).
    let turn = std::f32::consts::FRAC_1_SQRT_2;
    let mut keys: Vec<(&str, usize, Vec<f32>)> = vec![
        ("SCALAR", 2, vec![0.0, 1.0]),
        ("VEC3", 2, [[0.0; 3], to].concat()),
        ("VEC4", 2, vec![0.0, 0.0, 0.0, 1.0, 0.0, turn, 0.0, turn]),
    ];
    if vanish {
        keys.push(("VEC3", 2, vec![1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
    }
    if dolly {
        keys.push(("VEC3", 2, vec![0.0, 0.0, 5.0, 0.0, 0.0, 3.0]));
    }
    let first = doc["accessors"].as_array().unwrap().len();
    for (kind, count, values) in keys {
        let view = doc["bufferViews"].as_array().unwrap().len();
        doc["bufferViews"].as_array_mut().unwrap().push(json!({
            "buffer": 0, "byteOffset": bin.len(), "byteLength": values.len() * 4
        }));
        let mut accessor = json!({
            "bufferView": view, "componentType": 5126, "count": count, "type": kind
        });
        if kind == "SCALAR" {
            accessor["min"] = json!([values[0]]);
            accessor["max"] = json!([values[count - 1]]);
        }
        doc["accessors"].as_array_mut().unwrap().push(accessor);
        bin.extend(values.iter().flat_map(|x| x.to_le_bytes()));
    }
    let mut channels = vec![
        json!({ "sampler": 0, "target": { "node": 0, "path": "translation" } }),
        json!({ "sampler": 1, "target": { "node": 1, "path": "rotation" } }),
    ];
    let mut samplers = vec![
        json!({ "input": first, "output": first + 1, "interpolation": "LINEAR" }),
        json!({ "input": first, "output": first + 2, "interpolation": "STEP" }),
    ];
    let mut output = first + 3;
    if vanish {
        channels
            .push(json!({ "sampler": samplers.len(), "target": { "node": 1, "path": "scale" } }));
        samplers.push(json!({ "input": first, "output": output, "interpolation": "LINEAR" }));
        output += 1;
    }
    if dolly {
        channels.push(
            json!({ "sampler": samplers.len(), "target": { "node": 2, "path": "translation" } }),
        );
        samplers.push(json!({ "input": first, "output": output, "interpolation": "LINEAR" }));
    }
    doc["nodes"] = json!([
        { "children": [1] },
        { "mesh": 0 },
        { "camera": 0, "translation": [0.0, 0.0, 5.0] }
    ]);
    doc["scenes"] = json!([{ "nodes": [0, 2] }]);
    doc["cameras"] =
        json!([{ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1 } }]);
    doc["animations"] = json!([{ "name": "slide", "channels": channels, "samplers": samplers }]);
    doc["buffers"] = json!([{ "byteLength": bin.len(), "uri": data_uri(&bin) }]);
    doc
}
