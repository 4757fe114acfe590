//! What ply-rs reads past without a word, checked before it reads: a property named twice in
//! one element (its map keeps one, and the columns shift), a list whose count is not an
//! integer type (accepted in ASCII, refused in binary), and — in an ASCII file — a line with
//! more or fewer values than its element's properties call for (the extra ones were
//! ignored). Errors name the header or body line.

use std::collections::HashSet;
use std::io::BufRead;
use std::path::Path;

use crate::error::{Error, Result};

/// The largest header read: a PLY header is a few lines; past this it is no PLY.
const MAX_HEADER: u64 = 1 << 20;

/// One property of an element: a scalar, or a list with its count.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Prop {
    Scalar,
    List,
}

/// An element of the header: its name, its count and its properties in order.
struct Element {
    name: String,
    count: u64,
    props: Vec<Prop>,
}

/// Types a list's count may have: the integers.
const COUNT_TYPES: [&str; 12] = [
    "char", "uchar", "short", "ushort", "int", "uint", "int8", "uint8", "int16", "uint16", "int32",
    "uint32",
];

/// Checks the header of the PLY file `reader` reads, and an ASCII body's value counts.
pub fn check(path: &Path, mut reader: impl BufRead) -> Result<()> {
    let bad = |line: usize, msg: String| Error::input(path, Some(line), msg);
    // The header within its bound (a binary file's lines can be long), then the body.
    let mut header = std::io::Read::take(&mut reader, MAX_HEADER).lines();
    let mut ascii = false;
    let mut elements: Vec<Element> = Vec::new();
    let mut names: HashSet<String> = HashSet::new();
    let mut n = 0usize;
    loop {
        let Some(line) = header.next() else {
            return Err(bad(
                n,
                "no end_header line within 1 MiB: not a PLY file".into(),
            ));
        };
        n += 1;
        let Ok(line) = line else {
            // Not text: ply-rs reports what it finds.
            return Ok(());
        };
        if n == 1 && line.trim_end() != "ply" {
            return Ok(()); // no PLY magic: ply-rs says so
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["format", f, ..] => ascii = *f == "ascii",
            ["element", name, count, ..] => {
                names.clear();
                elements.push(Element {
                    name: name.to_string(),
                    count: count.parse().unwrap_or(0),
                    props: Vec::new(),
                });
            }
            ["property", "list", count_type, _, name, ..] => {
                if !COUNT_TYPES.contains(count_type) {
                    return Err(bad(
                        n,
                        format!("list {name}: its count is a {count_type}, not an integer type"),
                    ));
                }
                add(&mut elements, &mut names, name, Prop::List).map_err(|m| bad(n, m))?;
            }
            ["property", _, name, ..] => {
                add(&mut elements, &mut names, name, Prop::Scalar).map_err(|m| bad(n, m))?
            }
            _ => {}
        }
    }
    if !ascii {
        return Ok(());
    }
    let mut lines = reader.lines();
    // The body: one line an element, as many values as its properties call for.
    for e in &elements {
        for _ in 0..e.count {
            let Some(Ok(line)) = lines.next() else {
                return Ok(()); // a short file: ply-rs names it
            };
            n += 1;
            // Where the element's values end on the line, by its properties (a list count
            // is arithmetic here, never a loop over a count the file claims).
            let tokens: Vec<&str> = line.split_whitespace().collect();
            let mut end = 0usize;
            for p in &e.props {
                end = match p {
                    Prop::Scalar => end.saturating_add(1),
                    Prop::List => {
                        let count = tokens.get(end).and_then(|t| t.parse::<usize>().ok());
                        end.saturating_add(1).saturating_add(count.unwrap_or(0))
                    }
                };
            }
            let extra = tokens.len().saturating_sub(end);
            if extra > 0 {
                return Err(bad(
                    n,
                    format!(
                        "{extra} more values than the '{}' element's properties: a value too \
                         many, or a property missing from the header",
                        e.name
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Adds property `name` to the last element, refusing a second of the same name.
fn add(
    elements: &mut [Element],
    names: &mut HashSet<String>,
    name: &str,
    prop: Prop,
) -> std::result::Result<(), String> {
    let Some(e) = elements.last_mut() else {
        return Err(format!("property {name} before any element"));
    };
    if !names.insert(name.to_string()) {
        return Err(format!(
            "the '{}' element names property '{name}' twice: its columns would shift",
            e.name
        ));
    }
    e.props.push(prop);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ply(body: &str) -> String {
        let e = check(Path::new("m.ply"), body.as_bytes());
        e.err().map(|e| e.to_string()).unwrap_or_default()
    }

    const HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

    #[test]
    fn duplicates_float_counts_and_extra_values_are_named() {
        assert_eq!(ply(&format!("{HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")), "");
        let dup = HEAD.replace("property float y", "property float x");
        assert!(ply(&dup).contains("m.ply:5: the 'vertex' element names property 'x' twice"));
        let float = HEAD.replace("list uchar int", "list float int");
        assert!(ply(&float).contains("m.ply:8: list vertex_indices: its count is a float"));
        let extra = ply(&format!("{HEAD}0 0 0\n1 0 0 7\n0 1 0\n3 0 1 2\n"));
        assert!(
            extra.contains("m.ply:11: 1 more values than the 'vertex'"),
            "{extra}"
        );
        let face = ply(&format!("{HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 2 9\n"));
        assert!(face.contains("m.ply:13:"), "{face}");
        // Binary bodies are ply-rs's to read; their headers are still checked.
        let binary = HEAD.replace("ascii", "binary_little_endian");
        assert_eq!(ply(&binary), "");
    }
}
