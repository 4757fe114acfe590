//! Plain OBJ files read in bulk, on all threads: the geometry scanners and converters write
//! (`v` with three coordinates, `vt`, `vn`, `f` with any corner form, comments, `o`, `g`,
//! `s`). The text is cut at line ends into chunks; a first pass counts each chunk's vertices
//! (relative indices and range checks need the counts before a face), a second parses the
//! chunks in parallel, a third makes the triangles in parallel. The result is the one tobj
//! and the line scan give, value for value (the same `f32` parsing, fan triangulation, faces
//! in file order, placeholders for faces whose vertex index points nowhere). Anything else —
//! materials, `l` lines, vertex weights or colours, a face with texture coordinates on some
//! corners only, and every error — is left to tobj and the line scan with their messages
//! ([`read`] returns `None`).

use std::path::Path;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{check_triangle_count, classify, pack_corners, placeholder, TriStatus};
use crate::error::Result;
use crate::geometry::Triangle;
use crate::geometry::NO_NORMAL;

/// Bytes of text per chunk: enough to keep both passes busy, few enough to balance.
const CHUNK: usize = 1 << 20;

/// Marks a missing index (a corner without a texture coordinate; a placeholder face).
const NONE: u32 = u32::MAX;

/// What the bulk reader makes of a plain OBJ file.
pub(super) struct Bulk {
    pub triangles: Vec<Triangle>,
    pub status: Vec<TriStatus>,
    /// Texture coordinates of each triangle's corners (zero where the file has none).
    pub uvs: Vec<[Vec2; 3]>,
    /// Each triangle's corner normals, packed ([`super::pack_corners`]); empty where the
    /// file has no `vn`.
    pub normals: Vec<[u32; 3]>,
    pub short_faces: usize,
}

/// How many of each numbered statement a chunk holds.
#[derive(Clone, Copy, Default)]
struct Counts {
    v: usize,
    vt: usize,
    vn: usize,
}

impl std::ops::Add for Counts {
    type Output = Counts;
    fn add(self, o: Counts) -> Counts {
        Counts {
            v: self.v + o.v,
            vt: self.vt + o.vt,
            vn: self.vn + o.vn,
        }
    }
}

/// One triangle of a face: position indices (`v[0] == NONE` for a placeholder), texture
/// coordinate and normal indices (`NONE` where the corner names none), 0-based.
#[derive(Clone, Copy)]
struct Tri {
    v: [u32; 3],
    vt: [u32; 3],
    vn: [u32; 3],
}

/// Triangles, their status, and their corners' texture coordinates and packed normals.
type Made = (
    Vec<Triangle>,
    (Vec<TriStatus>, (Vec<[Vec2; 3]>, Vec<[u32; 3]>)),
);

/// A chunk parsed: its vertices and texture coordinates, and its faces' triangles.
#[derive(Default)]
struct Parsed {
    positions: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    tris: Vec<Tri>,
    short_faces: usize,
    /// Whether some corner names no texture coordinate.
    corner_without_vt: bool,
    /// Whether some corner names no normal.
    corner_without_vn: bool,
}

/// Reads `src` (the text of `path`) if it is a plain OBJ file; `None` leaves it to tobj.
/// An error only for a mesh too big to hold (checked before the triangles are made).
pub(super) fn read(path: &Path, src: &str) -> Option<Result<Bulk>> {
    read_in_chunks(path, src, CHUNK)
}

/// [`read`] with chunks of about `chunk` bytes.
pub(super) fn read_in_chunks(path: &Path, src: &str, chunk: usize) -> Option<Result<Bulk>> {
    let chunks = chunks(src, chunk.max(1));
    let counts: Vec<(Counts, usize)> =
        chunks.par_iter().map(|c| count(c)).collect::<Option<_>>()?;
    let mut starts = Vec::with_capacity(chunks.len());
    let mut total = (Counts::default(), 0usize);
    for &(c, tris) in &counts {
        starts.push(total.0);
        total = (total.0 + c, total.1 + tris);
    }
    if total.0.v >= NONE as usize || total.0.vt >= NONE as usize || total.0.vn >= NONE as usize {
        return None;
    }
    if let Err(e) = check_triangle_count(path, total.1 as u128) {
        return Some(Err(e));
    }
    let parsed: Vec<Parsed> = chunks
        .par_iter()
        .zip(&starts)
        .map(|(c, &start)| parse(c, start))
        .collect::<Option<_>>()?;
    let has_vt = total.0.vt > 0;
    if has_vt && parsed.iter().any(|p| p.corner_without_vt) {
        // tobj gives such corners the previous corner's coordinate: its rule, its reader.
        return None;
    }
    // Normals only where every corner names one (tobj's reader keeps the same rule).
    let has_vn = total.0.vn > 0 && !parsed.iter().any(|p| p.corner_without_vn);
    if total.0.vn > 0 && !has_vn {
        super::obj::warn_partial_normals(path);
    }
    let positions: Vec<Vec3> = parsed
        .iter()
        .flat_map(|p| p.positions.iter().copied())
        .collect();
    let texcoords: Vec<Vec2> = parsed
        .iter()
        .flat_map(|p| p.texcoords.iter().copied())
        .collect();
    let normals: Vec<Vec3> = (parsed.iter())
        .flat_map(|p| p.normals.iter().copied())
        .collect();
    let tris: Vec<&Tri> = parsed.iter().flat_map(|p| &p.tris).collect();
    let (triangles, (status, (uvs, mut packed))): Made = tris
        .par_iter()
        .map(|t| {
            if t.v[0] == NONE {
                let none = [NO_NORMAL; 3];
                return (
                    placeholder(),
                    (TriStatus::OutOfRange, ([Vec2::ZERO; 3], none)),
                );
            }
            let [a, b, c] = t.v.map(|i| positions[i as usize]);
            let tri = Triangle::new(a, b, c);
            let uv =
                t.vt.map(|i| texcoords.get(i as usize).copied().unwrap_or(Vec2::ZERO));
            let n = match has_vn {
                true => pack_corners(t.vn.map(|i| normals[i as usize])),
                false => [NO_NORMAL; 3],
            };
            (tri, (classify(&tri), (uv, n)))
        })
        .unzip();
    if packed.iter().all(|n| n[0] == NO_NORMAL) {
        packed = Vec::new();
    }
    Some(Ok(Bulk {
        triangles,
        status,
        uvs,
        normals: packed,
        short_faces: parsed.iter().map(|p| p.short_faces).sum(),
    }))
}

/// `src` cut into pieces of about `size` bytes, each ending with a line.
fn chunks(src: &str, size: usize) -> Vec<&str> {
    let mut out = Vec::with_capacity(src.len() / size + 1);
    let mut rest = src;
    while rest.len() > size {
        let cut = rest.as_bytes()[size..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(rest.len(), |i| size + i + 1);
        let (head, tail) = rest.split_at(cut);
        out.push(head);
        rest = tail;
    }
    if !rest.is_empty() {
        out.push(rest);
    }
    out
}

/// A chunk's numbered statements and the triangles its faces make; `None` if a statement
/// is one the bulk reader leaves to tobj.
fn count(chunk: &str) -> Option<(Counts, usize)> {
    let mut c = Counts::default();
    let mut tris = 0;
    for line in chunk.lines() {
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => c.v += 1,
            Some("vt") => c.vt += 1,
            Some("vn") => c.vn += 1,
            Some("f") => tris += words.count().saturating_sub(2),
            // A control or non-ASCII byte may be whitespace to tobj's splitting (Unicode's)
            // and not to this one's.
            Some(kw) if left_to_tobj(kw) || !kw.bytes().all(|b| b.is_ascii_graphic()) => {
                return None
            }
            _ => {}
        }
    }
    Some((c, tris))
}

/// Statements that change what tobj makes of the faces (materials; `l`, which tobj reads as
/// a face).
fn left_to_tobj(keyword: &str) -> bool {
    matches!(keyword, "usemtl" | "mtllib" | "l")
}

/// Parses a chunk whose first statements are numbered after `before`; `None` for anything
/// the line scan or tobj would refuse or treat otherwise.
fn parse(chunk: &str, before: Counts) -> Option<Parsed> {
    let mut out = Parsed::default();
    let mut n = before;
    let mut corners: Vec<(u32, u32, u32)> = Vec::with_capacity(8);
    for line in chunk.lines() {
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let (Some(x), Some(y), Some(z), None) =
                    (words.next(), words.next(), words.next(), words.next())
                else {
                    return None;
                };
                out.positions
                    .push(Vec3::new(x.parse().ok()?, y.parse().ok()?, z.parse().ok()?));
                n.v += 1;
            }
            Some("vt") => {
                let (u, v) = (words.next()?.parse().ok()?, words.next()?.parse().ok()?);
                all_numbers(words)?;
                out.texcoords.push(Vec2::new(u, v));
                n.vt += 1;
            }
            Some("vn") => {
                let mut c = [0.0f32; 3];
                for x in &mut c {
                    *x = words.next()?.parse::<f32>().ok()?;
                }
                all_numbers(words)?;
                out.normals.push(Vec3::from(c));
                n.vn += 1;
            }
            Some("f") => {
                corners.clear();
                let mut in_range = true;
                for w in words {
                    let (v, vt, vn) = corner(w, n)?;
                    in_range &= v != NONE;
                    out.corner_without_vt |= vt == NONE;
                    out.corner_without_vn |= vn == NONE;
                    corners.push((v, vt, vn));
                }
                if corners.len() < 3 {
                    out.short_faces += 1;
                    continue;
                }
                // Fan triangulation from the first corner, as tobj's.
                for k in 1..corners.len() - 1 {
                    let [a, b, c] = [corners[0], corners[k], corners[k + 1]];
                    out.tris.push(if in_range {
                        Tri {
                            v: [a.0, b.0, c.0],
                            vt: [a.1, b.1, c.1],
                            vn: [a.2, b.2, c.2],
                        }
                    } else {
                        Tri {
                            v: [NONE; 3],
                            vt: [NONE; 3],
                            vn: [NONE; 3],
                        }
                    });
                }
            }
            _ => {}
        }
    }
    Some(out)
}

/// Every remaining word parses as a number (the line scan's rule).
fn all_numbers<'a>(mut words: impl Iterator<Item = &'a str>) -> Option<()> {
    words.all(|w| w.parse::<f32>().is_ok()).then_some(())
}

/// A face corner (`v`, `v/vt`, `v//vn`, `v/vt/vn`) with `n` of each defined so far: its
/// 0-based position index (`NONE` when it points nowhere: the face becomes placeholders),
/// texture coordinate and normal indices (`NONE` when absent); `None` for anything the
/// line scan refuses.
fn corner(word: &str, n: Counts) -> Option<(u32, u32, u32)> {
    let mut parts = word.split('/');
    let v = parts.next().filter(|p| !p.is_empty())?;
    let vt = parts.next().unwrap_or("");
    let vn = parts.next().unwrap_or("");
    if parts.next().is_some() {
        return None;
    }
    // An index into `defined` things, 0-based; None when it points nowhere.
    let index = |text: &str, defined: usize| -> Option<Option<u32>> {
        let x: i64 = text.parse().ok()?;
        Some(if x > 0 && x as u64 <= defined as u64 {
            Some((x - 1) as u32)
        } else if x < 0 && x.unsigned_abs() <= defined as u64 {
            Some((defined as i64 + x) as u32)
        } else {
            None
        })
    };
    let v = index(v, n.v)?.unwrap_or(NONE);
    let vt = match vt {
        "" => NONE,
        t => index(t, n.vt)??,
    };
    let vn = match vn {
        "" => NONE,
        t => index(t, n.vn)??,
    };
    Some((v, vt, vn))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_end_with_lines_and_cover_the_text() {
        let line = "v 1 2 3\n";
        let src = line.repeat(100);
        let parts = chunks(&src, 50);
        assert_eq!(parts.len(), 15, "7 lines (56 bytes) a chunk, 2 in the last");
        assert_eq!(parts.concat(), src);
        assert!(parts.iter().all(|p| p.ends_with('\n')));
    }

    #[test]
    fn corners_resolve_relative_indices_and_refuse_what_the_scan_refuses() {
        let n = Counts { v: 4, vt: 2, vn: 1 };
        assert_eq!(corner("1", n), Some((0, NONE, NONE)));
        assert_eq!(corner("-1/2", n), Some((3, 1, NONE)));
        assert_eq!(corner("4//1", n), Some((3, NONE, 0)));
        assert_eq!(
            corner("5/1/1", n),
            Some((NONE, 0, 0)),
            "points nowhere: placeholder"
        );
        assert_eq!(corner("0", n), Some((NONE, NONE, NONE)));
        assert_eq!(corner("1/3", n), None, "texture coordinate past the end");
        assert_eq!(corner("1//2", n), None, "normal past the end");
        assert_eq!(corner("/1", n), None);
        assert_eq!(corner("1/1/1/1", n), None);
        assert_eq!(corner("x", n), None);
    }
}
