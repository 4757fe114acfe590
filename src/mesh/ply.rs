//! PLY loading (ASCII and binary, either byte order) through ply-rs-bw: the `vertex`
//! element's x, y, z and the `face` element's index lists, fan-triangulated in file order
//! like OBJ polygons. Binary bodies in the usual layouts are read in bulk on all threads
//! instead ([`ply_binary`](super::ply_binary)), with the same result. Faces naming no vertex keep their place as placeholders; other
//! elements are read past and named in a warning.

use std::io::BufReader;
use std::path::Path;

use glam::{Vec2, Vec3};
use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
};

use super::{check_triangle_count, classify, placeholder, Mesh, TriStatus};
use crate::error::{Error, Result};
use crate::geometry::Triangle;

/// The vertex properties of a normal.
pub(super) const NORMAL_NAMES: [&str; 3] = ["nx", "ny", "nz"];

/// The pairs of vertex properties that name texture coordinates, the first one present used.
pub(super) const UV_NAMES: [[&str; 2]; 4] = [
    ["u", "v"],
    ["s", "t"],
    ["texture_u", "texture_v"],
    ["texture_s", "texture_t"],
];

/// A vertex (position, normal, texture coordinates), whatever scalar types the file stores
/// them in.
struct Vertex([f64; 8]);

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex([0.0; 8])
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        let k = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            "nx" => 3,
            "ny" => 4,
            "nz" => 5,
            "u" | "s" | "texture_u" | "texture_s" => 6,
            "v" | "t" | "texture_v" | "texture_t" => 7,
            _ => return PropertyAccessResult::Ignored,
        };
        match scalar(&p) {
            Some(x) => {
                self.0[k] = x;
                PropertyAccessResult::Set
            }
            // Positions must be numbers; other properties of other types are read past.
            None if k < 3 => PropertyAccessResult::UnsupportedType,
            None => PropertyAccessResult::Ignored,
        }
    }
}

/// A PLY file with what a renderer takes besides the triangles.
#[derive(Clone, Debug, Default)]
pub struct PlyScene {
    /// The triangles in file order, each classified.
    pub mesh: Mesh,
    /// Each triangle's corner normals (`nx ny nz`), packed
    /// ([`pack_corners`](super::pack_corners)); empty where the vertices have none.
    pub normals: Vec<[u32; 3]>,
    /// Each triangle's corner texture coordinates (`u v`, `s t`, `texture_u texture_v`);
    /// empty where the vertices have none.
    pub uvs: Vec<[Vec2; 3]>,
}

/// Packed corner normals with a corner that has none made a triangle without any.
pub(super) fn whole_triangles(mut n: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    use crate::geometry::NO_NORMAL;
    n.iter_mut()
        .filter(|c| c.contains(&NO_NORMAL))
        .for_each(|c| *c = [NO_NORMAL; 3]);
    n
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(x) => x.into(),
        Property::UChar(x) => x.into(),
        Property::Short(x) => x.into(),
        Property::UShort(x) => x.into(),
        Property::Int(x) => x.into(),
        Property::UInt(x) => x.into(),
        Property::Float(x) => x.into(),
        Property::Double(x) => x,
        _ => return None,
    })
}

/// A face's vertex indices, widened (negative ones point at no vertex).
struct Face(Vec<i64>);

impl PropertyAccess for Face {
    fn new() -> Self {
        Face(Vec::new())
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        if !is_index_list(name) {
            return PropertyAccessResult::Ignored;
        }
        self.0 = match p {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
}

/// An element lancer does not use: read past.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

fn is_index_list(name: &str) -> bool {
    matches!(name, "vertex_indices" | "vertex_index")
}

/// One line naming the file, the line when ply-rs knows it, and what ply-rs found.
fn parse_error(path: &Path, e: ParseError) -> Error {
    let text = e.to_string();
    let msg = match e.line() {
        Some(l) => text
            .strip_prefix(&format!("Line {l}: "))
            .unwrap_or(&text)
            .to_string(),
        None => text,
    };
    // ply-rs puts the cause on a second line: one line for people.
    let msg = msg.split_whitespace().collect::<Vec<_>>().join(" ");
    Error::input(
        path,
        e.line(),
        format!("PLY parse error: {msg} (is the file complete and its header right?)"),
    )
}

/// Refuses an element whose layout lancer cannot read, naming the header's element.
fn check_element(path: &Path, e: &ElementDef) -> Result<()> {
    let prop = |n: &str| e.properties.get(n).map(|p| &p.data_type);
    match e.name.as_str() {
        "vertex" => {
            for axis in ["x", "y", "z"] {
                if !matches!(prop(axis), Some(PropertyType::Scalar(_))) {
                    return Err(Error::input(
                        path,
                        None,
                        format!("the 'vertex' element has no scalar property '{axis}': a PLY mesh needs x, y and z"),
                    ));
                }
            }
        }
        "face" => {
            let list = e
                .properties
                .iter()
                .find(|(n, _)| is_index_list(n))
                .map(|(_, p)| &p.data_type);
            if !matches!(list, Some(PropertyType::List(..))) {
                return Err(Error::input(
                    path,
                    None,
                    "the 'face' element has no list property 'vertex_indices' (or 'vertex_index')",
                ));
            }
        }
        _ => {}
    }
    Ok(())
}

/// A binary body in a layout [`ply_binary`](super::ply_binary) reads, read on all threads;
/// None for any other (ply-rs reads it).
fn load_binary_in_bulk(path: &Path, header: &Header, attributes: bool) -> Result<Option<PlyScene>> {
    let file = crate::input::read(path)?;
    let Some(start) = super::ply_binary::body_start(&file) else {
        return Ok(None);
    };
    let Some(body) = super::ply_binary::read(header, &file[start..], attributes, |t| {
        check_triangle_count(path, t)
    }) else {
        return Ok(None);
    };
    let body = body?;
    Ok(Some(PlyScene {
        mesh: Mesh {
            sources: vec![path.to_path_buf()],
            triangles: body.triangles,
            status: body.status,
            short_faces: body.short_faces,
        },
        normals: body.normals,
        uvs: body.uvs,
    }))
}

/// The refusal of a PLY without faces.
fn no_faces(path: &Path) -> Error {
    Error::input(
        path,
        None,
        "no 'face' element: lancer traces triangles, not point clouds",
    )
}

/// Loads every triangle of a PLY file in file order (polygons fan-triangulated).
pub fn load_ply(path: &Path) -> Result<Mesh> {
    read_ply(path, false).map(|s| s.mesh)
}

/// Loads a PLY file with its vertices' normals and texture coordinates.
pub fn load_ply_scene(path: &Path) -> Result<PlyScene> {
    read_ply(path, true)
}

/// [`load_ply_scene`], the normals and texture coordinates only where `attributes`.
fn read_ply(path: &Path, attributes: bool) -> Result<PlyScene> {
    let (file, _) = crate::input::open(path)?;
    super::ply_layout::check(path, BufReader::new(file))?;
    let (file, _) = crate::input::open(path)?;
    let mut reader = Reader::new(BufReader::new(file));
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| parse_error(path, e))?;
    let (mut first_vertex, mut first_face) = (true, true);
    for e in header.elements.values() {
        check_element(path, e)?;
        let used = match e.name.as_str() {
            "vertex" => std::mem::replace(&mut first_vertex, false),
            "face" => std::mem::replace(&mut first_face, false),
            _ => false,
        };
        if used && e.name == "vertex" {
            warn_unused_vertex_properties(path, e);
        }
        if !used && e.count > 0 {
            log::warn!(
                "{}: {} '{}' elements not used (lancer reads 'vertex' and 'face')",
                path.display(),
                e.count,
                e.name
            );
        }
    }
    if !header.elements.values().any(|e| e.name == "face") {
        // Known from the header: the body (a scan's millions of points) is not read.
        return Err(no_faces(path));
    }
    if header.encoding != Encoding::Ascii {
        if let Some(scene) = load_binary_in_bulk(path, &header, attributes)? {
            return Ok(scene);
        }
    }
    let vertex_def = header.elements.values().find(|e| e.name == "vertex");
    let has = |names: &[&str]| {
        vertex_def.is_some_and(|e| names.iter().all(|n| e.properties.contains_key(*n)))
    };
    let with_normals = attributes && has(&NORMAL_NAMES);
    let with_uvs = attributes && UV_NAMES.iter().any(|n| has(n));
    let mut vertices: Option<Vec<Vertex>> = None;
    let mut faces: Option<Vec<Face>> = None;
    for (_, e) in &header.elements {
        let read = |e| parse_error(path, e);
        match e.name.as_str() {
            "vertex" if vertices.is_none() => {
                vertices = Some(
                    Parser::<Vertex>::new()
                        .read_payload_for_element(&mut reader, e, &header)
                        .map_err(read)?,
                )
            }
            "face" if faces.is_none() => {
                faces = Some(
                    Parser::<Face>::new()
                        .read_payload_for_element(&mut reader, e, &header)
                        .map_err(read)?,
                )
            }
            _ => {
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, e, &header)
                    .map_err(read)?;
            }
        }
    }
    let vertices = vertices.unwrap_or_default();
    let faces = faces.ok_or_else(|| no_faces(path))?;
    let tris: u128 = faces
        .iter()
        .map(|f| f.0.len().saturating_sub(2) as u128)
        .sum();
    check_triangle_count(path, tris)?;

    let mut mesh = Mesh {
        sources: vec![path.to_path_buf()],
        ..Mesh::default()
    };
    let vertex = |i: i64| {
        let v = vertices.get(usize::try_from(i).ok()?)?;
        Some(Vec3::new(v.0[0] as f32, v.0[1] as f32, v.0[2] as f32))
    };
    let (mut normals, mut uvs) = (Vec::new(), Vec::new());
    let normal = |v: &Vertex| {
        let n = Vec3::new(v.0[3] as f32, v.0[4] as f32, v.0[5] as f32);
        crate::geometry::pack_unit(n).unwrap_or(crate::geometry::NO_NORMAL)
    };
    let uv = |v: &Vertex| Vec2::new(v.0[6] as f32, v.0[7] as f32);
    for f in &faces {
        if f.0.len() < 3 {
            mesh.short_faces += 1;
            continue;
        }
        let named: Option<Vec<&Vertex>> = (f.0.iter())
            .map(|&i| vertices.get(usize::try_from(i).ok()?))
            .collect();
        let corners: Option<Vec<Vec3>> = f.0.iter().map(|&i| vertex(i)).collect();
        for k in 1..f.0.len() - 1 {
            let (t, s) = match &corners {
                Some(c) => {
                    let t = Triangle::new(c[0], c[k], c[k + 1]);
                    let s = classify(&t);
                    (t, s)
                }
                None => (placeholder(), TriStatus::OutOfRange),
            };
            mesh.triangles.push(t);
            mesh.status.push(s);
            let ks = [0, k, k + 1];
            if with_normals {
                let n = named.as_ref().map(|c| ks.map(|j| normal(c[j])));
                normals.push(n.unwrap_or([crate::geometry::NO_NORMAL; 3]));
            }
            if with_uvs {
                uvs.push(
                    named
                        .as_ref()
                        .map_or([Vec2::ZERO; 3], |c| ks.map(|j| uv(c[j]))),
                );
            }
        }
    }
    Ok(PlyScene {
        mesh,
        normals: whole_triangles(normals),
        uvs,
    })
}

/// Warns about the properties of the 'vertex' element lancer reads past (colours, ...).
fn warn_unused_vertex_properties(path: &Path, e: &ElementDef) {
    let known = |n: &str| {
        ["x", "y", "z"].contains(&n)
            || NORMAL_NAMES.contains(&n)
            || UV_NAMES.iter().flatten().any(|u| *u == n)
    };
    let unused: Vec<&str> = (e.properties.keys())
        .map(String::as_str)
        .filter(|n| !known(n))
        .collect();
    if !unused.is_empty() {
        log::warn!(
            "{}: vertex properties not used: {} (lancer reads positions, normals and texture \
             coordinates)",
            path.display(),
            unused.join(", ")
        );
    }
}
