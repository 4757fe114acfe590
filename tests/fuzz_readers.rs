//! Hostile bytes for every reader: random bytes, grammar-shaped garbage and mutations of the
//! real files (scenes/*.toml, .obj, .mtl and the heads of ../shared/models/*.obj; small PLY
//! and glTF files written by tests/common/writers.rs) fed to the OBJ, MTL, PLY, glTF, TOML
//! scene, ray and hit file readers through the library API. Each call must
//! return Ok or Err: a panic or a hang fails the test, naming the reader and the input, which
//! is also saved under target/tmp/fuzz_readers/.
//!
//! A fixed seed and a modest number of cases keep the file fast (a few seconds in release);
//! `PROPTEST_CASES=N` and `PROPTEST_RNG_SEED=S` explore further.

mod common;

use std::cell::RefCell;
use std::io::Write;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Once};
use std::time::Duration;

use glam::Vec3;
use lancer::camera::Camera;
use lancer::geometry::{Ray, Triangle};
use lancer::mesh::{load_mesh, load_obj, load_obj_scene, Mesh};
use lancer::trace::files::{read_hits, read_rays};
use lancer::{Device, Query, RenderOptions, RenderScene, Tracer, TracerOptions};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestCaseError, TestError, TestRunner};

// ---------------------------------------------------------------------------------------------
// The harness: each reader call runs on its own thread under catch_unwind, with a time limit.

/// A call that takes longer than this is a hang.
const HANG_LIMIT: Duration = Duration::from_secs(20);

/// Name of the threads that run reader calls: their panics are recorded, not printed.
const WORKER: &str = "fuzz-case";

thread_local! {
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Panics on worker threads are recorded (message and location) for the failure report
/// instead of being printed once per shrinking step; other panics print as usual.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if std::thread::current().name() == Some(WORKER) {
                LAST_PANIC.with(|p| *p.borrow_mut() = Some(info.to_string()));
            } else {
                previous(info);
            }
        }));
    });
}

/// The files of one case: (file name, bytes); the first is the one being fuzzed.
type Files = Vec<(String, Vec<u8>)>;

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Saves a failing input under target/tmp/fuzz_readers/READER-HASH/ and returns that folder.
fn save_failure(reader: &str, files: &Files) -> PathBuf {
    let key = fnv(&files
        .iter()
        .flat_map(|(_, b)| b.clone())
        .collect::<Vec<u8>>());
    let safe: String = reader
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("fuzz_readers")
        .join(format!("{safe}-{key:016x}"));
    let _ = std::fs::create_dir_all(&dir);
    for (name, bytes) in files {
        let _ = std::fs::write(dir.join(name), bytes);
    }
    dir
}

/// The start of the input, escaped, for the failure message.
fn preview(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(600)])
        .escape_debug()
        .to_string();
    if bytes.len() > 600 {
        format!("{text}… ({} bytes in all)", bytes.len())
    } else {
        text
    }
}

/// Runs `call` (one reader on one input) on a worker thread. A panic becomes a test case
/// failure naming `reader`, the panic and the input; a hang ends the test binary at once
/// (after printing and saving the input), since shrinking a hang would take forever.
fn guarded<T: Send + 'static>(
    reader: &str,
    files: &Files,
    call: impl FnOnce() -> T + Send + 'static,
) -> Result<T, TestCaseError> {
    install_panic_hook();
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name(WORKER.into())
        .spawn(move || {
            let r = std::panic::catch_unwind(AssertUnwindSafe(call)).map_err(|payload| {
                LAST_PANIC
                    .with(|p| p.borrow_mut().take())
                    .unwrap_or_else(|| {
                        payload
                            .downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| payload.downcast_ref::<String>().cloned())
                            .unwrap_or_else(|| "panic with a non-string payload".into())
                    })
            });
            let _ = tx.send(r);
        })
        .expect("spawn a worker thread");
    match rx.recv_timeout(HANG_LIMIT) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(panic)) => {
            let dir = save_failure(reader, files);
            Err(TestCaseError::fail(format!(
                "{reader} PANICKED: {panic}\n  input saved in {}\n  {}: \"{}\"",
                dir.display(),
                files[0].0,
                preview(&files[0].1)
            )))
        }
        Err(_) => {
            let dir = save_failure(reader, files);
            // Straight to the process's stderr: the test harness captures eprintln!.
            let _ = writeln!(
                std::io::stderr(),
                "\nfuzz_readers: {reader} HUNG (no answer in {HANG_LIMIT:?})\n  input saved in {}\n  {}: \"{}\"",
                dir.display(),
                files[0].0,
                preview(&files[0].1)
            );
            std::process::exit(3);
        }
    }
}

/// The runner's settings: a fixed seed and `cases` cases, unless the environment says
/// otherwise; no regression files (the failing input is saved in target/tmp instead).
fn config(cases: u32) -> Config {
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    Config {
        cases: env("PROPTEST_CASES").map_or(cases, |c| c as u32),
        rng_seed: RngSeed::Fixed(env("PROPTEST_RNG_SEED").unwrap_or(0x1a_c3e5)),
        failure_persistence: None,
        max_shrink_iters: 2000,
        max_shrink_time: 30_000,
        ..Config::default()
    }
}

fn run_property<S: Strategy>(
    name: &str,
    cases: u32,
    strategy: S,
    test: impl Fn(S::Value) -> Result<(), TestCaseError>,
) where
    S::Value: std::fmt::Debug,
{
    let mut runner = TestRunner::new(config(cases));
    match runner.run(&strategy, test) {
        Ok(()) => {}
        Err(TestError::Fail(why, value)) => {
            let mut shown = format!("{value:?}");
            if shown.len() > 3000 {
                shown.truncate(3000);
                shown.push('…');
            }
            panic!("{name}: {why}\n  minimal failing case: {shown}");
        }
        Err(TestError::Abort(why)) => panic!("{name}: aborted: {why}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Inputs: the corpus of real files, and mutations of them.

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Largest model head: the first ~20 KB, cut at a line end.
const HEAD: usize = 20_000;

fn head(bytes: Vec<u8>) -> Vec<u8> {
    if bytes.len() <= HEAD {
        return bytes;
    }
    let cut = bytes[..HEAD]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(HEAD, |i| i + 1);
    bytes[..cut].to_vec()
}

/// Every file in scenes/ with extension `ext`, by name.
fn scene_files(ext: &str) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(repo("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, head(std::fs::read(&p).unwrap()))
        })
        .collect();
    out.sort();
    out
}

/// A synthetic OBJ with every statement the loader handles: vt, vn, negative indices,
/// polygons, groups, points and lines, materials.
const SYNTH_OBJ: &str = "\
# every statement
mtllib cornell-box.mtl
o a
g g1
s 1
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1.0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
vn 0 0 -1
usemtl white
f 1/1/1 2/2/1 3/3/1 4/4/1
usemtl light
f -5/-4/-2 -4/-3/-2 -1/-1/-1
f 1//2 2//2 5//2
f 2 3 5
l 1 2
p 3
usemtl nothere
f 1/1 3/3 4/4
";

/// The OBJ corpus: scenes/*.obj, the heads of ../shared/models/*.obj and SYNTH_OBJ.
fn obj_corpus() -> Vec<(String, Vec<u8>)> {
    let mut out = scene_files("obj");
    // common::model insists in CI that ../shared/models is there.
    if let Some(teapot) = common::model("teapot.obj") {
        let dir = teapot.parent().unwrap().to_path_buf();
        let mut models: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "obj"))
            .collect();
        models.sort();
        for p in models {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            out.push((name, head(std::fs::read(&p).unwrap())));
        }
    }
    out.push(("synthetic.obj".into(), SYNTH_OBJ.as_bytes().to_vec()));
    out
}

/// An MTL with the statements the renderer reads: Kd, map_Kd, Ke, Ks, illum 5 and 7, Ni.
const SYNTH_MTL: &str = "\
# every statement the renderer reads
newmtl white
Ka 0 0 0
Kd 0.5 0.5 0.5
map_Kd checker.png
newmtl red
Kd 0.9 0.1 0.1
Ks 0.2 0.2 0.2
Ns 10
d 1
Tr 0
newmtl green
illum 5
Ks 0.9 0.9 0.9
newmtl light
Ke 4 4 4
Kd 0.8 0.8 0.8
newmtl glass
illum 7
Ni 1.5
";

fn mtl_corpus() -> Vec<(String, Vec<u8>)> {
    let mut out = scene_files("mtl");
    out.push(("synthetic.mtl".into(), SYNTH_MTL.as_bytes().to_vec()));
    out
}

/// The OBJ that names the fuzzed MTL: one textured triangle per material of the corpus.
const MTL_USER_OBJ: &str = "\
mtllib x.mtl
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
vt 0 0
vt 1 0
vt 0 1
vt 1 1
vn 0 0 1
usemtl white
f 1/1/1 2/2/1 3/3/1
usemtl red
f 2/2/1 4/4/1 3/3/1
usemtl green
f 1/1 2/2 4/4
usemtl light
f 1 4 3
usemtl glass
f 3 2 1
usemtl a
f 1 3 4
";

/// A scene using every key of the format, in the fuzz folder (beside cornell-box.obj/.mtl
/// and checker.png).
const SYNTH_TOML: &str = r#"
[camera]
position = [0.0, 1.5, 4.0]
look_at = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov = 45.0
width = 64
height = 48

[render]
integrator = "ao"
max_bounces = 3
spp = 4
seed = 7
background = [0.1, 0.2, 0.3]
ao_distance = 0.5

[materials.tex]
type = "diffuse"
texture = "checker.png"

[materials.plain]
type = "diffuse"
albedo = [0.5, 0.4, 0.3]

[materials.mirror]
type = "mirror"
albedo = [0.9, 0.9, 0.9]

[materials.glass]
type = "glass"
ior = 1.5
albedo = [1.0, 1.0, 1.0]

[materials.lamp]
type = "emissive"
emission = [5.0, 5.0, 5.0]
two_sided = true

[[objects]]
shape = "quad"
material = "tex"
scale = 4.0

[[objects]]
shape = "sphere"
material = "glass"
segments = 8
scale = [0.5, 0.5, 0.5]
rotate = [10.0, 20.0, 30.0]
translate = [-0.5, 0.5, 0.0]

[[objects]]
shape = "box"
material = "mirror"
scale = 0.3
translate = [0.6, 0.3, 0.0]

[[objects]]
shape = "quad"
material = "lamp"
rotate = [180.0, 0.0, 0.0]
translate = [0.0, 2.0, 0.0]

[[objects]]
mesh = "cornell-box.obj"
scale = 0.001
translate = [1.0, 0.0, -1.0]

[[objects]]
mesh = "cornell-box.obj"
material = "plain"
scale = 0.001

[[lights]]
type = "point"
position = [1.0, 3.0, 1.0]
color = [1.0, 0.9, 0.8]
intensity = 3.0

[[lights]]
type = "directional"
direction = [-0.5, -1.0, -0.3]
intensity = 2.0
"#;

fn toml_corpus() -> Vec<(String, Vec<u8>)> {
    let mut out = scene_files("toml");
    out.push(("synthetic.toml".into(), SYNTH_TOML.as_bytes().to_vec()));
    out
}

/// Tokens spliced in: non-finite and out-of-range numbers, huge integers, NUL, invalid
/// UTF-8, line ends, punctuation the formats give meaning to, and statements.
const TOKENS: &[&[u8]] = &[
    b"nan",
    b"NaN",
    b"-nan",
    b"inf",
    b"-inf",
    b"+inf",
    b"infinity",
    b"-1e39",
    b"1e39",
    b"1e30",
    b"-1e30",
    b"1e13",
    b"-1e13",
    b"3.4028236e38",
    b"1e-45",
    b"1e-300",
    b"0",
    b"-0",
    b"0.0",
    b"-0.0",
    b"1",
    b"-1",
    b"2",
    b"3",
    b"0.5",
    b"4294967295",
    b"4294967296",
    b"-4294967296",
    b"2147483648",
    b"18446744073709551615",
    b"18446744073709551616",
    b"9223372036854775807",
    b"-9223372036854775808",
    b"1000000",
    b"99999999999999999999999999999999999999999",
    b"0x10",
    b"1_000",
    b"\0",
    b"\xff\xfe",
    b"\xc3",
    b"\xed\xa0\x80",
    b"\xef\xbb\xbf",
    b"\n",
    b"\r\n",
    b"\r",
    b"\t",
    b" ",
    b"\\",
    b"\\u0000",
    b"\"",
    b"'",
    b"\"\"\"",
    b"[",
    b"]",
    b"[]",
    b"{",
    b"}",
    b"{}",
    b"=",
    b",",
    b".",
    b"#",
    b"/",
    b"//",
    b"1/1/1",
    b"-1/-1/-1",
    b"0/0/0",
    b"1//1",
    b"2/2/2/2",
    b"f 1 2 3",
    b"f 1 2",
    b"f -1 -2 -3",
    b"f 0 0 0",
    b"f 99999 1 2",
    b"v 1e39 0 0",
    b"v nan nan nan",
    b"vt nan",
    b"vn 0 0 0",
    b"mtllib x.mtl",
    b"mtllib .",
    b"mtllib cornell-box.mtl",
    b"mtllib ",
    b"usemtl nothere",
    b"usemtl ",
    b"newmtl ",
    b"newmtl white",
    b"Kd nan 1 1",
    b"Kd 2 2 2",
    b"Kd -1 0 0",
    b"Ke inf 1 1",
    b"Ke 1e39 1 1",
    b"Ni 0",
    b"illum 5",
    b"illum 7",
    b"illum 4294967296",
    b"map_Kd checker.png",
    b"map_Kd x.mtl",
    b"map_Kd .",
    b"map_Kd missing.png",
    b"[[objects]]",
    b"[[lights]]",
    b"[camera]",
    b"[render]",
    b"[materials.x]",
    b"shape = \"sphere\"",
    b"segments = 2",
    b"segments = 4294967295",
    b"mesh = \"cornell-box.obj\"",
    b"mesh = \".\"",
    b"mesh = \"missing.obj\"",
    b"texture = \"checker.png\"",
    b"texture = \"cornell-box.mtl\"",
    b"material = \"x\"",
    b"type = \"emissive\"",
    b"scale = 0",
    b"scale = [0, 1, 1]",
    b"up = [0, 0, 0]",
    b"fov = 180",
    b"spp = 0",
    b"ao_distance = -1",
    b"width = 4294967295",
];

#[derive(Clone, Debug)]
enum Mutation {
    /// Flip one bit.
    Flip { at: usize, bit: u8 },
    /// Overwrite one byte.
    Set { at: usize, byte: u8 },
    /// Insert one byte.
    Insert { at: usize, byte: u8 },
    /// Delete up to `len` bytes.
    Delete { at: usize, len: usize },
    /// Repeat up to `len` bytes in place.
    Duplicate { at: usize, len: usize },
    /// Insert a token.
    Splice { at: usize, token: usize },
    /// Replace the word (a run of non-space, non-punctuation bytes) around `at` by a token.
    ReplaceWord { at: usize, token: usize },
    /// Repeat the line around `at`.
    DupLine { at: usize },
    /// Remove the line around `at`.
    DropLine { at: usize },
    /// Insert a token `times` times in a row (a very long line).
    LongLine {
        at: usize,
        token: usize,
        times: usize,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    let token = 0..TOKENS.len();
    prop_oneof![
        1 => (at, 0u8..8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        1 => (at, any::<u8>()).prop_map(|(at, byte)| Mutation::Set { at, byte }),
        1 => (at, any::<u8>()).prop_map(|(at, byte)| Mutation::Insert { at, byte }),
        1 => (at, 1usize..64).prop_map(|(at, len)| Mutation::Delete { at, len }),
        1 => (at, 1usize..64).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        3 => (at, token.clone()).prop_map(|(at, token)| Mutation::Splice { at, token }),
        5 => (at, token.clone())
            .prop_map(|(at, token)| Mutation::ReplaceWord { at, token }),
        1 => at.prop_map(|at| Mutation::DupLine { at }),
        1 => at.prop_map(|at| Mutation::DropLine { at }),
        1 => (at, token, 1usize..20_000)
            .prop_map(|(at, token, times)| Mutation::LongLine { at, token, times }),
    ]
}

/// Inputs stay below this size (long lines included).
const MAX_INPUT: usize = 400_000;

fn is_word_byte(b: u8) -> bool {
    !(b.is_ascii_whitespace() || b"[]{}=,\"'/#".contains(&b))
}

fn line_around(bytes: &[u8], at: usize) -> (usize, usize) {
    let start = bytes[..at]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let end = bytes[at..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |i| at + i + 1);
    (start, end)
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let n = bytes.len();
    let pos = |at: usize| if n == 0 { 0 } else { at % (n + 1) };
    let idx = |at: usize| if n == 0 { None } else { Some(at % n) };
    match *m {
        Mutation::Flip { at, bit } => {
            if let Some(i) = idx(at) {
                bytes[i] ^= 1 << bit;
            }
        }
        Mutation::Set { at, byte } => {
            if let Some(i) = idx(at) {
                bytes[i] = byte;
            }
        }
        Mutation::Insert { at, byte } => bytes.insert(pos(at), byte),
        Mutation::Delete { at, len } => {
            if let Some(i) = idx(at) {
                bytes.drain(i..(i + len).min(n));
            }
        }
        Mutation::Duplicate { at, len } => {
            if let Some(i) = idx(at) {
                let piece = bytes[i..(i + len).min(n)].to_vec();
                bytes.splice(i..i, piece);
            }
        }
        Mutation::Splice { at, token } => {
            let p = pos(at);
            bytes.splice(p..p, TOKENS[token].iter().copied());
        }
        Mutation::ReplaceWord { at, token } => {
            let p = pos(at);
            let mut start = p;
            while start > 0 && is_word_byte(bytes[start - 1]) {
                start -= 1;
            }
            let mut end = p;
            while end < n && is_word_byte(bytes[end]) {
                end += 1;
            }
            bytes.splice(start..end, TOKENS[token].iter().copied());
        }
        Mutation::DupLine { at } => {
            if let Some(i) = idx(at) {
                let (s, e) = line_around(bytes, i);
                let mut line = bytes[s..e].to_vec();
                if line.last() != Some(&b'\n') {
                    line.insert(0, b'\n');
                }
                bytes.splice(e..e, line);
            }
        }
        Mutation::DropLine { at } => {
            if let Some(i) = idx(at) {
                let (s, e) = line_around(bytes, i);
                bytes.drain(s..e);
            }
        }
        Mutation::LongLine { at, token, times } => {
            let p = pos(at);
            let tok = TOKENS[token];
            let times = times.min(MAX_INPUT / tok.len().max(1) / 2);
            let run: Vec<u8> = tok
                .iter()
                .copied()
                .cycle()
                .take(tok.len() * times)
                .collect();
            bytes.splice(p..p, run);
        }
    }
    bytes.truncate(MAX_INPUT);
}

/// A corpus file (by index, wrapped) with the mutations applied.
fn mutated(corpus: &[(String, Vec<u8>)], which: usize, muts: &[Mutation]) -> Vec<u8> {
    let mut bytes = corpus[which % corpus.len()].1.clone();
    for m in muts {
        apply(&mut bytes, m);
    }
    bytes
}

/// A corpus index and 1 to 6 mutations.
fn mutations() -> impl Strategy<Value = (usize, Vec<Mutation>)> {
    (any::<usize>(), prop::collection::vec(mutation(), 1..7))
}

/// Random bytes, biased half the time towards the characters the text formats use.
fn random_bytes() -> impl Strategy<Value = Vec<u8>> {
    let texty = prop::sample::select(
        b"0123456789 .-+eE/\n\r\t#[]=\",{}abcdfgilmnoprstuvxyzKdNT_\0\xff".to_vec(),
    );
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..2048),
        prop::collection::vec(texty, 0..2048),
    ]
}

/// Lines of `keywords` each followed by up to 6 `words`: text that looks like the format.
fn grammar(
    keywords: &'static [&'static str],
    words: &'static [&'static str],
) -> impl Strategy<Value = Vec<u8>> {
    let line = (
        prop::sample::select(keywords),
        prop::collection::vec(prop::sample::select(words), 0..7),
        prop::sample::select(&[" ", "\t", "  "][..]),
        prop::sample::select(&["\n", "\r\n", "\n", "\\\n", ""][..]),
    )
        .prop_map(|(kw, ws, sep, end)| {
            let mut s = kw.to_string();
            for w in ws {
                s.push_str(sep);
                s.push_str(w);
            }
            s.push_str(end);
            s
        });
    prop::collection::vec(line, 0..48).prop_map(|lines| lines.concat().into_bytes())
}

const OBJ_KEYWORDS: &[&str] = &[
    "v", "v", "v", "v", "vt", "vn", "vp", "f", "f", "f", "f", "l", "p", "o", "g", "s", "mtllib",
    "usemtl", "#", "", "curv", "cstype",
];

const OBJ_WORDS: &[&str] = &[
    "0",
    "1",
    "2",
    "3",
    "4",
    "-1",
    "-2",
    "-3",
    "-4",
    "0.5",
    "-0.5",
    "1e10",
    "1e11",
    "1e12",
    "1e13",
    "1e30",
    "-1e30",
    "1e39",
    "-1e39",
    "1e-30",
    "1e-45",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "1/1",
    "1/1/1",
    "2/2/2",
    "3/3/3",
    "1//1",
    "-1/-1/-1",
    "-1//-1",
    "0/0/0",
    "1/0/0",
    "1/2/3/4",
    "/",
    "//",
    "1/",
    "/1",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "x",
    "cornell-box.mtl",
    "x.mtl",
    ".",
    "white",
    "light",
    "\u{0}",
    "é",
];

const MTL_KEYWORDS: &[&str] = &[
    "newmtl", "newmtl", "Kd", "Kd", "Ka", "Ks", "Ke", "Ke", "Ni", "Ns", "d", "Tr", "illum",
    "map_Kd", "map_Ka", "map_Ks", "map_Bump", "bump", "map_d", "#", "",
];

const MTL_WORDS: &[&str] = &[
    "white",
    "red",
    "green",
    "light",
    "glass",
    "a",
    "0",
    "1",
    "0.5",
    "2",
    "5",
    "7",
    "-1",
    "-0",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "1e30",
    "4294967296",
    "-4294967296",
    "checker.png",
    "x.mtl",
    "x.obj",
    ".",
    "missing.png",
    "spectral",
    "xyz",
    "-o",
    "-s",
    "-clamp",
    "on",
];

// ---------------------------------------------------------------------------------------------
// Readers. Each test keeps its own folder; a case overwrites the fuzzed file in it.

fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("lancer-fuzz-")
        .tempdir()
        .unwrap()
}

fn copy_scene_file(dir: &Path, name: &str) {
    std::fs::copy(repo("scenes").join(name), dir.join(name)).unwrap();
}

/// What a reader's Result says, briefly (the value is only checked for panics and hangs).
fn outcome<T>(r: lancer::Result<T>) -> bool {
    r.is_ok()
}

/// Loads `path` as an OBJ every way the library offers; a usable mesh also goes through a
/// BVH build, the default layout and a few CPU rays of its default view.
fn obj_readers(reader: &str, path: &Path, files: &Files) -> Result<(), TestCaseError> {
    let p = path.to_path_buf();
    guarded(&format!("{reader}: load_obj"), files, move || {
        outcome(load_obj(&p))
    })?;
    let p = path.to_path_buf();
    guarded(&format!("{reader}: load_obj_scene"), files, move || {
        outcome(load_obj_scene(&p))
    })?;
    mesh_readers(reader, path, files)
}

/// Loads `path` with `load_mesh` (the reader its extension picks); a usable mesh also goes
/// through a BVH build, the default layout and a few CPU rays of its default view.
fn mesh_readers(reader: &str, path: &Path, files: &Files) -> Result<(), TestCaseError> {
    let p = path.to_path_buf();
    let mesh = guarded(&format!("{reader}: load_mesh"), files, move || {
        load_mesh(&p).ok()
    })?;
    if let Some(mesh) = mesh {
        guarded(
            &format!("{reader}: BVH build + flatten + 4x4 CPU rays of the default view"),
            files,
            move || {
                let opts = lancer::accel::bvh::BuildOptions::default();
                let bvh = lancer::accel::bvh::build(&mesh, &opts);
                let layout =
                    lancer::accel::bvh::layouts::flatten(lancer::LayoutKind::DfsSign, &bvh, &mesh);
                let rays = Camera::default_view(&mesh.bounds(), 4, 4).primary_rays();
                let (hits, _) =
                    layout.trace_batch(&rays, Query::Closest, &lancer::Robustness::default());
                hits.len()
            },
        )?;
    }
    Ok(())
}

/// The sample mesh of tests/formats.rs as ASCII PLY, binary PLY (both byte orders), glTF
/// with an embedded buffer and GLB: (file name, bytes).
fn ply_gltf_corpus() -> Vec<(String, Vec<u8>)> {
    use common::writers::{self, Indexed};
    let m = Indexed {
        verts: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.5],
            [0.0, 1.0, 0.5],
            [0.5, 0.5, 2.0],
        ],
        faces: vec![vec![0, 1, 2, 3], vec![0, 1, 4], vec![2, 3, 4]],
    };
    let bin = writers::gltf_buffer(&m);
    let embedded = writers::gltf_json(&m, Some(writers::data_uri(&bin)));
    vec![
        ("case.ply".into(), writers::ply_ascii(&m)),
        ("case.ply".into(), writers::ply_binary(&m, false)),
        ("case.ply".into(), writers::ply_binary(&m, true)),
        ("case.gltf".into(), serde_json::to_vec(&embedded).unwrap()),
        (
            "case.glb".into(),
            writers::glb(&writers::gltf_json(&m, None), Some(&bin)),
        ),
    ]
}

/// One mesh file (`name` in `dir`) through the mesh readers, and as `lancer render FILE`
/// reads it: materials and textures too.
fn mesh_file_case(dir: &Path, name: &str, bytes: Vec<u8>) -> Result<(), TestCaseError> {
    let path = dir.join(name);
    std::fs::write(&path, &bytes).unwrap();
    let files = vec![(name.to_string(), bytes)];
    mesh_readers(name, &path, &files)?;
    guarded(
        &format!("{name}: RenderScene::from_mesh"),
        &files,
        move || outcome(RenderScene::from_mesh(&path, 4, 4)),
    )?;
    Ok(())
}

#[test]
fn ply_and_gltf_readers_survive_mutated_and_random_files() {
    let corpus = ply_gltf_corpus();
    let dir = scratch();
    let case = |name: &str, bytes: Vec<u8>| mesh_file_case(dir.path(), name, bytes);
    run_property("PLY/glTF (mutated)", 400, mutations(), |(which, muts)| {
        let bytes = mutated(&corpus, which, &muts);
        case(&corpus[which % corpus.len()].0, bytes)
    });
    let names = ["case.ply", "case.gltf", "case.glb"];
    run_property(
        "PLY/glTF (random)",
        60,
        (0..names.len(), random_bytes()),
        |(k, bytes)| case(names[k], bytes),
    );
}

/// A glTF document with a reference of every kind the crate follows: the sample mesh's
/// accessors, views and buffer (a data URI), a material with a base-colour texture, its
/// sampler and image (a data-URI PNG), a camera, a node tree, a scene.
fn rich_gltf() -> serde_json::Value {
    use common::writers::{self, Indexed};
    let m = Indexed {
        verts: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.5],
            [0.0, 1.0, 0.5],
        ],
        faces: vec![vec![0, 1, 2, 3]],
    };
    let bin = writers::gltf_buffer(&m);
    let mut doc = writers::gltf_json(&m, Some(writers::data_uri(&bin)));
    let mut png = Vec::new();
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let png_uri = writers::data_uri(&png).replace("application/octet-stream", "image/png");
    doc["images"] = serde_json::json!([{ "uri": png_uri }]);
    doc["samplers"] = serde_json::json!([{}]);
    doc["textures"] = serde_json::json!([{ "source": 0, "sampler": 0 }]);
    doc["materials"] =
        serde_json::json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
    doc["meshes"][0]["primitives"][0]["material"] = serde_json::json!(0);
    doc["cameras"] = serde_json::json!([{ "type": "perspective",
        "perspective": { "yfov": 0.8, "znear": 0.1 } }]);
    doc["nodes"] = serde_json::json!([{ "children": [1] }, { "mesh": 0, "camera": 0 }]);
    doc
}

/// The JSON pointers of every value in `v` (the root included).
fn pointers(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(o) => o
            .iter()
            .for_each(|(k, x)| pointers(x, format!("{at}/{k}"), out)),
        serde_json::Value::Array(a) => {
            (a.iter().enumerate()).for_each(|(i, x)| pointers(x, format!("{at}/{i}"), out))
        }
        _ => {}
    }
    out.push(at);
}

/// Keys the crate follows as references, inserted by the structure-aware mutations.
const REFERENCE_KEYS: [&str; 14] = [
    "bufferView",
    "buffer",
    "mimeType",
    "uri",
    "children",
    "mesh",
    "camera",
    "skin",
    "sampler",
    "source",
    "index",
    "material",
    "indices",
    "scene",
];

/// One structure-aware change to a glTF document: (kind, where, what).
fn apply_json(doc: &mut serde_json::Value, (kind, at, what): (u8, usize, u64)) {
    use serde_json::{json, Value};
    let mut all = Vec::new();
    pointers(doc, String::new(), &mut all);
    let target = all[at % all.len()].clone();
    let Some(v) = doc.pointer_mut(&target) else {
        return;
    };
    let index = [0, 1, 2, 5, 255, u32::MAX as u64, u64::MAX][what as usize % 7];
    match kind % 5 {
        // An index moved, in range or far out.
        0 => *v = json!(index),
        // A value of the wrong kind.
        1 => {
            *v = [
                json!({}),
                json!([]),
                json!("x"),
                json!(-1),
                json!(0.5),
                Value::Null,
            ][what as usize % 6]
                .clone()
        }
        // A key removed.
        2 => {
            if let Some(o) = v.as_object_mut() {
                if let Some(k) = o.keys().nth(what as usize % o.len().max(1)).cloned() {
                    o.remove(&k);
                }
            }
        }
        // A reference key added (or replaced) with an index.
        3 => {
            if let Some(o) = v.as_object_mut() {
                o.insert(
                    REFERENCE_KEYS[what as usize % REFERENCE_KEYS.len()].into(),
                    json!(index % 8),
                );
            }
        }
        // An array element duplicated (cycles in children, repeated nodes).
        _ => {
            if let Some(a) = v.as_array_mut() {
                if let Some(x) = a.get(what as usize % a.len().max(1)).cloned() {
                    a.push(x);
                }
            }
        }
    }
}

#[test]
fn the_gltf_reader_survives_structure_aware_mutations() {
    let base = rich_gltf();
    let dir = scratch();
    let case = |name: &str, bytes: Vec<u8>| mesh_file_case(dir.path(), name, bytes);
    // The unmutated document loads: the mutations start from a working file.
    let path = dir.path().join("rich.gltf");
    std::fs::write(&path, serde_json::to_vec(&base).unwrap()).unwrap();
    RenderScene::from_mesh(&path, 4, 4).expect("the base document loads");
    let changes = proptest::collection::vec((any::<u8>(), any::<usize>(), any::<u64>()), 1..5);
    run_property(
        "glTF (structure-aware)",
        400,
        (changes, any::<bool>()),
        |(changes, glb)| {
            let mut doc = base.clone();
            changes.into_iter().for_each(|c| apply_json(&mut doc, c));
            match glb {
                true => case("case.glb", common::writers::glb(&doc, None)),
                false => case("case.gltf", serde_json::to_vec(&doc).unwrap()),
            }
        },
    );
}

/// The regression cases of the coverage-guided fuzz targets (scripts/fuzz.sh keeps each
/// crash it finds in tests/fuzz-regressions/TARGET/), with the crashes reported before the
/// fuzz targets existed: each fed to its target's reader ([`common::readers::run`], the
/// targets' own entry point) must return.
#[test]
fn fuzz_regressions_stay_fixed() {
    let root = repo("tests/fuzz-regressions");
    let mut cases = 0;
    for target in common::readers::TARGETS {
        let Ok(entries) = std::fs::read_dir(root.join(target)) else {
            continue;
        };
        let mut paths: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
        paths.sort();
        for path in paths {
            let bytes = std::fs::read(&path).unwrap();
            let name = format!("{target}/{}", path.file_name().unwrap().to_string_lossy());
            let files = vec![(name.clone(), bytes.clone())];
            if let Err(e) = guarded(&name, &files, move || common::readers::run(target, &bytes)) {
                panic!("{e}");
            }
            cases += 1;
        }
    }
    assert!(cases > 0, "no regression case in {}", root.display());
}

/// Writes the fuzz targets' seed corpus into `$LANCER_FUZZ_SEEDS/TARGET/` (scripts/fuzz.sh
/// runs it): the repository's scenes and OBJ/MTL, and PLY, glTF, GLB, EXR, BVH, ray and hit
/// files made here.
#[test]
#[ignore = "scripts/fuzz.sh writes the fuzz seeds with it"]
fn write_fuzz_seeds() {
    let Some(out) = std::env::var_os("LANCER_FUZZ_SEEDS").map(PathBuf::from) else {
        panic!("set LANCER_FUZZ_SEEDS to the corpus folder");
    };
    let put = |target: &str, name: &str, bytes: &[u8]| {
        let d = out.join(target);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(name), bytes).unwrap();
    };
    for (target, ext) in [("scene", "toml"), ("obj", "obj"), ("mtl", "mtl")] {
        for (name, bytes) in scene_files(ext) {
            put(target, &name, &bytes);
        }
    }
    for (k, (name, bytes)) in ply_gltf_corpus().into_iter().enumerate() {
        let target = name.rsplit('.').next().unwrap().to_string();
        put(&target, &format!("{k}-{name}"), &bytes);
    }
    put(
        "gltf",
        "rich.gltf",
        &serde_json::to_vec(&rich_gltf()).unwrap(),
    );
    let dir = scratch();
    let mesh = load_obj(&repo("scenes/cornell-box.obj")).unwrap();
    let rays = Camera::default_view(&mesh.bounds(), 8, 8).primary_rays();
    put("rays", "view.rays", bytemuck::cast_slice(&rays));
    let cpu = Device::cpu();
    let mut tracer = Tracer::new(&cpu, &mesh, &TracerOptions::default()).unwrap();
    let hits = tracer.trace(&rays, Query::Closest).unwrap().hits;
    put(
        "hits",
        "view.hits",
        &lancer::trace::files::encode_hits(&hits),
    );
    for &kind in lancer::LayoutKind::ALL {
        let bvh = lancer::accel::bvh::build(&mesh, &Default::default());
        let layout = lancer::accel::bvh::layouts::flatten(kind, &bvh, &mesh);
        let p = dir.path().join("seed.bvh");
        lancer::accel::bvh::layouts::bvh_file::write(&p, layout.as_ref(), mesh.len()).unwrap();
        put("bvh", &format!("{kind}.bvh"), &std::fs::read(&p).unwrap());
    }
    let scene = RenderScene::from_file(&repo("scenes/cornell.toml")).unwrap();
    let options = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    let mut scene = scene;
    (scene.camera.width, scene.camera.height) = (8, 6);
    let done = lancer::render::render(&scene, &cpu, &options).unwrap();
    let p = dir.path().join("seed.exr");
    done.image.to_exr().write(&p).unwrap();
    put("exr", "cornell.exr", &std::fs::read(&p).unwrap());
}

/// The OBJ folder: the fuzzed case.obj beside the MTL the corpus names.
fn obj_dir() -> tempfile::TempDir {
    let dir = scratch();
    copy_scene_file(dir.path(), "cornell-box.mtl");
    copy_scene_file(dir.path(), "checker.png");
    dir
}

#[test]
fn obj_reader_survives_mutated_files() {
    let corpus = obj_corpus();
    let dir = obj_dir();
    let path = dir.path().join("case.obj");
    run_property("OBJ (mutated)", 200, mutations(), |(which, muts)| {
        let bytes = mutated(&corpus, which, &muts);
        std::fs::write(&path, &bytes).unwrap();
        let files = vec![("case.obj".to_string(), bytes)];
        obj_readers("OBJ", &path, &files)
    });
}

#[test]
fn obj_reader_survives_random_and_grammar_bytes() {
    let dir = obj_dir();
    let path = dir.path().join("case.obj");
    let strategy = prop_oneof![random_bytes(), grammar(OBJ_KEYWORDS, OBJ_WORDS)];
    run_property("OBJ (random/grammar)", 200, strategy, |bytes| {
        std::fs::write(&path, &bytes).unwrap();
        let files = vec![("case.obj".to_string(), bytes)];
        obj_readers("OBJ", &path, &files)
    });
}

/// Loads an OBJ that names the fuzzed x.mtl, as a scene (materials) and for rendering.
fn mtl_readers(dir: &Path, bytes: Vec<u8>) -> Result<(), TestCaseError> {
    std::fs::write(dir.join("x.mtl"), &bytes).unwrap();
    let obj = dir.join("x.obj");
    let files = vec![
        ("x.mtl".to_string(), bytes),
        ("x.obj".to_string(), MTL_USER_OBJ.as_bytes().to_vec()),
    ];
    let p = obj.clone();
    guarded("MTL: load_obj_scene", &files, move || {
        outcome(load_obj_scene(&p))
    })?;
    let p = obj.clone();
    guarded("MTL: RenderScene::from_mesh(16x12)", &files, move || {
        outcome(RenderScene::from_mesh(&p, 16, 12))
    })?;
    Ok(())
}

fn mtl_dir() -> tempfile::TempDir {
    let dir = scratch();
    copy_scene_file(dir.path(), "checker.png");
    std::fs::write(dir.path().join("x.obj"), MTL_USER_OBJ).unwrap();
    dir
}

#[test]
fn mtl_reader_survives_mutated_files() {
    let corpus = mtl_corpus();
    let dir = mtl_dir();
    run_property("MTL (mutated)", 150, mutations(), |(which, muts)| {
        mtl_readers(dir.path(), mutated(&corpus, which, &muts))
    });
}

#[test]
fn mtl_reader_survives_random_and_grammar_bytes() {
    let dir = mtl_dir();
    let strategy = prop_oneof![random_bytes(), grammar(MTL_KEYWORDS, MTL_WORDS)];
    run_property("MTL (random/grammar)", 150, strategy, |bytes| {
        mtl_readers(dir.path(), bytes)
    });
}

/// Reads the fuzzed scene; a scene that loads is also rendered, 4×4 at 1 spp on the CPU.
fn toml_readers(path: &Path, bytes: Vec<u8>) -> Result<(), TestCaseError> {
    std::fs::write(path, &bytes).unwrap();
    let files = vec![("case.toml".to_string(), bytes)];
    let p = path.to_path_buf();
    let scene = guarded("TOML: RenderScene::from_file", &files, move || {
        RenderScene::from_file(&p).ok()
    })?;
    if let Some(mut scene) = scene {
        guarded("TOML: render(cpu, 4x4, 1 spp)", &files, move || {
            (scene.camera.width, scene.camera.height) = (4, 4);
            let options = RenderOptions {
                spp: Some(1),
                ..RenderOptions::default()
            };
            outcome(lancer::render::render(&scene, &Device::cpu(), &options))
        })?;
    }
    Ok(())
}

fn toml_dir() -> tempfile::TempDir {
    let dir = scratch();
    for f in ["cornell-box.obj", "cornell-box.mtl", "checker.png"] {
        copy_scene_file(dir.path(), f);
    }
    dir
}

#[test]
fn toml_scene_reader_survives_mutated_files() {
    let corpus = toml_corpus();
    let dir = toml_dir();
    let path = dir.path().join("case.toml");
    run_property("TOML scene (mutated)", 200, mutations(), |(which, muts)| {
        toml_readers(&path, mutated(&corpus, which, &muts))
    });
}

#[test]
fn toml_scene_reader_survives_random_bytes() {
    let dir = toml_dir();
    let path = dir.path().join("case.toml");
    run_property("TOML scene (random)", 64, random_bytes(), |bytes| {
        toml_readers(&path, bytes)
    });
}

/// f32 values that break arithmetic, and ordinary ones.
fn hostile_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(-f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(f32::MAX),
        Just(f32::MIN),
        Just(f32::MIN_POSITIVE),
        Just(1e-45f32),
        Just(0.0f32),
        Just(-0.0f32),
        Just(1e13f32),
        Just(-1e13f32),
        Just(1e30f32),
        -2.0f32..2.0,
        -1e6f32..1e6,
        any::<f32>(),
    ]
}

/// Ray file bytes: whole rays of hostile floats, sometimes with a partial ray after them,
/// or random bytes.
fn ray_file() -> impl Strategy<Value = Vec<u8>> {
    let whole = (
        prop::collection::vec(prop::collection::vec(hostile_f32(), 8), 0..64),
        prop::collection::vec(any::<u8>(), 0..3),
        prop::bool::weighted(0.15),
    )
        .prop_map(|(rays, tail, partial)| {
            let mut out: Vec<u8> = rays
                .iter()
                .flatten()
                .flat_map(|x| x.to_le_bytes())
                .collect();
            if partial {
                out.extend_from_slice(&tail);
                out.push(0);
            }
            out
        });
    prop_oneof![
        3 => whole,
        1 => prop::collection::vec(any::<u8>(), 0..1024),
    ]
}

fn quad_mesh() -> Mesh {
    let v = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    Mesh::from_triangles(vec![
        Triangle::new(v[0], v[1], v[2]),
        Triangle::new(v[0], v[2], v[3]),
    ])
}

#[test]
fn ray_file_reader_survives_hostile_bytes() {
    let dir = scratch();
    let path = dir.path().join("case.rays");
    run_property("ray file", 150, ray_file(), |bytes| {
        std::fs::write(&path, &bytes).unwrap();
        let files = vec![("case.rays".to_string(), bytes)];
        let p = path.clone();
        let rays: Option<Vec<Ray>> =
            guarded("rays: read_rays", &files, move || read_rays(&p).ok())?;
        if let Some(rays) = rays {
            // What the CLI's `trace` does next, on the CPU.
            guarded(
                "rays: read_rays + trace (cpu, closest and any)",
                &files,
                move || {
                    let device = Device::cpu();
                    let mesh = quad_mesh();
                    let mut tracer = Tracer::new(&device, &mesh, &TracerOptions::default())
                        .expect("a CPU tracer for a quad");
                    let closest = tracer.trace(&rays, Query::Closest).map(|r| r.hits.len());
                    let any = tracer.trace(&rays, Query::Any).map(|r| r.hits.len());
                    (outcome(closest), outcome(any))
                },
            )?;
        }
        Ok(())
    });
}

#[test]
fn hit_file_reader_survives_hostile_bytes() {
    let dir = scratch();
    let path = dir.path().join("case.hits");
    let strategy = prop_oneof![
        prop::collection::vec(any::<u8>(), 0..1024),
        prop::collection::vec(hostile_f32(), 0..128)
            .prop_map(|v| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>()),
    ];
    run_property("hit file", 100, strategy, |bytes| {
        std::fs::write(&path, &bytes).unwrap();
        let files = vec![("case.hits".to_string(), bytes)];
        let p = path.clone();
        guarded("hits: read_hits", &files, move || outcome(read_hits(&p)))?;
        Ok(())
    });
}

#[test]
fn readers_survive_their_own_folder_and_missing_files() {
    // Not bytes, but hostile all the same: a folder, a missing path, an empty file, /dev/null.
    let dir = scratch();
    let folder = dir.path().join("folder.obj");
    std::fs::create_dir(&folder).unwrap();
    std::fs::create_dir(dir.path().join("folder.toml")).unwrap();
    std::fs::write(dir.path().join("empty.obj"), b"").unwrap();
    std::fs::write(dir.path().join("empty.toml"), b"").unwrap();
    let paths = [
        folder.clone(),
        dir.path().join("folder.toml"),
        dir.path().join("missing.obj"),
        dir.path().join("empty.obj"),
        dir.path().join("empty.toml"),
        PathBuf::from("/dev/null"),
    ];
    for p in paths {
        let files = vec![(format!("path {}", p.display()), Vec::new())];
        let q = p.clone();
        let r = guarded("all readers on a non-file", &files, move || {
            (
                load_obj(&q).is_ok(),
                load_obj_scene(&q).is_ok(),
                RenderScene::from_file(&q).is_ok(),
                RenderScene::from_mesh(&q, 16, 12).is_ok(),
                read_rays(&q).is_ok(),
                read_hits(&q).is_ok(),
            )
        });
        if let Err(e) = r {
            panic!("{e}");
        }
    }
}
