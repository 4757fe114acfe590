//! Binary PLY bodies read in bulk, on all threads: the layouts scanners and exporters write
//! (every element a fixed record of scalars, except `face`, whose one property is its list of
//! vertex indices). The faces are first taken to be triangles, which places every record
//! (their counts checked in parallel), else walked once to find where each starts (lists
//! vary in length); then decoded and fan-triangulated in parallel, each vertex's position
//! decoded from its record where a face names it. The result is the one ply-rs gives, value for value (positions through f64 to
//! f32, indices widened, faces in file order); any other layout, and any body that does not
//! match its header's counts, is left to ply-rs and its messages ([`read`] returns `None`).

use glam::{Vec2, Vec3};
use ply_rs_bw::ply::{ElementDef, Encoding, Header, PropertyType, ScalarType};
use rayon::prelude::*;

use super::ply::{NORMAL_NAMES, UV_NAMES};
use super::{classify, placeholder, TriStatus};
use crate::geometry::{pack_unit, Triangle, NO_NORMAL};

/// A scalar type (ply-rs's, which is not `Copy`).
#[derive(Clone, Copy)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl From<&ScalarType> for Scalar {
    fn from(t: &ScalarType) -> Scalar {
        match t {
            ScalarType::Char => Scalar::I8,
            ScalarType::UChar => Scalar::U8,
            ScalarType::Short => Scalar::I16,
            ScalarType::UShort => Scalar::U16,
            ScalarType::Int => Scalar::I32,
            ScalarType::UInt => Scalar::U32,
            ScalarType::Float => Scalar::F32,
            ScalarType::Double => Scalar::F64,
        }
    }
}

/// Bytes of one scalar.
fn size(t: Scalar) -> usize {
    match t {
        Scalar::I8 | Scalar::U8 => 1,
        Scalar::I16 | Scalar::U16 => 2,
        Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
        Scalar::F64 => 8,
    }
}

/// A scalar at the start of `b` (at least its size long) as f64; integers exactly.
#[inline(always)]
fn value(b: &[u8], t: Scalar, big: bool) -> f64 {
    macro_rules! get {
        ($ty:ty, $n:expr) => {{
            let a: [u8; $n] = b[..$n].try_into().unwrap_or([0; $n]);
            (if big {
                <$ty>::from_be_bytes(a)
            } else {
                <$ty>::from_le_bytes(a)
            }) as f64
        }};
    }
    match t {
        Scalar::I8 => get!(i8, 1),
        Scalar::U8 => get!(u8, 1),
        Scalar::I16 => get!(i16, 2),
        Scalar::U16 => get!(u16, 2),
        Scalar::I32 => get!(i32, 4),
        Scalar::U32 => get!(u32, 4),
        Scalar::F32 => get!(f32, 4),
        Scalar::F64 => get!(f64, 8),
    }
}

/// An integer scalar at the start of `b` as i64 (None for a float type).
#[inline(always)]
fn index(b: &[u8], t: Scalar, big: bool) -> Option<i64> {
    match t {
        Scalar::F32 | Scalar::F64 => None,
        _ => Some(value(b, t, big) as i64),
    }
}

/// A fixed record's bytes, or None when a property is a list.
fn record_bytes(e: &ElementDef) -> Option<usize> {
    e.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => Some(size(t.into())),
            PropertyType::List(..) => None,
        })
        .sum()
}

/// Where the scalar properties `names` sit in a record of `e` (all of them), and their
/// types; None where one is missing or `e` holds a list.
fn find<const N: usize>(e: &ElementDef, names: [&str; N]) -> Option<[(usize, Scalar); N]> {
    let mut at = 0;
    let mut found: [Option<(usize, Scalar)>; N] = [None; N];
    for (name, p) in &e.properties {
        let PropertyType::Scalar(t) = &p.data_type else {
            return None;
        };
        let t = Scalar::from(t);
        if let Some(k) = names.iter().position(|a| a == name) {
            found[k] = Some((at, t));
        }
        at += size(t);
    }
    let mut out = [(0, Scalar::U8); N];
    for k in 0..N {
        out[k] = found[k]?;
    }
    Some(out)
}

/// Where x, y and z sit in a vertex record, and their types.
fn xyz(e: &ElementDef) -> Option<[(usize, Scalar); 3]> {
    find(e, ["x", "y", "z"])
}

/// The mesh's triangles and their status, the faces naming fewer than three vertices, and
/// (where asked for and the vertices have them) each triangle's corner normals, packed, and
/// texture coordinates.
pub(super) struct Body {
    pub triangles: Vec<Triangle>,
    pub status: Vec<TriStatus>,
    pub short_faces: usize,
    pub normals: Vec<[u32; 3]>,
    pub uvs: Vec<[Vec2; 3]>,
}

/// Reads the body after a binary header, or None to leave it to ply-rs; with `attributes`,
/// the vertices' normals and texture coordinates too. `check` is given the triangle count
/// before anything that size is allocated (the memory check); its error is returned as is.
pub(super) fn read<E>(
    header: &Header,
    body: &[u8],
    attributes: bool,
    check: impl FnOnce(u128) -> Result<(), E>,
) -> Option<Result<Body, E>> {
    let big = match header.encoding {
        Encoding::BinaryBigEndian => true,
        Encoding::BinaryLittleEndian => false,
        Encoding::Ascii => return None,
    };
    // Each element's bytes, in order; the first 'vertex' and 'face' are the ones read.
    let mut at = 0usize;
    let (mut vertex, mut face) = (None, None);
    for e in header.elements.values() {
        match e.name.as_str() {
            "face" if face.is_none() => {
                let mut props = e.properties.values();
                let (Some(p), None) = (props.next(), props.next()) else {
                    return None;
                };
                let PropertyType::List(count_type, item_type) = &p.data_type else {
                    return None;
                };
                if !matches!(p.name.as_str(), "vertex_indices" | "vertex_index") {
                    return None;
                }
                let (count_type, item_type) = (Scalar::from(count_type), Scalar::from(item_type));
                let starts = Starts::scan(body, at, e.count, count_type, item_type, big)?;
                at = starts.end;
                if at > body.len() {
                    return None;
                }
                face = Some((starts, count_type, item_type));
            }
            name => {
                let bytes = record_bytes(e)?.checked_mul(e.count)?;
                if name == "vertex" && vertex.is_none() {
                    vertex = Some((at, e.count, record_bytes(e)?, xyz(e)?, e));
                }
                at = at.checked_add(bytes)?;
                if at > body.len() {
                    return None;
                }
            }
        }
    }
    let (starts, count_type, item_type) = face?;
    let (c, i) = (size(count_type), size(item_type));
    // Positions, decoded where the faces name them (each a few times: cheaper than a copy of
    // every vertex in memory of its own).
    let vertices = match vertex {
        Some((start, count, stride, xyz, _)) if stride > 0 => {
            Positions::new(&body[start..start + count * stride], stride, xyz, big)
        }
        Some((_, count, _, _, _)) if count > 0 => return None,
        _ => Positions::new(&[], 1, [(0, Scalar::F32); 3], big),
    };
    // The vertices' own normals (packed) and texture coordinates, where asked for.
    let vertex_def = vertex.map(|v| v.4);
    let normal_at = (vertex_def.filter(|_| attributes)).and_then(|e| find(e, NORMAL_NAMES));
    let uv_at = (vertex_def.filter(|_| attributes))
        .and_then(|e| UV_NAMES.iter().find_map(|&names| find(e, names)));
    let per_vertex: Option<Vec<(u32, Vec2)>> = match (vertex, normal_at, uv_at) {
        (_, None, None) => None,
        (Some((start, count, stride, _, _)), _, _) if stride > 0 => Some(
            body[start..start + count * stride]
                .par_chunks_exact(stride)
                .map(|r| {
                    let get = |(o, t): (usize, Scalar)| value(&r[o..], t, big) as f32;
                    let n = normal_at.map_or(NO_NORMAL, |[x, y, z]| {
                        pack_unit(Vec3::new(get(x), get(y), get(z))).unwrap_or(NO_NORMAL)
                    });
                    (
                        n,
                        uv_at.map_or(Vec2::ZERO, |[u, v]| Vec2::new(get(u), get(v))),
                    )
                })
                .collect(),
        ),
        _ => None,
    };
    let corners = |f: usize| {
        let s = starts.at(f);
        let n = index(&body[s..], count_type, big).unwrap_or(0) as usize;
        (s + c, n)
    };
    let faces = Faces {
        body,
        starts: &starts,
        count_type,
        item_type,
        big,
    };
    let tris: u128 = match starts.triangles {
        true => starts.len() as u128,
        false => (0..starts.len())
            .into_par_iter()
            .map(|f| corners(f).1.saturating_sub(2) as u128)
            .sum(),
    };
    if let Err(e) = check(tris) {
        return Some(Err(e));
    }
    let short_faces = match starts.triangles {
        true => 0,
        false => (0..starts.len())
            .into_par_iter()
            .filter(|&f| corners(f).1 < 3)
            .count(),
    };
    let vertex = |b: &[u8]| {
        let k = index(b, item_type, big)?;
        vertices.get(usize::try_from(k).ok()?)
    };
    if tris == starts.len() as u128 && short_faces == 0 {
        // Every face a triangle (the usual file): one triangle per face and its status,
        // written in place.
        let (triangles, status): (Vec<Triangle>, Vec<TriStatus>) = (0..starts.len())
            .into_par_iter()
            .map(|f| {
                let (s, _) = corners(f);
                let v = |k: usize| vertex(&body[s + k * i..]);
                match (v(0), v(1), v(2)) {
                    (Some(a), Some(b), Some(c)) => {
                        let t = Triangle::new(a, b, c);
                        (t, classify(&t))
                    }
                    _ => (placeholder(), TriStatus::OutOfRange),
                }
            })
            .unzip();
        let (normals, uvs) =
            fan_attributes(&per_vertex, &faces, normal_at.is_some(), uv_at.is_some());
        return Some(Ok(Body {
            triangles,
            status,
            short_faces,
            normals,
            uvs,
        }));
    }
    let (triangles, status): (Vec<Triangle>, Vec<TriStatus>) = (0..starts.len())
        .into_par_iter()
        .flat_map_iter(|f| {
            let (s, n) = corners(f);
            let list = &body[s..s + n * i];
            // Triangles (the common face) without an allocation.
            let corner: Option<Corners> = if n == 3 {
                let v = |k: usize| vertex(&list[k * i..]);
                (|| Some(Corners::Three([v(0)?, v(1)?, v(2)?])))()
            } else {
                list.chunks_exact(i)
                    .map(vertex)
                    .collect::<Option<Vec<Vec3>>>()
                    .map(Corners::Many)
            };
            (1..n.saturating_sub(1)).map(move |k| match &corner {
                Some(v) => {
                    let v = v.as_slice();
                    let t = Triangle::new(v[0], v[k], v[k + 1]);
                    (t, classify(&t))
                }
                None => (placeholder(), TriStatus::OutOfRange),
            })
        })
        .unzip();
    let (normals, uvs) = fan_attributes(&per_vertex, &faces, normal_at.is_some(), uv_at.is_some());
    Some(Ok(Body {
        triangles,
        status,
        short_faces,
        normals,
        uvs,
    }))
}

/// Where each face's record starts (its count, then its list of vertex indices).
struct Starts {
    /// Every face's start, or none where every face is a triangle (`triangles`: then face f
    /// starts at `first + f · stride`).
    listed: Vec<usize>,
    triangles: bool,
    first: usize,
    stride: usize,
    count: usize,
    /// Where the faces end.
    end: usize,
}

impl Starts {
    /// The starts of `count` faces from `at`: first taken to be triangles, each count
    /// checked on all threads; else (or where the records do not fit `body`) each face walked
    /// in turn to find where the next starts. None where the counts lead past `body` or
    /// overflow.
    fn scan(
        body: &[u8],
        at: usize,
        count: usize,
        count_type: Scalar,
        item_type: Scalar,
        big: bool,
    ) -> Option<Starts> {
        let (c, i) = (size(count_type), size(item_type));
        let stride = c + 3 * i;
        let end = count.checked_mul(stride).and_then(|b| b.checked_add(at));
        if let Some(end) = end.filter(|&end| end <= body.len()) {
            let triangles = (body[at..end].par_chunks_exact(stride))
                .all(|r| index(r, count_type, big) == Some(3));
            if triangles {
                return Some(Starts {
                    listed: Vec::new(),
                    triangles: true,
                    first: at,
                    stride,
                    count,
                    end,
                });
            }
        }
        let mut listed = Vec::with_capacity(count.min(body.len()));
        let mut at = at;
        for _ in 0..count {
            let n = index(body.get(at..at + c)?, count_type, big)?;
            let n = usize::try_from(n).ok()?;
            listed.push(at);
            at = at.checked_add(c + n.checked_mul(i)?)?;
        }
        Some(Starts {
            listed,
            triangles: false,
            first: 0,
            stride: 0,
            count,
            end: at,
        })
    }

    /// Where face f starts.
    #[inline(always)]
    fn at(&self, f: usize) -> usize {
        match self.triangles {
            true => self.first + f * self.stride,
            false => self.listed[f],
        }
    }

    /// The number of faces.
    fn len(&self) -> usize {
        self.count
    }
}

/// The vertices' positions, decoded from their records where they are read.
struct Positions<'a> {
    records: &'a [u8],
    stride: usize,
    /// Where x, y and z sit in a record, and their types.
    xyz: [(usize, Scalar); 3],
    big: bool,
}

impl<'a> Positions<'a> {
    /// The positions in `records` of `stride` bytes each.
    fn new(records: &'a [u8], stride: usize, xyz: [(usize, Scalar); 3], big: bool) -> Self {
        Positions {
            records,
            stride,
            xyz,
            big,
        }
    }

    /// Whether they are little-endian f32 (the usual file), read without a type's dispatch.
    #[inline(always)]
    fn f32_le(&self) -> bool {
        !self.big && self.xyz.iter().all(|(_, t)| matches!(t, Scalar::F32))
    }
}

impl Positions<'_> {
    /// Vertex k's position (through f64, as ply-rs gives it), or None past the last.
    #[inline(always)]
    fn get(&self, k: usize) -> Option<Vec3> {
        let r = self.records.get(k.checked_mul(self.stride)?..)?;
        if r.len() < self.stride {
            return None;
        }
        if self.f32_le() {
            // Through f64 as the other types go (a signalling NaN comes out quiet, as there).
            let get = |o: usize| {
                let b: [u8; 4] = r[o..o + 4].try_into().unwrap_or([0; 4]);
                f32::from_le_bytes(b) as f64 as f32
            };
            return Some(Vec3::new(
                get(self.xyz[0].0),
                get(self.xyz[1].0),
                get(self.xyz[2].0),
            ));
        }
        let get = |(o, t): (usize, Scalar)| value(&r[o..], t, self.big) as f32;
        Some(Vec3::new(
            get(self.xyz[0]),
            get(self.xyz[1]),
            get(self.xyz[2]),
        ))
    }
}

/// The faces of a body: where each face's index list starts, and how to read it.
struct Faces<'a> {
    body: &'a [u8],
    starts: &'a Starts,
    count_type: Scalar,
    item_type: Scalar,
    big: bool,
}

impl Faces<'_> {
    /// Face f's vertex indices (None for one that names no vertex of `n`).
    fn indices(&self, f: usize, n: usize) -> Option<Vec<usize>> {
        let (c, i) = (size(self.count_type), size(self.item_type));
        let s = self.starts.at(f);
        let count = index(&self.body[s..], self.count_type, self.big).unwrap_or(0) as usize;
        let list = &self.body[s + c..s + c + count * i];
        (list.chunks_exact(i))
            .map(|b| {
                let k = usize::try_from(index(b, self.item_type, self.big)?).ok()?;
                (k < n).then_some(k)
            })
            .collect()
    }

    /// Each triangle's corners' values of `per` (by vertex), in fan order; `none` for a
    /// triangle of a face naming no vertex.
    fn fan<T: Copy + Send + Sync>(&self, per: &[T], none: T) -> Vec<[T; 3]> {
        (0..self.starts.len())
            .into_par_iter()
            .flat_map_iter(|f| {
                let corners = self.indices(f, per.len());
                let n = corners.as_ref().map_or_else(
                    || {
                        let s = self.starts.at(f);
                        index(&self.body[s..], self.count_type, self.big).unwrap_or(0) as usize
                    },
                    Vec::len,
                );
                (1..n.saturating_sub(1)).map(move |k| match &corners {
                    Some(c) => [per[c[0]], per[c[k]], per[c[k + 1]]],
                    None => [none; 3],
                })
            })
            .collect()
    }
}

/// The triangles' packed corner normals and texture coordinates from the vertices' (each
/// empty where the vertices have none).
fn fan_attributes(
    per_vertex: &Option<Vec<(u32, Vec2)>>,
    faces: &Faces,
    normals: bool,
    uvs: bool,
) -> (Vec<[u32; 3]>, Vec<[Vec2; 3]>) {
    let Some(per) = per_vertex else {
        return (Vec::new(), Vec::new());
    };
    let n: Vec<u32> = per.iter().map(|p| p.0).collect();
    let t: Vec<Vec2> = per.iter().map(|p| p.1).collect();
    let n = match normals {
        true => super::ply::whole_triangles(faces.fan(&n, NO_NORMAL)),
        false => Vec::new(),
    };
    let t = match uvs {
        true => faces.fan(&t, Vec2::ZERO),
        false => Vec::new(),
    };
    (n, t)
}

/// A face's corner positions.
enum Corners {
    Three([Vec3; 3]),
    Many(Vec<Vec3>),
}

impl Corners {
    fn as_slice(&self) -> &[Vec3] {
        match self {
            Corners::Three(v) => v,
            Corners::Many(v) => v,
        }
    }
}

/// Where the body starts: after the line `end_header` (None when there is none).
pub(super) fn body_start(file: &[u8]) -> Option<usize> {
    let key = b"\nend_header";
    let at = file.windows(key.len()).position(|w| w == key)? + key.len();
    let nl = file[at..].iter().position(|&b| b == b'\n')?;
    // Only spaces or a carriage return may follow on that line.
    (file[at..at + nl].iter().all(|&b| b == b' ' || b == b'\r')).then_some(at + nl + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ply_rs_bw::parser::{Parser, Reader};
    use ply_rs_bw::ply::DefaultElement;

    /// A binary little-endian file with `vertex_props` before x y z's end and one quad.
    fn file(extra_vertex: &str) -> Vec<u8> {
        let mut f = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
             property float y\nproperty float z\n{extra_vertex}element face 1\n\
             property list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        for v in [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ] {
            for c in v {
                f.extend(c.to_le_bytes());
            }
            if !extra_vertex.is_empty() {
                f.push(0); // an empty list
            }
        }
        f.push(4);
        for i in 0..4i32 {
            f.extend(i.to_le_bytes());
        }
        f
    }

    fn bulk(bytes: &[u8]) -> Option<Body> {
        let header = Parser::<DefaultElement>::new()
            .read_header(&mut Reader::new(std::io::Cursor::new(bytes)))
            .unwrap();
        let start = body_start(bytes).unwrap();
        read(&header, &bytes[start..], false, |_| Ok::<(), ()>(())).map(|r| r.unwrap())
    }

    #[test]
    fn the_usual_layout_is_read_in_bulk_and_others_are_left_to_ply_rs() {
        let body = bulk(&file("")).expect("read in bulk");
        assert_eq!(body.triangles.len(), 2);
        assert_eq!(body.triangles[1].v[2], Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(body.status, [TriStatus::Ok, TriStatus::Ok]);
        // A list in the vertex record: not a fixed record, so ply-rs reads it.
        assert!(bulk(&file("property list uchar int extra\n")).is_none());
        // A body shorter than its header says: ply-rs reads it, and says so.
        let mut cut = file("");
        cut.pop();
        assert!(bulk(&cut).is_none());
    }
}
