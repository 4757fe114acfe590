//! OBJ loading through tobj. A line scan first finds what tobj would reject without a line
//! number (bad numbers, bad indices) and faces whose vertex index points nowhere; the latter
//! are commented out for tobj and replaced by placeholders so numbering stays in file order.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{classify, mtl, placeholder, Mesh, TriStatus};
use crate::error::{Error, Result};
use crate::geometry::Triangle;

/// Result of the line scan.
struct Scan {
    /// The text handed to tobj (out-of-range faces commented out).
    text: String,
    /// (triangle index where the face would start, triangles it would have made).
    out_of_range: Vec<(usize, usize)>,
    short_faces: usize,
}

fn scan(path: &Path, src: &str) -> Result<Scan> {
    let mut text = String::with_capacity(src.len() + 64);
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    let mut tris = 0usize;
    let mut out_of_range = Vec::new();
    let mut short_faces = 0;
    for (i, line) in src.lines().enumerate() {
        let lineno = i + 1;
        let bad = |msg: String| Error::input(path, Some(lineno), msg);
        let mut words = line.split_whitespace();
        let mut keep = true;
        match words.next() {
            Some(kw @ ("v" | "vn" | "vt")) => {
                let need = if kw == "vt" { 1 } else { 3 };
                let nums: Vec<&str> = words.collect();
                if nums.len() < need {
                    return Err(bad(format!(
                        "'{kw}' needs {need} numbers, found {}",
                        nums.len()
                    )));
                }
                if let Some(w) = nums.iter().find(|w| w.parse::<f32>().is_err()) {
                    return Err(bad(format!("'{w}' is not a number")));
                }
                match kw {
                    "v" => nv += 1,
                    "vt" => nvt += 1,
                    _ => nvn += 1,
                }
            }
            Some("f") => {
                let corners: Vec<&str> = words.collect();
                let mut in_range = true;
                for c in &corners {
                    let parts: Vec<&str> = c.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(bad(format!(
                            "'{c}' is not a face corner (v, v/vt, v//vn or v/vt/vn)"
                        )));
                    }
                    for (k, (p, n)) in parts.iter().zip([nv, nvt, nvn]).enumerate() {
                        if p.is_empty() {
                            continue;
                        }
                        let x: i64 = p.parse().map_err(|_| {
                            bad(format!("'{p}' in face corner '{c}' is not an index"))
                        })?;
                        let ok =
                            (x > 0 && x as usize <= n) || (x < 0 && x.unsigned_abs() as usize <= n);
                        if !ok && k == 0 {
                            in_range = false;
                        } else if !ok {
                            let what = if k == 1 {
                                "texture coordinate"
                            } else {
                                "normal"
                            };
                            return Err(bad(format!("{what} index {x} in '{c}' refers to none of the {n} defined so far")));
                        }
                    }
                }
                if corners.len() < 3 {
                    short_faces += 1;
                    keep = false;
                } else if !in_range {
                    out_of_range.push((tris, corners.len() - 2));
                    keep = false;
                }
                if corners.len() >= 3 {
                    tris += corners.len() - 2;
                }
            }
            _ => {}
        }
        if !keep {
            text.push('#');
        }
        text.push_str(line);
        text.push('\n');
    }
    Ok(Scan {
        text,
        out_of_range,
        short_faces,
    })
}

/// Loads every triangle of an OBJ file in file order (polygons fan-triangulated).
/// An OBJ file with what a renderer needs besides the triangles: per-triangle texture
/// coordinates and material (index into `materials`, from the MTL files it names).
#[derive(Clone, Debug, Default)]
pub struct ObjScene {
    /// The triangles in file order, each classified.
    pub mesh: Mesh,
    /// Texture coordinates of each triangle's corners (zero where the file gives none).
    pub uvs: Vec<[Vec2; 3]>,
    /// Per triangle: index into `materials`, or None (no `usemtl`, or a placeholder).
    pub material_ids: Vec<Option<usize>>,
    /// The materials of the MTL files the OBJ names (empty if they could not be read).
    pub materials: Vec<tobj::Material>,
    /// Why the MTL library could not be read, if it could not.
    pub mtl_error: Option<String>,
}

/// Loads every triangle of an OBJ file in file order (polygons fan-triangulated), without
/// texture coordinates or materials.
pub fn load_obj(path: &Path) -> Result<Mesh> {
    load_obj_scene(path).map(|s| s.mesh)
}

/// Loads an OBJ file with its texture coordinates and MTL materials.
pub fn load_obj_scene(path: &Path) -> Result<ObjScene> {
    let src = crate::input::read_text(path)?;
    let scan = scan(path, &src)?;
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    // The MTL libraries the OBJ names, whether each could be read, and the first bad number.
    let mtl_files: RefCell<Vec<PathBuf>> = RefCell::new(Vec::new());
    let mtl_unread: RefCell<Option<String>> = RefCell::new(None);
    let mtl_bad: RefCell<Option<Error>> = RefCell::new(None);
    let loaded = tobj::load_obj_buf(&mut scan.text.as_bytes(), &opts, |p| {
        let file = dir.join(p);
        mtl_files.borrow_mut().push(file.clone());
        // Read once, bounded (a device or a FIFO is refused, not read), and checked first:
        // tobj panics on some malformed lines (a short colour).
        let text = match crate::input::read_text(&file) {
            Ok(text) => text,
            Err(e) => {
                *mtl_unread.borrow_mut() = Some(e.to_string());
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        if let Err(e) = mtl::check(&file, &text) {
            mtl_bad.borrow_mut().get_or_insert(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
        tobj::load_mtl_buf(&mut text.as_bytes())
    });
    if let Some(e) = mtl_bad.into_inner() {
        return Err(e);
    }
    let (models, materials) =
        loaded.map_err(|e| Error::input(path, None, format!("OBJ parse error: {e}")))?;

    let mut triangles = Vec::new();
    let mut status = Vec::new();
    let mut uvs = Vec::new();
    let mut material_ids = Vec::new();
    let mut pending = scan.out_of_range.iter().peekable();
    let mut fill = |triangles: &mut Vec<Triangle>,
                    status: &mut Vec<TriStatus>,
                    uvs: &mut Vec<[Vec2; 3]>,
                    material_ids: &mut Vec<Option<usize>>| {
        while let Some(&&(at, n)) = pending.peek() {
            if at != triangles.len() {
                break;
            }
            for _ in 0..n {
                triangles.push(placeholder());
                status.push(TriStatus::OutOfRange);
                uvs.push([Vec2::ZERO; 3]);
                material_ids.push(None);
            }
            pending.next();
        }
    };
    for m in &models {
        let p = &m.mesh.positions;
        let vert = |i: u32| {
            let i = i as usize * 3;
            Vec3::new(p[i], p[i + 1], p[i + 2])
        };
        let tc = &m.mesh.texcoords;
        let uv = |k: usize| {
            m.mesh.texcoord_indices.get(k).map_or(Vec2::ZERO, |&i| {
                let i = i as usize * 2;
                Vec2::new(tc[i], tc[i + 1])
            })
        };
        for (fi, f) in m.mesh.indices.chunks_exact(3).enumerate() {
            fill(&mut triangles, &mut status, &mut uvs, &mut material_ids);
            let t = Triangle::new(vert(f[0]), vert(f[1]), vert(f[2]));
            status.push(classify(&t));
            triangles.push(t);
            uvs.push([uv(3 * fi), uv(3 * fi + 1), uv(3 * fi + 2)]);
            material_ids.push(m.mesh.material_id);
        }
    }
    fill(&mut triangles, &mut status, &mut uvs, &mut material_ids);
    let (materials, mtl_error) = match materials {
        Ok(m) => (m, None),
        Err(e) => (
            Vec::new(),
            Some(mtl_unread.into_inner().unwrap_or_else(|| e.to_string())),
        ),
    };
    if mtl_error.is_none() {
        warn_unknown_usemtl(path, &src, &materials);
    }
    let mut sources = vec![path.to_path_buf()];
    sources.extend(mtl_files.into_inner());
    // The texture files the MTL libraries name are inputs too: no output may replace one.
    for m in &materials {
        let maps = [
            &m.diffuse_texture,
            &m.ambient_texture,
            &m.specular_texture,
            &m.normal_texture,
            &m.shininess_texture,
            &m.dissolve_texture,
        ];
        sources.extend(maps.into_iter().flatten().map(|t| dir.join(t)));
    }
    Ok(ObjScene {
        mesh: Mesh {
            triangles,
            status,
            short_faces: scan.short_faces,
            sources,
        },
        uvs,
        material_ids,
        materials,
        mtl_error,
    })
}

/// Warns, with the OBJ's file and line, about each `usemtl` that names no material of the
/// libraries read (tobj leaves those faces without a material: they render grey).
fn warn_unknown_usemtl(path: &Path, src: &str, materials: &[tobj::Material]) {
    for (i, line) in src.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("usemtl") {
            continue;
        }
        let name = words.collect::<Vec<_>>().join(" ");
        if !materials.iter().any(|m| m.name == name) {
            log::warn!(
                "{}:{}: usemtl {name}: no material of that name in the MTL library; its \
                 faces are grey",
                path.display(),
                i + 1
            );
        }
    }
}
