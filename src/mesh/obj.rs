//! OBJ loading. Plain geometry is read in bulk on all threads ([`obj_bulk`](super::obj_bulk));
//! everything else through tobj, after a line scan that finds what tobj would reject without
//! a line number (bad numbers, bad indices) and faces whose vertex index points nowhere; the
//! latter are commented out for tobj and replaced by placeholders so numbering stays in file
//! order. Both give the same mesh for the same file.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{check_triangle_count, classify, mtl, pack_corners, placeholder, Mesh, TriStatus};
use crate::error::{Error, Result};
use crate::geometry::{Triangle, NO_NORMAL};

/// Result of the line scan.
struct Scan {
    /// The text handed to tobj (out-of-range faces commented out).
    text: String,
    /// (triangle index where the face would start, triangles it would have made).
    out_of_range: Vec<(usize, usize)>,
    short_faces: usize,
    /// Triangles the faces make (placeholders included).
    tris: usize,
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
        tris,
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
    /// Each triangle's corner normals (`vn`), packed ([`pack_corners`]); empty where the
    /// file has none.
    pub normals: Vec<[u32; 3]>,
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
    match super::obj_bulk::read(path, &src) {
        Some(bulk) => Ok(from_bulk(path, bulk?)),
        None => load_with_tobj(path, &src),
    }
}

/// The scene of a plain OBJ file (no materials) read in bulk.
fn from_bulk(path: &Path, bulk: super::obj_bulk::Bulk) -> ObjScene {
    let n = bulk.triangles.len();
    ObjScene {
        mesh: Mesh {
            triangles: bulk.triangles,
            status: bulk.status,
            short_faces: bulk.short_faces,
            sources: vec![path.to_path_buf()],
        },
        uvs: bulk.uvs,
        normals: bulk.normals,
        material_ids: vec![None; n],
        materials: Vec::new(),
        mtl_error: None,
    }
}

/// Loads an OBJ file (its text `src`) through the line scan and tobj.
fn load_with_tobj(path: &Path, src: &str) -> Result<ObjScene> {
    let scan = scan(path, src)?;
    check_triangle_count(path, scan.tris as u128)?;
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
        // A library named again adds nothing new (tobj would append its materials again:
        // time and memory growing with the square of the repeats).
        if mtl_files.borrow().contains(&file) {
            return Ok(Default::default());
        }
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
    let mut normals = Vec::new();
    let mut material_ids = Vec::new();
    let mut pending = scan.out_of_range.iter().peekable();
    let mut fill = |triangles: &mut Vec<Triangle>,
                    status: &mut Vec<TriStatus>,
                    uvs: &mut Vec<[Vec2; 3]>,
                    normals: &mut Vec<[u32; 3]>,
                    material_ids: &mut Vec<Option<usize>>| {
        while let Some(&&(at, n)) = pending.peek() {
            if at != triangles.len() {
                break;
            }
            for _ in 0..n {
                triangles.push(placeholder());
                status.push(TriStatus::OutOfRange);
                uvs.push([Vec2::ZERO; 3]);
                normals.push([NO_NORMAL; 3]);
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
        // Normals where every corner of the model names one.
        let (nv, ni) = (&m.mesh.normals, &m.mesh.normal_indices);
        let has_normals = !ni.is_empty() && ni.len() == m.mesh.indices.len();
        let normal = |k: usize| {
            let i = ni[k] as usize * 3;
            match nv.get(i..i + 3) {
                Some(n) => Vec3::new(n[0], n[1], n[2]),
                None => Vec3::ZERO,
            }
        };
        for (fi, f) in m.mesh.indices.chunks_exact(3).enumerate() {
            fill(
                &mut triangles,
                &mut status,
                &mut uvs,
                &mut normals,
                &mut material_ids,
            );
            let t = Triangle::new(vert(f[0]), vert(f[1]), vert(f[2]));
            status.push(classify(&t));
            triangles.push(t);
            uvs.push([uv(3 * fi), uv(3 * fi + 1), uv(3 * fi + 2)]);
            normals.push(match has_normals {
                true => pack_corners([normal(3 * fi), normal(3 * fi + 1), normal(3 * fi + 2)]),
                false => [NO_NORMAL; 3],
            });
            material_ids.push(m.mesh.material_id);
        }
    }
    fill(
        &mut triangles,
        &mut status,
        &mut uvs,
        &mut normals,
        &mut material_ids,
    );
    // Normals only where every corner names one (the bulk reader's rule; tobj fills a
    // corner without one from elsewhere, so the text says).
    let has_vn = models.iter().any(|m| !m.mesh.normals.is_empty());
    let flat = normals.iter().all(|n| n[0] == NO_NORMAL);
    if flat || !every_corner_names_a_normal(src) {
        normals = Vec::new();
        if has_vn && !flat {
            warn_partial_normals(path);
        }
    }
    let (materials, mtl_error) = match materials {
        Ok(m) => (m, None),
        Err(e) => (
            Vec::new(),
            Some(mtl_unread.into_inner().unwrap_or_else(|| e.to_string())),
        ),
    };
    if mtl_error.is_none() {
        warn_unknown_usemtl(path, src, &materials);
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
        normals,
        material_ids,
        materials,
        mtl_error,
    })
}

/// Whether every corner of every face (`f`) of an OBJ text names a normal (`v//vn`,
/// `v/vt/vn`).
fn every_corner_names_a_normal(src: &str) -> bool {
    (src.lines())
        .filter_map(|l| l.trim_start().strip_prefix("f "))
        .flat_map(str::split_ascii_whitespace)
        .all(|c| c.split('/').nth(2).is_some_and(|n| !n.is_empty()))
}

/// Warns that an OBJ's `vn` normals are not used: some face corners name none.
pub(super) fn warn_partial_normals(path: &Path) {
    log::warn!(
        "{}: some face corners name no normal (vn): the mesh's normals are not used, it \
         shades flat",
        path.display()
    );
}

/// Warns, with the OBJ's file and line, about each `usemtl` that names no material of the
/// libraries read (tobj leaves those faces without a material: they render grey).
fn warn_unknown_usemtl(path: &Path, src: &str, materials: &[tobj::Material]) {
    // A set: a file may switch between thousands of materials thousands of times.
    let known: std::collections::HashSet<&str> =
        materials.iter().map(|m| m.name.as_str()).collect();
    for (i, line) in src.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("usemtl") {
            continue;
        }
        let name = words.collect::<Vec<_>>().join(" ");
        if !known.contains(name.as_str()) {
            log::warn!(
                "{}:{}: usemtl {name}: no material of that name in the MTL library; its \
                 faces are grey",
                path.display(),
                i + 1
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A statement of a generated OBJ file; indices are drawn relative to what is defined
    /// when the statement is written.
    #[derive(Clone, Debug)]
    enum Statement {
        V([usize; 3]),
        Vt([usize; 2]),
        Vn,
        /// Corners: (position pick, texture coordinate pick or none, normal or not).
        F(Vec<(Pick, Option<Pick>, bool)>),
        Other(usize),
    }

    #[derive(Clone, Copy, Debug)]
    enum Pick {
        Absolute(u8),
        Relative(u8),
        /// Past the end (for a position: a placeholder face).
        Past,
    }

    const NUMBERS: [&str; 10] = [
        "0",
        "1.5",
        "-2e-3",
        "7",
        "0.1",
        "-0",
        "123456.789",
        "3.4028236e38",
        "nan",
        "1e-45",
    ];
    const OTHER: [&str; 6] = ["# a comment", "", "o thing", "g group", "s 1", "  \t"];

    fn pick() -> impl Strategy<Value = Pick> {
        prop_oneof![
            8 => any::<u8>().prop_map(Pick::Absolute),
            4 => any::<u8>().prop_map(Pick::Relative),
            1 => Just(Pick::Past),
        ]
    }

    fn statement() -> impl Strategy<Value = Statement> {
        let corner = (pick(), prop::option::of(pick()), any::<bool>());
        prop_oneof![
            4 => prop::array::uniform3(0..NUMBERS.len()).prop_map(Statement::V),
            1 => prop::array::uniform2(0..NUMBERS.len()).prop_map(Statement::Vt),
            1 => Just(Statement::Vn),
            4 => prop::collection::vec(corner, 1..7).prop_map(Statement::F),
            1 => (0..OTHER.len()).prop_map(Statement::Other),
        ]
    }

    /// The text of `statements` (each index within what is defined so far, unless `Past`),
    /// and whether it has texture coordinates and a corner without one.
    fn render(statements: &[Statement], crlf: bool) -> (String, bool) {
        let mut corner_without_vt = false;
        let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
        let end = if crlf { "\r\n" } else { "\n" };
        let index = |p: Pick, n: usize| match p {
            _ if n == 0 => (n + 1) as i64,
            Pick::Absolute(k) => 1 + (k as usize % n) as i64,
            Pick::Relative(k) => -1 - (k as usize % n) as i64,
            Pick::Past => (n + 1) as i64,
        };
        let mut text = String::new();
        for s in statements {
            let line = match s {
                Statement::V(c) => {
                    nv += 1;
                    format!("v {} {} {}", NUMBERS[c[0]], NUMBERS[c[1]], NUMBERS[c[2]])
                }
                Statement::Vt(c) => {
                    nvt += 1;
                    format!("vt {} {}", NUMBERS[c[0]], NUMBERS[c[1]])
                }
                Statement::Vn => {
                    nvn += 1;
                    "vn 0 0 1".to_string()
                }
                Statement::F(corners) => {
                    let words: Vec<String> = corners
                        .iter()
                        .map(|&(v, vt, vn)| {
                            // Texture coordinates and normals stay in range (the scan
                            // refuses others); positions may point nowhere.
                            let vt = vt.filter(|_| nvt > 0).map(|p| match p {
                                Pick::Past => Pick::Absolute(0),
                                p => p,
                            });
                            let v = index(v, nv);
                            corner_without_vt |= vt.is_none();
                            match (vt, vn && nvn > 0) {
                                (None, false) => format!("{v}"),
                                (Some(t), false) => format!("{v}/{}", index(t, nvt)),
                                (None, true) => format!("{v}//{}", index(Pick::Absolute(0), nvn)),
                                (Some(t), true) => {
                                    format!(
                                        "{v}/{}/{}",
                                        index(t, nvt),
                                        index(Pick::Absolute(0), nvn)
                                    )
                                }
                            }
                        })
                        .collect();
                    format!("f {}", words.join(" "))
                }
                Statement::Other(k) => OTHER[*k].to_string(),
            };
            text += &line;
            text += end;
        }
        (text, nvt > 0 && corner_without_vt)
    }

    fn same_scene(a: &ObjScene, b: &ObjScene) -> std::result::Result<(), TestCaseError> {
        let bits = |s: &ObjScene| -> Vec<[u32; 9]> {
            s.mesh
                .triangles
                .iter()
                .map(|t| {
                    let f = [t.v[0], t.v[1], t.v[2]].map(|v| v.to_array());
                    std::array::from_fn(|i| f[i / 3][i % 3].to_bits())
                })
                .collect()
        };
        let uv_bits = |s: &ObjScene| -> Vec<[u32; 6]> {
            s.uvs
                .iter()
                .map(|u| std::array::from_fn(|i| u[i / 2][i % 2].to_bits()))
                .collect()
        };
        prop_assert_eq!(bits(a), bits(b), "triangles");
        prop_assert_eq!(&a.mesh.status, &b.mesh.status, "status");
        prop_assert_eq!(a.mesh.short_faces, b.mesh.short_faces, "short faces");
        prop_assert_eq!(&a.mesh.sources, &b.mesh.sources, "sources");
        prop_assert_eq!(uv_bits(a), uv_bits(b), "texture coordinates");
        prop_assert_eq!(&a.normals, &b.normals, "normals");
        prop_assert_eq!(&a.material_ids, &b.material_ids, "materials");
        prop_assert!(a.materials.is_empty() && b.materials.is_empty());
        prop_assert_eq!(&a.mtl_error, &b.mtl_error);
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The bulk reader, in chunks of any size, against the line scan and tobj on the same
        /// text: bit for bit, status for status, wherever it takes the file (files with
        /// texture coordinates on every corner, or none, and no other statement it leaves to
        /// tobj); it must take most of these.
        #[test]
        fn bulk_reading_equals_tobj(
            uv in any::<bool>(),
            statements in prop::collection::vec(statement(), 0..60),
            crlf in any::<bool>(),
            chunk in 1usize..200,
        ) {
            // With `uv`, every corner names a texture coordinate once one is defined.
            let statements: Vec<Statement> = statements
                .into_iter()
                .map(|s| match s {
                    Statement::F(c) => Statement::F(
                        c.into_iter()
                            .map(|(v, t, n)| (v, if uv { t.or(Some(Pick::Absolute(0))) } else { None }, n))
                            .collect(),
                    ),
                    Statement::Vt(_) if !uv => Statement::Vn,
                    s => s,
                })
                .collect();
            let (text, uv_on_some_corners) = render(&statements, crlf);
            let path = Path::new("generated.obj");
            let expected = load_with_tobj(path, &text).map_err(|e| TestCaseError::fail(e.to_string()))?;
            let bulk = super::super::obj_bulk::read_in_chunks(path, &text, chunk);
            match bulk {
                Some(bulk) => {
                    let got = from_bulk(path, bulk.map_err(|e| TestCaseError::fail(e.to_string()))?);
                    same_scene(&got, &expected)?;
                }
                None => prop_assert!(uv_on_some_corners, "left to tobj:\n{text}"),
            }
        }
    }

    /// The shared scanned models are plain: read in bulk, equal to tobj's reading.
    #[test]
    fn scanned_models_read_in_bulk_equal_tobj() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models");
        for name in ["stanford-bunny.obj", "teapot.obj"] {
            let path = dir.join(name);
            let Ok(text) = std::fs::read_to_string(&path) else {
                assert!(
                    std::env::var("CI").is_err(),
                    "{} is missing in CI",
                    path.display()
                );
                continue;
            };
            let bulk = super::super::obj_bulk::read(&path, &text).expect("a plain OBJ file");
            let got = from_bulk(&path, bulk.expect("small enough"));
            let expected = load_with_tobj(&path, &text).expect("a valid OBJ file");
            assert!(got.mesh.len() > 1000);
            same_scene(&got, &expected).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }

    /// A library named again is read once: its materials are not appended again, and
    /// faces after each `usemtl` keep their material.
    #[test]
    fn a_library_named_again_is_read_once() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("lib.mtl"),
            "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n",
        )
        .unwrap();
        let path = dir.path().join("x.obj");
        let text = "mtllib lib.mtl\nmtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
                    usemtl blue\nf 1 2 3\nmtllib lib.mtl\nusemtl red\nf 1 3 2\n";
        let scene = load_with_tobj(&path, text).unwrap();
        let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["red", "blue"]);
        let used: Vec<Option<&str>> = (scene.material_ids.iter())
            .map(|id| id.map(|i| scene.materials[i].name.as_str()))
            .collect();
        assert_eq!(used, [Some("blue"), Some("red")]);
    }

    #[test]
    fn materials_lines_and_vertex_colours_are_left_to_tobj() {
        let path = Path::new("x.obj");
        let plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n";
        assert!(super::super::obj_bulk::read(path, plain).is_some());
        for extra in [
            "usemtl red\n",
            "mtllib a.mtl\n",
            "l 1 2\n",
            "v 0 0 1 0.5 0.5 0.5\n",
            "v 0 0 1 2\n",
            "f 1 2/1 3\n",
            "\u{b}v 0 0 2\n",
        ] {
            let text = format!("{plain}{extra}");
            assert!(
                super::super::obj_bulk::read(path, &text).is_none(),
                "{extra:?}"
            );
        }
    }
}
