//! The house flows one way: each top-level module of the library may use only the modules
//! above it in [`ORDER`] (docs/src/architecture.md draws the same graph). The test reads
//! the sources, so a `use crate::render::…` in `gpu` — or a new module left out of the
//! order — fails here, naming the file and the line. Unit-test modules (`#[cfg(test)] mod
//! tests { … }`) are consumers of their module, not part of it, and comments are not code:
//! both are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The top-level modules from the bottom of the house to the top.
const ORDER: &[&str] = &[
    "error", "util", "limits", "input", "output", // leaves
    "geometry", "mesh", "camera", "accel", "embree", "gpu", "device", "trace", "render",
    "accuracy", "bench",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level modules `lib.rs` declares.
fn declared_modules() -> Vec<String> {
    let lib = fs::read_to_string("src/lib.rs").unwrap();
    lib.lines()
        .filter_map(|l| {
            let l = l.trim();
            let l = l.strip_prefix("pub ").unwrap_or(l);
            l.strip_prefix("mod ")?
                .strip_suffix(';')
                .map(str::to_string)
        })
        .collect()
}

/// `source` without comments and without `#[cfg(test)] mod … { … }` blocks, line
/// numbers kept (removed text becomes blanks).
fn code_only(source: &str) -> String {
    let mut out: Vec<String> = source
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => l[..i].to_string(),
            None => l.to_string(),
        })
        .collect();
    let mut i = 0;
    while i < out.len() {
        let is_test_mod = out[i].trim() == "#[cfg(test)]"
            && out
                .get(i + 1)
                .is_some_and(|n| n.trim_start().starts_with("mod "));
        if !is_test_mod {
            i += 1;
            continue;
        }
        // Blank from the attribute to the brace that closes the module.
        let mut depth = 0i32;
        let mut opened = false;
        let mut j = i;
        while j < out.len() {
            for c in out[j].chars() {
                match c {
                    '{' => (depth, opened) = (depth + 1, true),
                    '}' => depth -= 1,
                    _ => {}
                }
            }
            let done = opened && depth == 0 || out[j].trim_end().ends_with(';') && !opened;
            out[j].clear();
            j += 1;
            if done {
                break;
            }
        }
        i = j;
    }
    out.join("\n")
}

/// Every top-level module a line of code names through `crate::` (paths and `crate::{…}`
/// groups), with its line number.
fn uses(code: &str, modules: &[String]) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    let text: Vec<&str> = code.lines().collect();
    for (n, line) in text.iter().enumerate() {
        let mut rest = *line;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                // A group may run over lines: collect to its closing brace.
                let mut joined = group.to_string();
                let mut k = n + 1;
                while !joined.contains('}') && k < text.len() {
                    joined.push_str(text[k]);
                    k += 1;
                }
                for item in joined.split('}').next().unwrap().split(',') {
                    let name = item.trim().split("::").next().unwrap().trim();
                    if modules.iter().any(|m| m == name) {
                        found.push((name.to_string(), n + 1));
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if modules.contains(&name) {
                    found.push((name, n + 1));
                }
            }
        }
    }
    found
}

/// The top-level module a source file belongs to.
fn module_of(path: &Path) -> Option<String> {
    let rel = path.strip_prefix("src").ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    Some(first.trim_end_matches(".rs").to_string())
}

#[test]
fn every_module_is_placed_in_the_order() {
    let declared = declared_modules();
    assert!(declared.len() >= 10, "lib.rs declares {declared:?}");
    let missing: Vec<_> = declared
        .iter()
        .filter(|m| !ORDER.contains(&m.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "modules {missing:?} are not placed in tests/module_graph.rs's ORDER: put each where \
         it belongs in the house (below everything that uses it)"
    );
}

#[test]
fn modules_depend_one_way() {
    let modules = declared_modules();
    let rank = |m: &str| ORDER.iter().position(|o| *o == m);
    let mut files = Vec::new();
    rust_files(Path::new("src"), &mut files);
    files.sort();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut upward = Vec::new();
    for file in &files {
        let Some(from) = module_of(file) else {
            continue;
        };
        if !modules.contains(&from) {
            continue; // main.rs, cmd/: the binary, above everything
        }
        let code = code_only(&fs::read_to_string(file).unwrap());
        for (to, line) in uses(&code, &modules) {
            if to == from {
                continue;
            }
            graph.entry(from.clone()).or_default().insert(to.clone());
            if rank(&to) > rank(&from) {
                upward.push(format!("{}:{line}: {from} uses {to}", file.display()));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "modules must only use modules below them ({ORDER:?}, bottom first):\n{}",
        upward.join("\n")
    );
    // No circle either (implied by the order; said in the graph's own terms).
    for start in graph.keys() {
        let mut stack = vec![(start.clone(), vec![start.clone()])];
        while let Some((at, path)) = stack.pop() {
            for next in graph.get(&at).into_iter().flatten() {
                assert!(next != start, "circle: {} -> {next}", path.join(" -> "));
                if !path.contains(next) {
                    let mut p = path.clone();
                    p.push(next.clone());
                    stack.push((next.clone(), p));
                }
            }
        }
    }
}

#[test]
fn the_checker_sees_an_upward_use() {
    // The test above can fail: a use of `render` from `gpu`, grouped or not, is found, and
    // one inside a unit-test module or a comment is not.
    let modules: Vec<String> = ["gpu", "render", "geometry"].map(String::from).to_vec();
    let src = "use crate::render::Material;\n\
               use crate::{\n    geometry::Ray,\n    render::Light,\n};\n\
               // crate::render in a comment\n\
               #[cfg(test)]\nmod tests {\n    use crate::render::x;\n}\n";
    let found = uses(&code_only(src), &modules);
    assert_eq!(
        found,
        [
            ("render".to_string(), 1),
            ("geometry".to_string(), 2),
            ("render".to_string(), 2)
        ]
    );
}
