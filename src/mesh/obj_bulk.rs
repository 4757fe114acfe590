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

/// Most bytes of text per chunk: enough to keep both passes busy, few enough to balance.
const CHUNK: usize = 1 << 20;

/// Fewest bytes of text per chunk: a small file is cut into several chunks a thread (so
/// that the threads finish together) but not into pieces whose bookkeeping shows.
const MIN_CHUNK: usize = 64 << 10;

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
    let per_thread = src.len() / (4 * rayon::current_num_threads());
    read_in_chunks(path, src, per_thread.clamp(MIN_CHUNK, CHUNK))
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
    let mut words = Words::new(chunk);
    loop {
        match words.next() {
            Some("v") => c.v += 1,
            Some("vt") => c.vt += 1,
            Some("vn") => c.vn += 1,
            Some("f") => tris += words.by_ref().count().saturating_sub(2),
            // A control or non-ASCII byte may be whitespace to tobj's splitting (Unicode's)
            // and not to this one's.
            Some(kw) if left_to_tobj(kw) || !kw.bytes().all(|b| b.is_ascii_graphic()) => {
                return None
            }
            _ => {}
        }
        if !words.next_line() {
            return Some((c, tris));
        }
    }
}

/// The words of a text line by line, as `str::lines` and `str::split_ascii_whitespace`
/// make them (a line's `\r` is whitespace to both): an iterator over the current line's
/// words, and [`Words::next_line`] to go on to the next. One pass over the bytes, which
/// the library's adaptors make two (and call per byte).
struct Words<'a> {
    text: &'a str,
    /// Where the current line goes on.
    at: usize,
}

impl<'a> Words<'a> {
    fn new(text: &'a str) -> Self {
        Words { text, at: 0 }
    }

    /// Moves past the current line's end; false when there is no line after it.
    fn next_line(&mut self) -> bool {
        match newline(self.text.as_bytes(), self.at) {
            Some(i) => {
                self.at = i + 1;
                self.at < self.text.len()
            }
            None => {
                self.at = self.text.len();
                false
            }
        }
    }
}

/// The position of the first `\n` in `bytes` from `from` on, looked for eight bytes at a
/// time (a line's rest is short: a call to memchr costs more).
#[inline]
fn newline(bytes: &[u8], from: usize) -> Option<usize> {
    const ONES: u64 = u64::from_ne_bytes([0x01; 8]);
    const HIGHS: u64 = u64::from_ne_bytes([0x80; 8]);
    const NEWLINES: u64 = u64::from_ne_bytes([b'\n'; 8]);
    let mut i = from;
    while let Some(eight) = bytes.get(i..i + 8) {
        // A byte of x is 0 where the text has '\n'; the lowest flagged byte of `zero` is
        // the first such (a borrow only flags bytes above a zero one).
        let x = u64::from_le_bytes(eight.try_into().unwrap_or_default()) ^ NEWLINES;
        let zero = x.wrapping_sub(ONES) & !x & HIGHS;
        if zero != 0 {
            return Some(i + zero.trailing_zeros() as usize / 8);
        }
        i += 8;
    }
    (bytes[i..].iter().position(|&b| b == b'\n')).map(|k| i + k)
}

impl<'a> Iterator for Words<'a> {
    type Item = &'a str;

    /// The current line's next word, none at its end (which is not passed).
    #[inline]
    fn next(&mut self) -> Option<&'a str> {
        let bytes = self.text.as_bytes();
        let mut i = self.at;
        while i < bytes.len() && matches!(bytes[i], b' ' | b'\t' | b'\r' | b'\x0c') {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        self.at = i;
        // Both ends lie at an ASCII byte or the text's end: character boundaries.
        (i > start).then(|| &self.text[start..i])
    }
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
    let mut words = Words::new(chunk);
    loop {
        match words.next() {
            Some("v") => {
                let (Some(x), Some(y), Some(z), None) =
                    (words.next(), words.next(), words.next(), words.next())
                else {
                    return None;
                };
                out.positions
                    .push(Vec3::new(parse_f32(x)?, parse_f32(y)?, parse_f32(z)?));
                n.v += 1;
            }
            Some("vt") => {
                let (u, v) = (parse_f32(words.next()?)?, parse_f32(words.next()?)?);
                all_numbers(&mut words)?;
                out.texcoords.push(Vec2::new(u, v));
                n.vt += 1;
            }
            Some("vn") => {
                let mut c = [0.0f32; 3];
                for x in &mut c {
                    *x = parse_f32(words.next()?)?;
                }
                all_numbers(&mut words)?;
                out.normals.push(Vec3::from(c));
                n.vn += 1;
            }
            Some("f") => {
                corners.clear();
                let mut in_range = true;
                for w in words.by_ref() {
                    let (v, vt, vn) = corner(w, n)?;
                    in_range &= v != NONE;
                    out.corner_without_vt |= vt == NONE;
                    out.corner_without_vn |= vn == NONE;
                    corners.push((v, vt, vn));
                }
                if corners.len() < 3 {
                    out.short_faces += 1;
                }
                // Fan triangulation from the first corner, as tobj's.
                for k in 1..corners.len().max(2) - 1 {
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
        if !words.next_line() {
            return Some(out);
        }
    }
}

/// Every remaining word parses as a number (the line scan's rule).
fn all_numbers<'a>(mut words: impl Iterator<Item = &'a str>) -> Option<()> {
    words.all(|w| parse_f32(w).is_some()).then_some(())
}

/// `str::parse::<f32>`, with a fast path for the plain decimals that scanners and
/// exporters write (`-0.0378297`, `1416.000000`): where the digits but trailing zeros make
/// a whole number m ≤ 2^24 and at most ten of them follow the point, m and 10^e are exact
/// in f32 and their quotient is the correctly rounded value (Clinger's fast path; the
/// library's parse takes it too, after a general scan), so the bits are the library's.
/// Anything else goes to the library.
#[inline]
fn parse_f32(word: &str) -> Option<f32> {
    const POW10: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];
    let bytes = word.as_bytes();
    let (negative, body) = match bytes {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, bytes),
    };
    let (mut m, mut digits, mut after_point, mut point) = (0u64, 0usize, 0usize, false);
    for &b in body {
        match b {
            b'0'..=b'9' => {
                m = m * 10 + (b - b'0') as u64;
                digits += 1;
                after_point += point as usize;
                // 19 digits stay below 10^19 < 2^64.
                if digits > 19 {
                    return word.parse().ok();
                }
            }
            b'.' if !point => point = true,
            _ => return word.parse().ok(),
        }
    }
    // Trailing zeros after the point change nothing (`1416.000000` is 1416 / 10^0).
    while after_point > 0 && m % 10 == 0 {
        m /= 10;
        after_point -= 1;
    }
    if digits == 0 || m > 1 << 24 || after_point >= POW10.len() {
        return word.parse().ok();
    }
    let x = m as f32 / POW10[after_point];
    Some(if negative { -x } else { x })
}

/// A face corner (`v`, `v/vt`, `v//vn`, `v/vt/vn`) with `n` of each defined so far: its
/// 0-based position index (`NONE` when it points nowhere: the face becomes placeholders),
/// texture coordinate and normal indices (`NONE` when absent); `None` for anything the
/// line scan refuses.
fn corner(word: &str, n: Counts) -> Option<(u32, u32, u32)> {
    let bytes = word.as_bytes();
    // The parts between slashes: at most three.
    let cut = |from: usize| {
        let end = bytes[from..]
            .iter()
            .position(|&b| b == b'/')
            .map_or(bytes.len(), |i| from + i);
        (&bytes[from..end], end)
    };
    let (v, end) = cut(0);
    let (vt, vn) = match end < bytes.len() {
        false => (&[][..], &[][..]),
        true => {
            let (vt, end) = cut(end + 1);
            match end < bytes.len() {
                false => (vt, &[][..]),
                true => {
                    let (vn, end) = cut(end + 1);
                    if end < bytes.len() {
                        return None;
                    }
                    (vt, vn)
                }
            }
        }
    };
    if v.is_empty() {
        return None;
    }
    // An index into `defined` things, 0-based; None when it points nowhere.
    let index = |text: &[u8], defined: usize| -> Option<Option<u32>> {
        let x = parse_i64(text)?;
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
        [] => NONE,
        t => index(t, n.vt)??,
    };
    let vn = match vn {
        [] => NONE,
        t => index(t, n.vn)??,
    };
    Some((v, vt, vn))
}

/// `str::parse::<i64>` of ASCII text, by hand (the library's goes through a generic
/// radix path): an optional sign, then at least one digit; none on overflow.
#[inline]
fn parse_i64(text: &[u8]) -> Option<i64> {
    let (negative, digits) = match text {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, text),
    };
    if digits.is_empty() {
        return None;
    }
    let mut x: i64 = 0;
    for &b in digits {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        // Accumulated on the side of the sign, so that i64::MIN parses as the library's.
        x = x.checked_mul(10)?;
        x = match negative {
            true => x.checked_sub(d as i64)?,
            false => x.checked_add(d as i64)?,
        };
    }
    Some(x)
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
        assert_eq!(corner("+2/-2//", n), None, "four parts");
        assert_eq!(corner("+2/-2/", n), Some((1, 0, NONE)));
        assert_eq!(corner("1/ 1", n), None);
    }

    /// The words of each line, as the library's adaptors make them.
    fn library_words(text: &str) -> Vec<Vec<&str>> {
        let lines: Vec<Vec<&str>> = (text.lines())
            .map(|l| l.split_ascii_whitespace().collect())
            .collect();
        // `Words` sees one (empty) line in an empty text.
        if lines.is_empty() {
            vec![vec![]]
        } else {
            lines
        }
    }

    proptest::proptest! {
        /// `Words` splits lines and words as `str::lines` and `split_ascii_whitespace` do
        /// (every kind of ASCII whitespace, the vertical tab that is not one, non-ASCII
        /// text, `\r\n` and a lone `\r`), whether a line's words are all taken or only the
        /// first (the rest skipped).
        #[test]
        fn words_split_as_the_library_does(
            picks in proptest::collection::vec(0usize..14, 0..80),
            all in proptest::bool::ANY,
        ) {
            const PIECES: [&str; 14] = [
                " ", "\t", "\r", "\n", "\x0b", "\x0c", "v", "1/2", "é", "\r\n", "\x01", "\x1f",
                "-0.0378297", "!",
            ];
            let text: String = picks.iter().map(|&p| PIECES[p]).collect();
            let mut want = library_words(&text);
            if !all {
                want.iter_mut().for_each(|w| w.truncate(1));
            }
            let mut got = Vec::new();
            let mut words = Words::new(&text);
            loop {
                got.push(match all {
                    true => words.by_ref().collect(),
                    false => words.next().into_iter().collect::<Vec<_>>(),
                });
                if !words.next_line() {
                    break;
                }
            }
            proptest::prop_assert_eq!(got, want);
        }

        /// Indices parse as `str::parse::<i64>` parses them, overflow and signs included.
        #[test]
        fn indices_parse_as_the_library_parses_them(
            picks in proptest::collection::vec(0usize..14, 0..24),
        ) {
            const PIECES: [&str; 14] = ["+", "-", "0", "1", "2", "5", "7", "8", "9", "x", " ", "3", "4", "6"];
            let text: String = picks.iter().map(|&p| PIECES[p]).collect();
            proptest::prop_assert_eq!(parse_i64(text.as_bytes()), text.parse::<i64>().ok());
        }
    }

    proptest::proptest! {
        /// Numbers parse to the library's bits: plain decimals (the fast path) and
        /// anything else (signs, points, exponents, too many digits, words that are none).
        #[test]
        fn numbers_parse_as_the_library_parses_them(
            picks in proptest::collection::vec(0usize..16, 0..16),
            digits in proptest::collection::vec(0u8..10, 1..12),
            point in 0usize..13,
            negative in proptest::bool::ANY,
        ) {
            const PIECES: [&str; 16] =
                ["+", "-", "0", "1", "9", "5", ".", "e", "E", "3", "7", "i", "n", "f", "a", "2"];
            let text: String = picks.iter().map(|&p| PIECES[p]).collect();
            let same = |t: &str| {
                parse_f32(t).map(f32::to_bits) == t.parse::<f32>().ok().map(f32::to_bits)
            };
            proptest::prop_assert!(same(&text), "{:?}", text);
            // A decimal with the point anywhere among its digits.
            let mut decimal: String = digits.iter().map(|d| char::from(b'0' + d)).collect();
            decimal.insert(point.min(decimal.len()), '.');
            if negative {
                decimal.insert(0, '-');
            }
            proptest::prop_assert!(same(&decimal), "{:?}", decimal);
        }
    }

    #[test]
    fn numbers_at_the_fast_paths_limits_parse_as_the_library_parses_them() {
        for text in [
            "16777216",
            "16777217",
            "1677721.7",
            "0.0000000001",
            "0.00000000001",
            "-0",
            "-0.0",
            "5.",
            ".5",
            "+.5",
            ".",
            "-",
            "",
            "0.1",
            "0.3",
            "3.4028235e38",
            "1e-45",
            "inf",
            "NaN",
            "0.16777217",
            "9999999",
            "0.9999999999",
            "-0.0378297",
            "1.0.0",
        ] {
            let (got, want) = (parse_f32(text), text.parse::<f32>().ok());
            assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{text:?}");
        }
    }

    #[test]
    fn indices_at_the_limits_parse_as_the_library_parses_them() {
        for text in [
            "9223372036854775807",
            "-9223372036854775808",
            "9223372036854775808",
            "-9223372036854775809",
            "+9223372036854775807",
            "00000000000000000000000000001",
            "-0",
            "+",
            "-",
            "",
            "+-1",
        ] {
            assert_eq!(
                parse_i64(text.as_bytes()),
                text.parse::<i64>().ok(),
                "{text:?}"
            );
        }
    }
}
