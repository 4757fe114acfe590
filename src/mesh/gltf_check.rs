//! What the `gltf` crate indexes without checking, checked before it sees a document: the
//! crate's own validation and its accessors index arrays directly and unwrap image sources,
//! so a reference out of range or an image without a source would panic inside it. Every
//! index a glTF 2.0 document holds (accessors, buffer views, buffers, images, samplers,
//! textures, materials, meshes, nodes, cameras, skins, scenes, animation samplers) is checked
//! against its array here, with the JSON path of the first one out of range; also the asset
//! version (2.x), a GLB's header length and chunks, and node cycles (named).

use serde_json::Value;

/// The JSON of a `.gltf` file or of a GLB's first chunk, after the GLB's header and chunk
/// lengths are checked against the file.
pub fn json_of(bytes: &[u8]) -> Result<&[u8], String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(bytes);
    }
    let word = |at: usize| {
        let b = bytes
            .get(at..at + 4)
            .ok_or("the GLB ends inside its header")?;
        Ok::<u32, String>(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (version, length) = (word(4)?, word(8)?);
    if version != 2 {
        return Err(format!(
            "GLB version {version}: lancer reads glTF 2.0 (GLB version 2)"
        ));
    }
    if length as usize != bytes.len() {
        return Err(format!(
            "the GLB header gives a length of {length} bytes but the file has {}",
            bytes.len()
        ));
    }
    let (json_len, kind) = (word(12)? as usize, word(16)?);
    if kind != u32::from_le_bytes(*b"JSON") {
        return Err("the GLB's first chunk is not its JSON".into());
    }
    bytes
        .get(20..20usize.saturating_add(json_len))
        .ok_or_else(|| format!("the GLB's JSON chunk ({json_len} bytes) runs past the file's end"))
}

/// The extensions a glTF document requires that lancer does not read, each with what to do
/// about it; empty when it can read the file.
pub fn unsupported_required(json: &[u8]) -> Vec<String> {
    let Ok(doc) = serde_json::from_slice::<Value>(json) else {
        return Vec::new();
    };
    let required = doc.get("extensionsRequired").and_then(Value::as_array);
    (required.into_iter().flatten())
        .filter_map(Value::as_str)
        .filter(|x| !SUPPORTED_EXTENSIONS.contains(x))
        .map(|x| {
            let what = match x {
                "KHR_draco_mesh_compression" | "EXT_meshopt_compression" => {
                    "decompress its meshes (e.g. gltf-transform copy IN OUT)"
                }
                "KHR_texture_basisu" | "EXT_texture_webp" | "EXT_texture_avif" => {
                    "convert its textures to PNG or JPEG"
                }
                _ => "export it without that extension",
            };
            format!("{x} ({what})")
        })
        .collect()
}

/// The glTF extensions lancer reads (the `gltf` crate's features it enables).
pub const SUPPORTED_EXTENSIONS: [&str; 5] = [
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_lights_punctual",
    "KHR_texture_transform",
];

/// Checks every reference of the document `json` against its array (and the rest the module
/// names). Returns the first problem with its JSON path.
pub fn check(json: &[u8]) -> Result<(), String> {
    let doc: Value = serde_json::from_slice(json).map_err(|e| format!("not valid JSON: {e}"))?;
    let version = doc.pointer("/asset/version").and_then(Value::as_str);
    match version {
        Some(v) if v.split('.').next() == Some("2") => {}
        Some(v) => return Err(format!("asset.version {v:?}: lancer reads glTF 2.0")),
        None => return Err("no asset.version: not a glTF 2.0 document".into()),
    }
    let c = Check { doc: &doc };
    c.all("accessors", |c, a, at| {
        c.one(a, "bufferView", "bufferViews", at)?;
        c.one(a, "sparse/indices/bufferView", "bufferViews", at)?;
        c.one(a, "sparse/values/bufferView", "bufferViews", at)
    })?;
    c.all("bufferViews", |c, v, at| c.one(v, "buffer", "buffers", at))?;
    c.all("images", |c, image, at| {
        c.one(image, "bufferView", "bufferViews", at)?;
        let has = |k: &str| image.get(k).is_some();
        match (has("uri"), has("bufferView"), has("mimeType")) {
            (false, false, _) => Err(format!("{at}: an image with neither uri nor bufferView")),
            (_, true, false) => Err(format!("{at}: an image in a bufferView needs a mimeType")),
            _ => Ok(()),
        }
    })?;
    c.all("textures", |c, t, at| {
        c.one(t, "source", "images", at)?;
        c.one(t, "sampler", "samplers", at)
    })?;
    c.all("materials", |c, m, at| c.texture_infos(m, at))?;
    c.all("meshes", |c, mesh, at| {
        for (i, p) in items(mesh.get("primitives")) {
            let at = format!("{at}/primitives/{i}");
            for (name, _) in p
                .get("attributes")
                .and_then(Value::as_object)
                .into_iter()
                .flatten()
            {
                c.one(p, &format!("attributes/{name}"), "accessors", &at)?;
            }
            c.one(p, "indices", "accessors", &at)?;
            c.one(p, "material", "materials", &at)?;
            for (j, target) in items(p.get("targets")) {
                for (name, _) in target.as_object().into_iter().flatten() {
                    c.one(target, name, "accessors", &format!("{at}/targets/{j}"))?;
                }
            }
        }
        Ok(())
    })?;
    c.all("nodes", |c, n, at| {
        c.many(n, "children", "nodes", at)?;
        c.one(n, "mesh", "meshes", at)?;
        c.one(n, "camera", "cameras", at)?;
        c.one(n, "skin", "skins", at)
    })?;
    c.all("scenes", |c, s, at| c.many(s, "nodes", "nodes", at))?;
    c.one(&doc, "scene", "scenes", "")?;
    c.all("skins", |c, s, at| {
        c.one(s, "inverseBindMatrices", "accessors", at)?;
        c.one(s, "skeleton", "nodes", at)?;
        c.many(s, "joints", "nodes", at)
    })?;
    c.all("animations", |c, a, at| {
        let samplers = items(a.get("samplers")).count();
        for (i, s) in items(a.get("samplers")) {
            c.one(s, "input", "accessors", &format!("{at}/samplers/{i}"))?;
            c.one(s, "output", "accessors", &format!("{at}/samplers/{i}"))?;
        }
        for (i, ch) in items(a.get("channels")) {
            let at = format!("{at}/channels/{i}");
            c.one(ch, "target/node", "nodes", &at)?;
            match ch.get("sampler").map(Value::as_u64) {
                Some(Some(s)) if (s as usize) < samplers => {}
                Some(_) => return Err(format!("{at}/sampler: no such animation sampler")),
                None => return Err(format!("{at}: a channel without a sampler")),
            }
        }
        Ok(())
    })?;
    node_cycle(&doc)
}

/// The elements of a JSON array with their indices (none for anything else).
fn items(v: Option<&Value>) -> impl Iterator<Item = (usize, &Value)> {
    v.and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
}

/// The checks over one document.
struct Check<'a> {
    doc: &'a Value,
}

impl Check<'_> {
    /// How many elements the top-level array `name` has.
    fn len(&self, name: &str) -> usize {
        self.doc
            .get(name)
            .and_then(Value::as_array)
            .map_or(0, Vec::len)
    }

    /// Runs `f` over every element of the top-level array `name`, with its JSON path.
    fn all(
        &self,
        name: &str,
        f: impl Fn(&Self, &Value, &str) -> Result<(), String>,
    ) -> Result<(), String> {
        items(self.doc.get(name)).try_for_each(|(i, v)| f(self, v, &format!("/{name}/{i}")))
    }

    /// The index at `key` (a `/`-separated path) of `obj`, if present, is in `target`.
    fn one(&self, obj: &Value, key: &str, target: &str, at: &str) -> Result<(), String> {
        match obj.pointer(&format!("/{key}")) {
            None => Ok(()),
            Some(v) => self.index(v, target, &format!("{at}/{key}")),
        }
    }

    /// Every index in the array at `key` of `obj`, if present, is in `target`.
    fn many(&self, obj: &Value, key: &str, target: &str, at: &str) -> Result<(), String> {
        match obj.get(key) {
            None => Ok(()),
            Some(Value::Array(a)) => (a.iter().enumerate())
                .try_for_each(|(i, v)| self.index(v, target, &format!("{at}/{key}/{i}"))),
            Some(_) => Err(format!("{at}/{key}: not an array of indices")),
        }
    }

    fn index(&self, v: &Value, target: &str, at: &str) -> Result<(), String> {
        let n = self.len(target);
        match v.as_u64() {
            Some(i) if (i as usize) < n => Ok(()),
            Some(i) => Err(format!("{at}: index {i}, but there are {n} {target}")),
            None => Err(format!("{at}: {v} is not an index")),
        }
    }

    /// Every texture reference (`{"index": …}` under a key ending in `Texture`) in a
    /// material, its extensions included.
    fn texture_infos(&self, v: &Value, at: &str) -> Result<(), String> {
        for (key, value) in v.as_object().into_iter().flatten() {
            let here = format!("{at}/{key}");
            if key.ends_with("Texture") && value.is_object() {
                self.one(value, "index", "textures", &here)?;
            }
            if value.is_object() {
                self.texture_infos(value, &here)?;
            }
        }
        Ok(())
    }
}

/// Refuses a node that is its own ancestor, naming the cycle.
fn node_cycle(doc: &Value) -> Result<(), String> {
    let children: Vec<Vec<usize>> = items(doc.get("nodes"))
        .map(|(_, n)| {
            items(n.get("children"))
                .filter_map(|(_, c)| c.as_u64().map(|c| c as usize))
                .collect()
        })
        .collect();
    // 0 unvisited, 1 on the current path, 2 done; iterative depth-first search.
    let mut state = vec![0u8; children.len()];
    for root in 0..children.len() {
        if state[root] != 0 {
            continue;
        }
        let mut path = vec![(root, 0usize)];
        state[root] = 1;
        while let Some(&mut (node, ref mut next)) = path.last_mut() {
            match children[node].get(*next) {
                Some(&child) => {
                    *next += 1;
                    match state[child] {
                        0 => {
                            state[child] = 1;
                            path.push((child, 0));
                        }
                        1 => {
                            let from = path.iter().position(|&(n, _)| n == child).unwrap_or(0);
                            let cycle: Vec<String> =
                                path[from..].iter().map(|(n, _)| n.to_string()).collect();
                            return Err(format!(
                                "the nodes {} → {child} form a cycle: a node tree must not \
                                 contain itself",
                                cycle.join(" → ")
                            ));
                        }
                        _ => {}
                    }
                }
                None => {
                    state[node] = 2;
                    path.pop();
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(body: &str) -> Result<(), String> {
        check(format!(r#"{{"asset": {{"version": "2.0"}}, {body}}}"#).as_bytes())
    }

    #[test]
    fn references_out_of_range_are_named_by_their_path() {
        let e = doc(r#""accessors": [{}, {}], "meshes": [{"primitives": [{"attributes": {"POSITION": 5}}]}]"#)
            .unwrap_err();
        assert!(
            e.contains(
                "/meshes/0/primitives/0/attributes/POSITION: index 5, but there are 2 accessors"
            ),
            "{e}"
        );
        let e = doc(r#""images": [{"bufferView": 0}], "bufferViews": [{"buffer": 0}], "buffers": [{"byteLength": 1}]"#).unwrap_err();
        assert!(e.contains("needs a mimeType"), "{e}");
        assert!(doc(r#""images": [{}]"#)
            .unwrap_err()
            .contains("neither uri nor bufferView"));
        let e =
            doc(r#""materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 3}}}]"#)
                .unwrap_err();
        assert!(
            e.contains("baseColorTexture/index: index 3, but there are 0 textures"),
            "{e}"
        );
        assert!(doc(r#""scene": 0"#)
            .unwrap_err()
            .contains("/scene: index 0"));
        assert!(doc(r#""nodes": [{"mesh": 0}]"#)
            .unwrap_err()
            .contains("0 meshes"));
    }

    #[test]
    fn versions_cycles_and_glb_lengths() {
        let v3 = check(br#"{"asset": {"version": "3.0"}}"#).unwrap_err();
        assert!(v3.contains("3.0"), "{v3}");
        let e = doc(r#""nodes": [{"children": [1]}, {"children": [2]}, {"children": [0]}]"#)
            .unwrap_err();
        assert!(e.contains("0 → 1 → 2 → 0"), "{e}");
        assert!(doc(r#""nodes": [{"children": [1, 2]}, {"children": [2]}, {}]"#).is_ok());
        let json = br#"{"asset":{"version":"2.0"}}"#;
        let mut glb = b"glTF".to_vec();
        glb.extend_from_slice(&2u32.to_le_bytes());
        let total = 20 + json.len();
        glb.extend_from_slice(&(total as u32).to_le_bytes());
        glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"JSON");
        glb.extend_from_slice(json);
        assert_eq!(json_of(&glb).unwrap(), json);
        glb[8] = 12; // a header length too small
        assert!(json_of(&glb).unwrap_err().contains("length of 12"));
    }
}
