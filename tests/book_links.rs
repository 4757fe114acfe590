//! The README and the book (docs/src, built by mdBook with scripts/book.sh) hold together:
//! every relative link and image in README.md and docs/src/**/*.md names a file that exists
//! (resolved from the linking file's folder; `#fragment` stripped), every `#fragment` into a
//! markdown page names one of its headings, every page SUMMARY.md lists exists, every page
//! under docs/src is listed in SUMMARY.md, README.md stays a front door of at most 200
//! lines, and the library page's quick start is the doctest of src/lib.rs. All failures are
//! listed together. Links in code blocks and code spans are not links.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Component, Path, PathBuf};

const README_MAX_LINES: usize = 200;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn book_src() -> PathBuf {
    root().join("docs").join("src")
}

/// Every `.md` file under `dir`, sorted.
fn markdown_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            markdown_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "md") {
            out.push(path);
        }
    }
}

/// The file's text with fenced code blocks and inline code spans blanked out (lengths and
/// line breaks kept, so positions and line numbers stay right).
fn without_code(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut fence: Option<String> = None;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        let marker: String = trimmed
            .chars()
            .take_while(|&c| c == '`' || c == '~')
            .collect();
        let is_fence =
            marker.len() >= 3 && marker.chars().all(|c| c == marker.chars().next().unwrap());
        match &fence {
            Some(open) => {
                if is_fence
                    && marker.starts_with(open.as_str())
                    && trimmed[marker.len()..].trim().is_empty()
                {
                    fence = None;
                }
                out.extend(line.chars().map(|c| if c == '\n' { '\n' } else { ' ' }));
            }
            None if is_fence => {
                fence = Some(marker);
                out.extend(line.chars().map(|c| if c == '\n' { '\n' } else { ' ' }));
            }
            None => out.push_str(&blank_code_spans(line)),
        }
    }
    out
}

/// One line with its `code spans` blanked.
fn blank_code_spans(line: &str) -> String {
    let chars: Vec<char> = line.chars().collect();
    let mut out: Vec<char> = chars.clone();
    let mut i = 0;
    while i < chars.len() {
        if chars[i] != '`' {
            i += 1;
            continue;
        }
        let mut n = 0;
        while i + n < chars.len() && chars[i + n] == '`' {
            n += 1;
        }
        // Find the closing run of exactly n backticks.
        let mut j = i + n;
        let mut close = None;
        while j < chars.len() {
            if chars[j] == '`' {
                let mut m = 0;
                while j + m < chars.len() && chars[j + m] == '`' {
                    m += 1;
                }
                if m == n {
                    close = Some(j);
                    break;
                }
                j += m;
            } else {
                j += 1;
            }
        }
        match close {
            Some(j) => {
                for c in out.iter_mut().take(j + n).skip(i) {
                    *c = ' ';
                }
                i = j + n;
            }
            None => i += n,
        }
    }
    out.into_iter().collect()
}

/// A link found in a markdown file: its target as written, and the line it is on.
struct Link {
    target: String,
    line: usize,
}

/// Inline links and images `[text](target "title")`, reference definitions
/// `[label]: target`, and HTML `src="…"` / `href="…"` attributes, outside code.
fn links(text: &str) -> Vec<Link> {
    let text = without_code(text);
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        // Reference definitions.
        let t = line.trim_start();
        if let Some(rest) = t.strip_prefix('[') {
            if let Some(end) = rest.find("]:") {
                if !rest[..end].contains(']') {
                    let target = rest[end + 2..].split_whitespace().next().unwrap_or("");
                    let target = target.trim_start_matches('<').trim_end_matches('>');
                    found.push(Link {
                        target: target.to_string(),
                        line: line_no,
                    });
                    continue;
                }
            }
        }
        // Inline links and images: every `](` opens a target.
        let bytes = line.as_bytes();
        let mut i = 0;
        while let Some(k) = line[i..].find("](") {
            let start = i + k + 2;
            let mut depth = 1;
            let mut j = start;
            while j < bytes.len() {
                match bytes[j] {
                    b'(' => depth += 1,
                    b')' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    _ => {}
                }
                j += 1;
            }
            let inside = line[start..j.min(line.len())].trim();
            let target = if let Some(rest) = inside.strip_prefix('<') {
                rest.split('>').next().unwrap_or("")
            } else {
                inside.split_whitespace().next().unwrap_or("")
            };
            found.push(Link {
                target: target.to_string(),
                line: line_no,
            });
            i = j.min(line.len());
            if i >= line.len() {
                break;
            }
        }
        // HTML attributes.
        for attr in ["src=\"", "href=\""] {
            let mut rest = line;
            while let Some(k) = rest.find(attr) {
                let after = &rest[k + attr.len()..];
                let end = after.find('"').unwrap_or(after.len());
                found.push(Link {
                    target: after[..end].to_string(),
                    line: line_no,
                });
                rest = &after[end..];
            }
        }
    }
    found
}

/// Whether a target leaves the repository (a URL) or stays in the page (`#anchor` only).
fn is_external(target: &str) -> bool {
    let lower = target.to_ascii_lowercase();
    lower.starts_with("http://")
        || lower.starts_with("https://")
        || lower.starts_with("mailto:")
        || lower.contains("://")
}

/// `%20` and friends, decoded.
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).unwrap_or("");
            if let Ok(b) = u8::from_str_radix(hex, 16) {
                out.push(b);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// `a/b/../c` → `a/c`, without touching the file system.
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            Component::CurDir => {}
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// A heading's anchor as mdBook and GitHub make it: lowercase, letters, digits, `-` and `_`
/// kept, spaces to `-`, everything else dropped; inline code, emphasis and link targets
/// reduced to their text.
fn anchor_of(heading: &str) -> String {
    // [text](target) → text
    let mut text = String::new();
    let mut rest = heading;
    while let Some(k) = rest.find("](") {
        let (before, after) = rest.split_at(k);
        text.push_str(before);
        let close = after.find(')').unwrap_or(after.len() - 1);
        rest = &after[close + 1..];
    }
    text.push_str(rest);
    text.chars()
        .flat_map(char::to_lowercase)
        .filter_map(|c| match c {
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            c if c.is_whitespace() => Some('-'),
            _ => None,
        })
        .collect()
}

/// The anchors of a markdown file's headings (ATX `#` headings outside code), with `-1`,
/// `-2` … for repeats, as mdBook and GitHub number them.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let code_free = without_code_fences_only(text);
    for line in code_free.lines() {
        let t = line.trim_start();
        let hashes = t.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || hashes > 6 || !t[hashes..].starts_with(' ') {
            continue;
        }
        let base = anchor_of(t[hashes..].trim().trim_end_matches('#').trim());
        let mut id = base.clone();
        let mut k = 1;
        while seen.contains(&id) {
            id = format!("{base}-{k}");
            k += 1;
        }
        seen.insert(id);
    }
    seen
}

/// The text with fenced code blocks blanked but code spans kept (headings keep their code).
fn without_code_fences_only(text: &str) -> String {
    let mut out = String::new();
    let mut in_fence = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("```") || t.starts_with("~~~") {
            in_fence = !in_fence;
            out.push('\n');
            continue;
        }
        if !in_fence {
            out.push_str(line);
        }
        out.push('\n');
    }
    out
}

/// The pages README.md and the book consist of.
fn pages() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    markdown_files(&book_src(), &mut files);
    files
}

/// Every broken relative link in `files`, as `FILE:LINE: target (why)`.
fn broken_links(files: &[PathBuf]) -> Vec<String> {
    let root = root();
    let mut broken = Vec::new();
    for file in files {
        let text = fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let shown = file
            .strip_prefix(&root)
            .unwrap_or(file)
            .display()
            .to_string();
        for link in links(&text) {
            let target = link.target.trim();
            if target.is_empty() {
                broken.push(format!("{shown}:{}: an empty link target", link.line));
                continue;
            }
            if is_external(target) {
                continue;
            }
            let (path_part, fragment) = match target.split_once('#') {
                Some((p, f)) => (p, Some(f)),
                None => (target, None),
            };
            let path_part = path_part.split('?').next().unwrap_or("");
            let resolved = if path_part.is_empty() {
                file.clone()
            } else if path_part.starts_with('/') {
                broken.push(format!(
                    "{shown}:{}: {target} (an absolute path: links must be relative)",
                    link.line
                ));
                continue;
            } else {
                normalise(&file.parent().unwrap().join(percent_decode(path_part)))
            };
            if !resolved.exists() {
                broken.push(format!(
                    "{shown}:{}: {target} (no such file: {})",
                    link.line,
                    resolved.strip_prefix(&root).unwrap_or(&resolved).display()
                ));
                continue;
            }
            if let Some(fragment) = fragment.filter(|f| !f.is_empty()) {
                if resolved.extension().is_some_and(|e| e == "md") {
                    let page = fs::read_to_string(&resolved).unwrap();
                    if !anchors(&page).contains(&percent_decode(fragment)) {
                        broken.push(format!(
                            "{shown}:{}: {target} (no heading #{fragment} in {})",
                            link.line,
                            resolved.strip_prefix(&root).unwrap_or(&resolved).display()
                        ));
                    }
                }
            }
        }
    }
    broken
}

#[test]
fn every_relative_link_and_image_resolves() {
    let broken = broken_links(&pages());
    assert!(
        broken.is_empty(),
        "{} broken link(s) in README.md and docs/src:\n  {}",
        broken.len(),
        broken.join("\n  ")
    );
}

/// The pages SUMMARY.md lists, relative to docs/src.
fn summary_pages() -> Vec<(usize, String)> {
    let summary = fs::read_to_string(book_src().join("SUMMARY.md")).expect("docs/src/SUMMARY.md");
    links(&summary)
        .into_iter()
        .filter(|l| !l.target.is_empty() && !is_external(&l.target))
        .map(|l| (l.line, l.target.split('#').next().unwrap().to_string()))
        .collect()
}

#[test]
fn summary_lists_every_page_and_every_listed_page_exists() {
    let src = book_src();
    let listed = summary_pages();
    let mut problems = Vec::new();
    let mut listed_set = BTreeSet::new();
    for (line, page) in &listed {
        let path = normalise(&src.join(page));
        if !path.is_file() {
            problems.push(format!("docs/src/SUMMARY.md:{line}: {page} does not exist"));
        }
        listed_set.insert(path);
    }
    let mut files = Vec::new();
    markdown_files(&src, &mut files);
    for file in files {
        if file.file_name().is_some_and(|n| n == "SUMMARY.md") {
            continue;
        }
        if !listed_set.contains(&file) {
            problems.push(format!(
                "{} is not listed in docs/src/SUMMARY.md (mdBook would leave it out of the book)",
                file.strip_prefix(root()).unwrap_or(&file).display()
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "the book's pages:\n  {}",
        problems.join("\n  ")
    );
}

#[test]
fn readme_is_a_front_door() {
    let readme = fs::read_to_string(root().join("README.md")).expect("README.md");
    let lines = readme.lines().count();
    assert!(
        lines <= README_MAX_LINES,
        "README.md has {lines} lines; keep it at most {README_MAX_LINES} and move the rest into \
         the book (docs/src)"
    );
}

// The checker checks itself: a link it should catch, and links it should leave alone.
#[test]
fn the_link_finder_sees_links_and_ignores_code() {
    let text = "See [a](a.md), ![img](images/x.png \"title\") and [b][ref].\n\
                [ref]: other.md#part\n\
                `[not](code.md)` and <img src=\"pic.png\">\n\
                ```\n[also not](fenced.md)\n```\n\
                [nested `code`](n.md) [url](https://example.com) [anchor](#here)\n";
    let targets: Vec<String> = links(text).into_iter().map(|l| l.target).collect();
    assert_eq!(
        targets,
        [
            "a.md",
            "images/x.png",
            "other.md#part",
            "pic.png",
            "n.md",
            "https://example.com",
            "#here"
        ]
    );
    assert_eq!(
        anchor_of("The CPU twins: four-lane hits and the SAH collapse"),
        "the-cpu-twins-four-lane-hits-and-the-sah-collapse"
    );
    assert_eq!(anchor_of("`lancer heatmap`"), "lancer-heatmap");
    assert_eq!(anchor_of("cwbvh's subgroup mode"), "cwbvhs-subgroup-mode");
}

#[test]
fn a_broken_link_is_caught() {
    let dir = std::env::temp_dir().join(format!("lancer-book-links-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    let page = dir.join("page.md");
    fs::write(
        &page,
        "# Title\n\n[fine](page.md#title) [gone](missing.md) [bad](page.md#nope)\n",
    )
    .unwrap();
    let broken = broken_links(std::slice::from_ref(&page));
    fs::remove_dir_all(&dir).unwrap();
    assert_eq!(broken.len(), 2, "{broken:?}");
    assert!(broken[0].contains("missing.md"), "{broken:?}");
    assert!(broken[1].contains("#nope"), "{broken:?}");
}

/// The first fenced code block of `text`, without its fence lines.
fn first_code_block(lines: &[&str]) -> Option<Vec<String>> {
    let start = lines
        .iter()
        .position(|l| l.trim_start().starts_with("```"))?;
    let len = lines[start + 1..]
        .iter()
        .position(|l| l.trim_start().starts_with("```"))?;
    Some(
        lines[start + 1..start + 1 + len]
            .iter()
            .map(|l| l.to_string())
            .collect(),
    )
}

#[test]
fn the_library_page_shows_the_quick_start_doctest() {
    let lib = fs::read_to_string(root().join("src/lib.rs")).expect("src/lib.rs");
    let doc: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect();
    let page = fs::read_to_string(book_src().join("library.md")).expect("docs/src/library.md");
    let page: Vec<&str> = page.lines().collect();
    let doctest = first_code_block(&doc).expect("a quick-start doctest in src/lib.rs");
    let shown = page
        .iter()
        .position(|l| l.starts_with("```rust"))
        .and_then(|i| first_code_block(&page[i..]))
        .expect("a ```rust code block in docs/src/library.md");
    assert_eq!(
        shown, doctest,
        "docs/src/library.md's quick start differs from the doctest in src/lib.rs: copy the \
         doctest into the page"
    );
}
