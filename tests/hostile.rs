//! Hostile command lines against the `lancer` binary: outputs that are inputs, devices or
//! folders, missing and malformed inputs, out-of-range values, sizes that would not fit,
//! huge coordinates, and signals. The policy (README, "Command line"):
//!
//! - exit 0: success; stderr holds only `warning:` lines;
//! - exit 2: bad input or usage; exit 1: device errors and write failures at write time;
//! - exit 130: a render interrupted by SIGINT/SIGTERM, after saving its image;
//! - never 101 (panic) or 134 (abort), never killed by a signal;
//! - an error is ONE line starting with `error:` (warnings may precede it), naming the file
//!   (and line) at fault where there is one.
//!
//! Every row prints what it ran and what it got; all failing rows are listed together.

mod common;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use glam::Vec3;
use lancer::geometry::Ray;

/// A run that takes longer than this is a hang (a guard, not a measure of speed).
const HANG_GUARD: Duration = Duration::from_secs(60);

// ---------------------------------------------------------------------------------------------
// Running the binary.

#[derive(Debug)]
struct Got {
    code: Option<i32>,
    /// The signal that ended the process, if one did.
    signal: Option<i32>,
    stdout: String,
    stderr: String,
    secs: f64,
    hung: bool,
}

impl Got {
    fn show(&self) -> String {
        let how = if self.hung {
            format!("HUNG (killed after {HANG_GUARD:?})")
        } else if let Some(s) = self.signal {
            format!("killed by signal {s}")
        } else {
            format!("exit {:?}", self.code)
        };
        format!(
            "{how} in {:.2} s\n      stderr: {}\n      stdout: {}",
            self.secs,
            indent(&self.stderr),
            indent(&self.stdout)
        )
    }

    fn stderr_lines(&self) -> Vec<&str> {
        self.stderr
            .lines()
            .map(str::trim_end)
            .filter(|l| !l.trim().is_empty())
            .collect()
    }

    /// The one `error:` line, if stderr has exactly one.
    fn error_line(&self) -> Option<&str> {
        let errors: Vec<&str> = self
            .stderr_lines()
            .into_iter()
            .filter(|l| l.starts_with("error:"))
            .collect();
        (errors.len() == 1).then(|| errors[0])
    }

    fn warnings(&self) -> Vec<&str> {
        self.stderr_lines()
            .into_iter()
            .filter(|l| l.starts_with("warning:"))
            .collect()
    }
}

fn indent(s: &str) -> String {
    let s = s.trim_end();
    if s.is_empty() {
        "(empty)".into()
    } else {
        s.replace('\n', "\n              ")
    }
}

fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    })
}

fn spawn(dir: &Path, args: &[String]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start lancer")
}

/// Waits for `child` (killing it after HANG_GUARD) and collects what it printed.
fn finish(mut child: Child, start: Instant) -> Got {
    let out = drain(child.stdout.take().unwrap());
    let err = drain(child.stderr.take().unwrap());
    let mut hung = false;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > HANG_GUARD {
            hung = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let secs = start.elapsed().as_secs_f64();
    #[cfg(unix)]
    let signal = std::os::unix::process::ExitStatusExt::signal(&status);
    #[cfg(not(unix))]
    let signal = None;
    Got {
        code: status.code(),
        signal,
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
        secs,
        hung,
    }
}

fn run_in(dir: &Path, args: &[String]) -> Got {
    let start = Instant::now();
    finish(spawn(dir, args), start)
}

fn command_line(args: &[String]) -> String {
    let mut s = String::from("lancer");
    for a in args {
        if a.is_empty() || a.contains(|c: char| c.is_whitespace() || c == '\'') {
            s.push_str(&format!(" {a:?}"));
        } else {
            s.push(' ');
            s.push_str(a);
        }
    }
    s
}

// ---------------------------------------------------------------------------------------------
// A row of the table: a command line and what the policy wants of it.

#[derive(Clone, Copy, Debug, PartialEq)]
enum Want {
    /// Exit 0, stderr only warnings.
    Ok,
    /// Exit with this code, one `error:` line (warnings may precede it).
    Fail(i32),
    /// Either of the above with code 2, judged by the exit code seen (a choice of policy).
    OkOrFail2,
}

type Check = Box<dyn Fn(&Got) -> Vec<String>>;

struct Row {
    name: String,
    args: Vec<String>,
    want: Want,
    /// Substrings the error line must contain (the file at fault, its line, …).
    names: Vec<String>,
    /// Substrings one single warning line must contain, all of them (Want::Ok).
    warns: Vec<String>,
    /// Substrings stderr and stdout must not contain.
    lacks: Vec<String>,
    /// More to check afterwards (files unchanged, outputs absent, …).
    checks: Vec<Check>,
    /// Must exit within this many seconds (a fail-fast row).
    max_secs: Option<f64>,
}

impl Row {
    fn new(name: impl Into<String>, want: Want, args: &[&dyn AsArg]) -> Row {
        Row {
            name: name.into(),
            args: args.iter().map(|a| a.as_arg()).collect(),
            want,
            names: Vec::new(),
            warns: Vec::new(),
            lacks: Vec::new(),
            checks: Vec::new(),
            max_secs: None,
        }
    }
    fn names(mut self, s: &[&str]) -> Row {
        self.names.extend(s.iter().map(|s| s.to_string()));
        self
    }
    fn warns(mut self, s: &[&str]) -> Row {
        self.warns.extend(s.iter().map(|s| s.to_string()));
        self
    }
    fn lacks(mut self, s: &[&str]) -> Row {
        self.lacks.extend(s.iter().map(|s| s.to_string()));
        self
    }
    fn check(mut self, c: impl Fn(&Got) -> Vec<String> + 'static) -> Row {
        self.checks.push(Box::new(c));
        self
    }
    /// The files keep their bytes (read now, compared after the run).
    fn unchanged(self, files: &[&Path]) -> Row {
        let before: Vec<(PathBuf, Vec<u8>)> = files
            .iter()
            .map(|f| {
                (
                    f.to_path_buf(),
                    std::fs::read(f).expect("an input to protect"),
                )
            })
            .collect();
        self.check(move |_| {
            before
                .iter()
                .filter(|(f, b)| std::fs::read(f).ok().as_ref() != Some(b))
                .map(|(f, _)| format!("{} was changed (or removed)", f.display()))
                .collect()
        })
    }
    /// The file was not created.
    fn absent(self, file: &Path) -> Row {
        let f = file.to_path_buf();
        self.check(move |_| {
            if f.exists() {
                vec![format!("{} was created", f.display())]
            } else {
                Vec::new()
            }
        })
    }
    /// The error line also names one of these (a limit, a range, …).
    fn names_one_of(self, alternatives: &'static [&'static str]) -> Row {
        self.check(move |g| match g.error_line() {
            Some(l) if alternatives.iter().any(|a| l.contains(a)) => Vec::new(),
            Some(l) => vec![format!("error line names none of {alternatives:?}: {l}")],
            None => Vec::new(), // reported by the common checks
        })
    }
    fn within(mut self, secs: f64) -> Row {
        self.max_secs = Some(secs);
        self
    }
}

/// Paths and strings as arguments.
trait AsArg {
    fn as_arg(&self) -> String;
}
impl AsArg for &str {
    fn as_arg(&self) -> String {
        self.to_string()
    }
}
impl AsArg for String {
    fn as_arg(&self) -> String {
        self.clone()
    }
}
impl AsArg for PathBuf {
    fn as_arg(&self) -> String {
        self.to_str().expect("UTF-8 test path").to_string()
    }
}
impl AsArg for &Path {
    fn as_arg(&self) -> String {
        self.to_str().expect("UTF-8 test path").to_string()
    }
}

/// What is wrong with a run, by the policy and the row's own wants.
fn problems(row: &Row, got: &Got) -> Vec<String> {
    let mut p = Vec::new();
    if got.hung {
        p.push(format!("hung: still running after {HANG_GUARD:?}"));
        return p;
    }
    if let Some(s) = got.signal {
        p.push(format!("killed by signal {s}"));
    }
    match got.code {
        Some(101) => p.push("exit 101: a panic".into()),
        Some(134) => p.push("exit 134: an abort".into()),
        _ => {}
    }
    for bad in ["panicked at", "RUST_BACKTRACE", "memory allocation of"] {
        if got.stderr.contains(bad) {
            p.push(format!("stderr shows a crash ({bad:?})"));
        }
    }
    let lines = got.stderr_lines();
    let want = match row.want {
        Want::OkOrFail2 if got.code == Some(0) => Want::Ok,
        Want::OkOrFail2 => Want::Fail(2),
        w => w,
    };
    match want {
        Want::Ok => {
            if got.code != Some(0) {
                p.push(format!("want exit 0, got {:?}", got.code));
            }
            if let Some(l) = lines.iter().find(|l| !l.starts_with("warning:")) {
                p.push(format!(
                    "a successful run's stderr has a line that is no warning: {l}"
                ));
            }
            if !row.warns.is_empty() {
                let found = got
                    .warnings()
                    .iter()
                    .any(|w| row.warns.iter().all(|s| w.contains(s.as_str())));
                if !found {
                    p.push(format!("no warning line names all of {:?}", row.warns));
                }
            }
        }
        Want::OkOrFail2 => unreachable!(),
        Want::Fail(code) => {
            if got.code != Some(code) {
                p.push(format!("want exit {code}, got {:?}", got.code));
            }
            let n_err = lines.iter().filter(|l| l.starts_with("error:")).count();
            if n_err != 1 {
                p.push(format!(
                    "want exactly one 'error:' line on stderr, got {n_err}"
                ));
            }
            match lines.last() {
                Some(last) if last.starts_with("error:") => {}
                Some(last) => p.push(format!("the last stderr line is not the error: {last}")),
                None => p.push("stderr is empty".into()),
            }
            if let Some(l) = lines
                .iter()
                .take(lines.len().saturating_sub(1))
                .find(|l| !l.starts_with("warning:"))
            {
                p.push(format!("a line before the error is no warning: {l}"));
            }
            if let Some(err) = got.error_line() {
                for n in &row.names {
                    if !err.contains(n.as_str()) {
                        p.push(format!("the error line does not name {n:?}"));
                    }
                }
            }
        }
    }
    for l in &row.lacks {
        if got.stderr.contains(l.as_str()) || got.stdout.contains(l.as_str()) {
            p.push(format!("output mentions {l:?}"));
        }
    }
    if let Some(max) = row.max_secs {
        if got.secs > max {
            p.push(format!(
                "took {:.1} s: it should have refused before any work (within {max} s)",
                got.secs
            ));
        }
    }
    for c in &row.checks {
        p.extend(c(got));
    }
    p
}

/// Runs every row in `dir`, prints each, and fails listing every row that broke the policy.
fn run_table(dir: &Path, rows: Vec<Row>) {
    let mut failed = Vec::new();
    let total = rows.len();
    for row in rows {
        let got = run_in(dir, &row.args);
        let p = problems(&row, &got);
        let verdict = if p.is_empty() { "ok" } else { "FAIL" };
        println!(
            "[{verdict}] {} (want {:?})\n    $ {}\n    {}",
            row.name,
            row.want,
            command_line(&row.args),
            got.show()
        );
        for x in &p {
            println!("    !! {x}");
        }
        if !p.is_empty() {
            failed.push(format!(
                "{}\n    $ {}\n    {}\n    !! {}",
                row.name,
                command_line(&row.args),
                got.show(),
                p.join("\n    !! ")
            ));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {total} hostile rows broke the policy:\n\n{}",
        failed.len(),
        failed.join("\n\n")
    );
}

// ---------------------------------------------------------------------------------------------
// Inputs.

struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new() -> Scratch {
        Scratch(
            tempfile::Builder::new()
                .prefix("lancer-hostile-")
                .tempdir()
                .unwrap(),
        )
    }
    fn dir(&self) -> &Path {
        self.0.path()
    }
    fn path(&self, rel: &str) -> PathBuf {
        self.0.path().join(rel)
    }
    /// Writes `rel` (creating its folder) and returns its path.
    fn write(&self, rel: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let p = self.path(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, bytes).unwrap();
        p
    }
    fn mkdir(&self, rel: &str) -> PathBuf {
        let p = self.path(rel);
        std::fs::create_dir_all(&p).unwrap();
        p
    }
    /// Copies scenes/NAME to REL.
    fn copy_scene(&self, name: &str, rel: &str) -> PathBuf {
        self.write(rel, std::fs::read(scene(name)).unwrap())
    }
}

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

const QUAD: &str = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n";

/// A ray file of the quad's kind of view: rays from z = 5 towards the origin region.
/// A PNG of `w`×`h` 8-bit grey pixels, its header and the start of its data only: what a
/// reader learns before decoding.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let body = [kind, data].concat();
        png.extend_from_slice(&body);
        png.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
    };
    let ihdr = [&w.to_be_bytes()[..], &h.to_be_bytes(), &[8, 0, 0, 0, 0]].concat();
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00]);
    chunk(b"IEND", &[]);
    png
}

fn write_ray_file(path: &Path) {
    let rays: Vec<Ray> = (0..16)
        .map(|i| {
            let (x, y) = ((i % 4) as f32 * 0.5 - 0.75, (i / 4) as f32 * 0.5 - 0.75);
            Ray::new(Vec3::new(x, y, 5.0), Vec3::NEG_Z, 0.0, 1e30)
        })
        .collect();
    lancer::trace::files::write_rays(path, &rays).unwrap();
}

/// A small scene, valid as written; rows swap one line of it.
const SCENE: &str = r#"[camera]
position = [0.0, 1.0, 5.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
width = 8
height = 8

[render]
integrator = "direct"
spp = 1
ao_distance = 1.0

[materials.m]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]

[[objects]]
shape = "sphere"
material = "m"
segments = 8
scale = 1.0
rotate = [0.0, 0.0, 0.0]

[[lights]]
type = "point"
position = [0.0, 3.0, 3.0]
intensity = 5.0
"#;

/// SCENE with the line `old` replaced by `new`; also the line range an error may name: from
/// the header of the table that holds the line to the line itself.
fn scene_with(old: &str, new: &str) -> (String, usize, usize) {
    let lines: Vec<&str> = SCENE.lines().collect();
    let at = lines
        .iter()
        .position(|l| *l == old)
        .unwrap_or_else(|| panic!("SCENE has no line {old:?}"));
    let header = lines[..at]
        .iter()
        .rposition(|l| l.starts_with('['))
        .unwrap_or(0);
    let mut out: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    out[at] = new.to_string();
    (out.join("\n") + "\n", header + 1, at + 1)
}

/// The error line names `file:LINE` with LINE in `lo..=hi`.
fn names_line(file: &'static str, lo: usize, hi: usize) -> impl Fn(&Got) -> Vec<String> {
    move |g| {
        let Some(err) = g.error_line() else {
            return Vec::new();
        };
        let ok = (lo..=hi).any(|l| err.contains(&format!("{file}:{l}")));
        if ok {
            Vec::new()
        } else {
            vec![format!(
                "the error line does not name {file}:LINE with LINE in {lo}..={hi}: {err}"
            )]
        }
    }
}

fn small_render() -> [&'static str; 8] {
    [
        "--device", "cpu", "--width", "8", "--height", "8", "--spp", "1",
    ]
}

fn with(base: &[&dyn AsArg], more: &[&str]) -> Vec<String> {
    base.iter()
        .map(|a| a.as_arg())
        .chain(more.iter().map(|s| s.to_string()))
        .collect()
}

fn row_args(name: &str, want: Want, args: Vec<String>) -> Row {
    Row {
        name: name.into(),
        args,
        want,
        names: Vec::new(),
        warns: Vec::new(),
        lacks: Vec::new(),
        checks: Vec::new(),
        max_secs: None,
    }
}

// ---------------------------------------------------------------------------------------------
// The table.

/// A check run after a command of the model runs: the problems it finds.
type ModelCheck = dyn Fn() -> Vec<String>;

#[test]
fn hostile_command_lines() {
    let s = Scratch::new();
    let quad = s.write("quad.obj", QUAD);
    let rays = s.path("r.bin");
    write_ray_file(&rays);

    // A mesh with its MTL, and one whose MTL library is named like an image.
    let lit = s.write("lit/mesh.obj", format!("mtllib mesh.mtl\nusemtl a\n{QUAD}"));
    let lit_mtl = s.write("lit/mesh.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
    let weird = s.write("lit/weird.obj", format!("mtllib lib.png\nusemtl a\n{QUAD}"));
    let weird_mtl = s.write("lit/lib.png", "newmtl a\nKd 0.5 0.5 0.5\n");

    // The textured scene with its texture, a copy of it named like an image, and the Cornell
    // scene with its mesh and MTL.
    let textured = s.copy_scene("textured.toml", "tex/textured.toml");
    let checker = s.copy_scene("checker.png", "tex/checker.png");
    let scene_png = s.copy_scene("textured.toml", "tex/scene.png");
    let cornell = scene("cornell.toml");

    let outdir = s.mkdir("outdir.png");
    let mesh_dir = s.mkdir("meshdir.obj");
    let plain_dir = s.mkdir("plaindir");
    let scene_dir = s.mkdir("scenedir.toml");

    let small = small_render();
    let sm: Vec<&str> = small.to_vec();
    let r = |args: &[&dyn AsArg]| with(args, &sm);
    // bench structures on the quad, on the CPU, with `more`.
    let bench_quad =
        |more: &[&str]| with(&[&"bench", &"structures", &quad, &"--device", &"cpu"], more);

    let mut rows = vec![
        // ---- outputs that are inputs
        Row::new(
            "rays: output = the input mesh",
            Want::Fail(2),
            &[&"rays", &quad, &"-o", &quad],
        )
        .names(&["quad.obj"])
        .unchanged(&[&quad]),
        Row::new(
            "trace: output = the ray file",
            Want::Fail(2),
            &[
                &"trace",
                &quad,
                &"--rays",
                &rays,
                &"--out",
                &rays,
                &"--device",
                &"cpu",
            ],
        )
        .names(&["r.bin"])
        .unchanged(&[&quad, &rays]),
        Row::new(
            "trace: output = the mesh",
            Want::Fail(2),
            &[
                &"trace",
                &quad,
                &"--rays",
                &rays,
                &"--out",
                &quad,
                &"--device",
                &"cpu",
            ],
        )
        .names(&["quad.obj"])
        .unchanged(&[&quad, &rays]),
        row_args(
            "render: output = the scene's texture",
            Want::Fail(2),
            r(&[&"render", &textured, &"-o", &checker]),
        )
        .names(&["checker.png"])
        .unchanged(&[&checker, &textured]),
        row_args(
            "render: output = the scene's texture, spelled tex/./checker.png",
            Want::Fail(2),
            r(&[&"render", &textured, &"-o", &s.path("tex/./checker.png")]),
        )
        .names(&["checker.png"])
        .unchanged(&[&checker, &textured]),
        row_args(
            "render: output ends in / (a file's name)",
            Want::Fail(2),
            r(&[&"render", &textured, &"-o", &"slash.png/"]),
        )
        .names(&["slash.png/", "names a folder, not a file"])
        .within(10.0),
        Row::new(
            "rays: output a folder yet to make (newdir/)",
            Want::Fail(2),
            &[&"rays", &quad, &"-o", &"newdir/"],
        )
        .names(&["newdir/", "names a folder, not a file"])
        .absent(&s.path("newdir"))
        .within(10.0),
        row_args(
            "render: an output name of 250 bytes (its temporary name would be longer)",
            Want::Ok,
            r(&[
                &"render",
                &textured,
                &"-o",
                &format!("{}.png", "a".repeat(246)),
            ]),
        ),
        row_args(
            "bench structures: --chart not a .png",
            Want::Fail(2),
            bench_quad(&["--chart", "c.json"]),
        )
        .names(&["c.json", ".png"]),
        row_args(
            "bench structures: --chart ./y.png and --report y.md (whose chart is y.png)",
            Want::Fail(2),
            bench_quad(&["--chart", "./y.png", "--report", "y.md"]),
        )
        .names(&["y.png", "two outputs"]),
        Row::new(
            "merge: output not .exr",
            Want::Fail(2),
            &[&"merge", &quad, &"-o", &"sub"],
        )
        .names(&["sub", "use a .exr file name"])
        .lacks(&[".png"]),
        row_args(
            "render: output = the scene file itself",
            Want::Fail(2),
            r(&[&"render", &textured, &"-o", &textured]),
        )
        .names(&["textured.toml"])
        .unchanged(&[&textured, &checker]),
        row_args(
            "render: output = the scene file itself (a scene named scene.png)",
            Want::Fail(2),
            r(&[&"render", &scene_png, &"-o", &scene_png]),
        )
        .names(&["scene.png"])
        .unchanged(&[&scene_png, &checker]),
        Row::new(
            "rays: output = the mesh's MTL",
            Want::Fail(2),
            &[&"rays", &lit, &"-o", &lit_mtl],
        )
        .names(&["mesh.mtl"])
        .unchanged(&[&lit, &lit_mtl]),
        Row::new(
            "trace: output = the mesh's MTL",
            Want::Fail(2),
            &[
                &"trace",
                &lit,
                &"--rays",
                &rays,
                &"--out",
                &lit_mtl,
                &"--device",
                &"cpu",
            ],
        )
        .names(&["mesh.mtl"])
        .unchanged(&[&lit, &lit_mtl, &rays]),
        row_args(
            "render: output = the mesh's MTL (an MTL named lib.png)",
            Want::Fail(2),
            r(&[&"render", &weird, &"-o", &weird_mtl]),
        )
        .names(&["lib.png"])
        .unchanged(&[&weird, &weird_mtl]),
        Row::new(
            "heatmap: output = the mesh's MTL (an MTL named lib.png)",
            Want::Fail(2),
            &[
                &"heatmap",
                &weird,
                &"-o",
                &weird_mtl,
                &"--device",
                &"cpu",
                &"--width",
                &"8",
                &"--height",
                &"8",
            ],
        )
        .names(&["lib.png"])
        .unchanged(&[&weird, &weird_mtl]),
        // ---- output paths refused before any work
        row_args(
            "render: output in a missing folder fails fast",
            Want::Fail(2),
            with(
                &[&"render", &cornell, &"-o", &"nodir/x.png"],
                &[
                    "--spp", "1000000", "--width", "8", "--height", "8", "--device", "cpu",
                ],
            ),
        )
        .names(&["nodir"])
        .lacks(&["spp ->"])
        .within(20.0)
        .absent(&s.path("nodir")),
        Row::new(
            "rays: output in a missing folder",
            Want::Fail(2),
            &[&"rays", &quad, &"-o", &"nodir/r.bin"],
        )
        .names(&["nodir"]),
        row_args(
            "render: unknown output extension .jpg",
            Want::Fail(2),
            r(&[&"render", &cornell, &"-o", &"out.jpg"]),
        )
        .names(&["out.jpg"])
        .lacks(&["spp ->"])
        .absent(&s.path("out.jpg")),
        row_args(
            "render: output /dev/full",
            Want::Fail(2),
            r(&[&"render", &cornell, &"-o", &"/dev/full"]),
        )
        .names(&["/dev/full"])
        .check(dev_full_intact),
        Row::new(
            "rays: output /dev/full",
            Want::Fail(2),
            &[&"rays", &quad, &"-o", &"/dev/full"],
        )
        .names(&["/dev/full"])
        .check(dev_full_intact),
        Row::new(
            "trace: output /dev/full",
            Want::Fail(2),
            &[
                &"trace",
                &quad,
                &"--rays",
                &rays,
                &"--out",
                &"/dev/full",
                &"--device",
                &"cpu",
            ],
        )
        .names(&["/dev/full"])
        .check(dev_full_intact),
        row_args(
            "render: output is an existing folder",
            Want::Fail(2),
            r(&[&"render", &cornell, &"-o", &outdir]),
        )
        .names(&["outdir.png"])
        .check(is_dir(&outdir)),
        Row::new(
            "rays: output is an existing folder",
            Want::Fail(2),
            &[&"rays", &quad, &"-o", &plain_dir],
        )
        .names(&["plaindir"])
        .check(is_dir(&plain_dir)),
        Row::new(
            "heatmap: .exr output",
            Want::Fail(2),
            &[&"heatmap", &quad, &"-o", &"x.exr", &"--device", &"cpu"],
        )
        .names(&["x.exr"])
        .lacks(&["Rgb8"])
        .absent(&s.path("x.exr")),
    ];

    // An image name that is a link to a device: refused as a device, not by its extension.
    #[cfg(unix)]
    {
        let link = s.path("devfull.png");
        std::os::unix::fs::symlink("/dev/full", &link).unwrap();
        rows.push(
            row_args(
                "render: output devfull.png, a link to /dev/full",
                Want::Fail(2),
                r(&[&"render", &cornell, &"-o", &link]),
            )
            .names(&["devfull.png"])
            .check(dev_full_intact),
        );
        rows.push(
            Row::new(
                "heatmap: output devfull.png, a link to /dev/full",
                Want::Fail(2),
                &[
                    &"heatmap",
                    &quad,
                    &"-o",
                    &link,
                    &"--device",
                    &"cpu",
                    &"--width",
                    &"8",
                    &"--height",
                    &"8",
                ],
            )
            .names(&["devfull.png"])
            .check(dev_full_intact),
        );
    }

    // ---- workgroup sizes the adapter cannot run (the GPU is the point here)
    for wg in ["0", "100000", "4294967295"] {
        rows.push(
            Row::new(
                format!("trace --device gpu --workgroup-size {wg}"),
                Want::Fail(2),
                &[
                    &"trace",
                    &quad,
                    &"--rays",
                    &rays,
                    &"--out",
                    &"h.bin",
                    &"--device",
                    &"gpu",
                    &"--workgroup-size",
                    &wg,
                ],
            )
            .names(&[wg])
            .absent(&s.path("h.bin")),
        );
    }

    // ---- sizes that cannot be allocated
    const LIMIT_WORDS: &[&str] = &[
        "available",
        "more than",
        "limit",
        "at most",
        "exceeds",
        "maximum",
    ];
    let huge_sphere = s.write(
        "huge-sphere.toml",
        SCENE.replace("segments = 8", "segments = 1000000"),
    );
    rows.extend([
        Row::new(
            "render 100000x100000",
            Want::Fail(2),
            &[
                &"render",
                &cornell,
                &"--width",
                &"100000",
                &"--height",
                &"100000",
                &"--device",
                &"cpu",
                &"-o",
                &"big.png",
            ],
        )
        .names(&["100000"])
        .names_one_of(LIMIT_WORDS)
        .absent(&s.path("big.png")),
        Row::new(
            "rays 100000x100000",
            Want::Fail(2),
            &[
                &"rays",
                &quad,
                &"--width",
                &"100000",
                &"--height",
                &"100000",
                &"-o",
                &"big.bin",
            ],
        )
        .names(&["100000"])
        .names_one_of(LIMIT_WORDS)
        .absent(&s.path("big.bin")),
        Row::new(
            "heatmap 100000x100000",
            Want::Fail(2),
            &[
                &"heatmap",
                &quad,
                &"--width",
                &"100000",
                &"--height",
                &"100000",
                &"--device",
                &"cpu",
                &"-o",
                &"h.png",
            ],
        )
        .names(&["100000"])
        .names_one_of(LIMIT_WORDS),
        row_args(
            "scene: sphere segments = 1000000",
            Want::Fail(2),
            r(&[&"render", &huge_sphere, &"-o", &"sphere.png"]),
        )
        .names(&["huge-sphere.toml", "1000000"])
        .names_one_of(LIMIT_WORDS),
    ]);

    // 65535² pixels fit the u32 pixel index; their buffers (~200 GiB) fit no test machine.
    // Where they might, the row would render for hours instead: skip it there.
    match lancer::limits::available_memory() {
        Some(m) if m < 150 << 30 => rows.push(
            Row::new(
                "render 65535x65535 (pixels fit u32, memory does not)",
                Want::Fail(2),
                &[
                    &"render",
                    &cornell,
                    &"--width",
                    &"65535",
                    &"--height",
                    &"65535",
                    &"--device",
                    &"cpu",
                    &"-o",
                    &"big2.png",
                ],
            )
            .names(&["65535"])
            .names_one_of(LIMIT_WORDS),
        ),
        m => println!("note: skipping the 65535x65535 row ({m:?} bytes available)"),
    }

    // ---- values in a scene file, refused with FILE:LINE
    rows.push(row_args(
        "scene: the valid base scene renders (control)",
        Want::Ok,
        r(&[&"render", &s.write("base.toml", SCENE), &"-o", &"base.png"]),
    ));
    let bad_values: &[(&str, &str, &str, &str)] = &[
        (
            "up parallel to the view",
            "v-up-parallel.toml",
            "up = [0.0, 1.0, 0.0]",
            "up = [0.0, -2.0, -10.0]",
        ),
        (
            "up = [0,0,0]",
            "v-up-zero.toml",
            "up = [0.0, 1.0, 0.0]",
            "up = [0.0, 0.0, 0.0]",
        ),
        (
            "position with nan",
            "v-position-nan.toml",
            "position = [0.0, 1.0, 5.0]",
            "position = [nan, 1.0, 5.0]",
        ),
        (
            "light intensity = nan",
            "v-intensity-nan.toml",
            "intensity = 5.0",
            "intensity = nan",
        ),
        (
            "object scale = nan",
            "v-scale-nan.toml",
            "scale = 1.0",
            "scale = nan",
        ),
        (
            "object rotate = [nan, 0, 0]",
            "v-rotate-nan.toml",
            "rotate = [0.0, 0.0, 0.0]",
            "rotate = [nan, 0.0, 0.0]",
        ),
        (
            "ao_distance = -1",
            "v-ao-negative.toml",
            "ao_distance = 1.0",
            "ao_distance = -1.0",
        ),
        ("spp = 0", "v-spp-zero.toml", "spp = 1", "spp = 0"),
        (
            "max_bounces = 4000000000 (every sample a hang)",
            "v-bounces-huge.toml",
            "spp = 1",
            "spp = 1\nmax_bounces = 4000000000",
        ),
        (
            "sphere segments = 2",
            "v-segments-2.toml",
            "segments = 8",
            "segments = 2",
        ),
    ];
    for &(what, file, old, new) in bad_values {
        let (text, lo, hi) = scene_with(old, new);
        let path = s.write(file, text);
        rows.push(
            row_args(
                &format!("scene: {what}"),
                Want::Fail(2),
                r(&[&"render", &path, &"-o", &"v.png"]),
            )
            .names(&[file])
            .check(names_line(file, lo, hi))
            .absent(&s.path("v.png")),
        );
    }
    // A material name with a line break must not break the one-line error.
    let newline_name = s.write(
        "v-newline-name.toml",
        SCENE.replace("material = \"m\"", "material = \"no\\nsuch\""),
    );
    rows.push(
        row_args(
            "scene: unknown material whose name holds a line break",
            Want::Fail(2),
            r(&[&"render", &newline_name, &"-o", &"v.png"]),
        )
        .names(&["v-newline-name.toml"]),
    );

    // ---- CLI values
    rows.extend([
        Row::new(
            "build --t-cube nan",
            Want::Fail(2),
            &[&"build", &quad, &"--t-cube", &"nan"],
        ),
        Row::new(
            "build --t-cube -1",
            Want::Fail(2),
            &[&"build", &quad, &"--t-cube=-1"],
        ),
        Row::new(
            "build --t-obj 0",
            Want::Fail(2),
            &[&"build", &quad, &"--t-obj", &"0"],
        ),
        Row::new(
            "rays --width 0",
            Want::Fail(2),
            &[&"rays", &quad, &"--width", &"0", &"-o", &"w.bin"],
        )
        .absent(&s.path("w.bin")),
        Row::new(
            "heatmap --width 0",
            Want::Fail(2),
            &[
                &"heatmap",
                &quad,
                &"--width",
                &"0",
                &"-o",
                &"w.png",
                &"--device",
                &"cpu",
            ],
        )
        .absent(&s.path("w.png")),
        Row::new(
            "bench trace --repeat 0",
            Want::Fail(2),
            &[
                &"bench",
                &"trace",
                &quad,
                &"--repeat",
                &"0",
                &"--device",
                &"cpu",
            ],
        ),
        row_args(
            "render --time-limit nan",
            Want::Fail(2),
            r(&[
                &"render",
                &cornell,
                &"-o",
                &"t.png",
                &"--time-limit",
                &"nan",
            ]),
        )
        .absent(&s.path("t.png")),
        // Finite but beyond what a Duration holds: refused as usage, not a panic.
        row_args(
            "render --time-limit 1e20",
            Want::Fail(2),
            r(&[
                &"render",
                &cornell,
                &"-o",
                &"t.png",
                &"--time-limit",
                &"1e20",
            ]),
        )
        .absent(&s.path("t.png")),
        row_args(
            "render --width 0",
            Want::Fail(2),
            with(
                &[
                    &"render",
                    &cornell,
                    &"-o",
                    &"t.png",
                    &"--width",
                    &"0",
                    &"--device",
                    &"cpu",
                ],
                &["--spp", "1"],
            ),
        )
        .absent(&s.path("t.png")),
    ]);

    // ---- MTL values, refused with m.mtl:LINE
    for (what, stmt, want) in [
        ("Kd nan", "Kd nan 0.5 0.5", Want::Fail(2)),
        ("Kd -1", "Kd -1 0 0", Want::Fail(2)),
        ("Ke inf", "Ke inf 1 1", Want::Fail(2)),
        // Found by tests/fuzz_readers.rs: tobj panics on a colour with fewer than 3 numbers.
        ("Kd with no numbers", "Kd", Want::Fail(2)),
        ("Ke with no numbers", "Ke", Want::Fail(2)),
        // MTL lets g and b default to r: a grey, or a refusal; never a panic.
        ("Kd with one number", "Kd 0.5", Want::OkOrFail2),
    ] {
        let sub = format!("mtl-{}", what.replace(' ', "-"));
        let obj = s.write(
            &format!("{sub}/x.obj"),
            format!("mtllib m.mtl\nusemtl a\n{QUAD}"),
        );
        s.write(
            &format!("{sub}/m.mtl"),
            format!("newmtl a\nKa 0 0 0\n{stmt}\n"),
        );
        rows.push(
            row_args(
                &format!("MTL: {what}"),
                want,
                r(&[&"render", &obj, &"-o", &s.path(&format!("{sub}/x.png"))]),
            )
            .names(&["m.mtl:3"]),
        );
        rows.push(
            Row::new(format!("MTL: {what} (build)"), want, &[&"build", &obj]).names(&["m.mtl:3"]),
        );
    }
    let unknown = s.write(
        "usemtl/x.obj",
        "mtllib m.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nusemtl unknown\nf 1 2 3\n",
    );
    s.write("usemtl/m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
    rows.push(
        row_args(
            "MTL: usemtl of an unknown material warns",
            Want::Ok,
            r(&[&"render", &unknown, &"-o", &s.path("usemtl/x.png")]),
        )
        .warns(&["x.obj:5", "unknown"]),
    );
    let nothere = s.write("nomtl/x.obj", format!("mtllib nothere.mtl\n{QUAD}"));
    rows.push(
        row_args(
            "MTL: a missing MTL library warns",
            Want::Ok,
            r(&[&"render", &nothere, &"-o", &s.path("nomtl/x.png")]),
        )
        .warns(&["nothere.mtl"]),
    );

    // ---- glTF meshes with triangles left out: counted, and refused when none is left, by
    // every command (build and trace read a glTF through another path than render's)
    let gltf = |nodes: usize, tris: &str| {
        let (bytes, count, data) = match tris {
            "nan" => (36, 3, "AADAfwAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"),
            _ => (
                72,
                6,
                "AADAfwAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAAAAAACAPwAAAAAAAAAA\
                 AAAAAAAAgD8AAAAA",
            ),
        };
        let node_list: Vec<String> = (0..nodes).map(|i| i.to_string()).collect();
        let node_defs: Vec<String> = (0..nodes)
            .map(|i| format!(r#"{{"mesh":0,"translation":[{},0,0]}}"#, 3 * i))
            .collect();
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "buffers":[{{"byteLength":{bytes},"uri":"data:application/octet-stream;base64,{data}"}}],
            "bufferViews":[{{"buffer":0,"byteLength":{bytes}}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3",
            "min":[0,0,0],"max":[1,1,0]}}]}}"#,
            node_list.join(","),
            node_defs.join(",")
        )
    };
    for (nodes, what) in [(1, "one node"), (2, "two nodes: instances")] {
        let none = s.write(
            &format!("gltf-left-out/none{nodes}.gltf"),
            gltf(nodes, "nan"),
        );
        let half = s.write(
            &format!("gltf-left-out/half{nodes}.gltf"),
            gltf(nodes, "half"),
        );
        let hits = s.path(&format!("gltf-left-out/h{nodes}.hits"));
        let trace = |m: &Path| -> Vec<String> {
            with(
                &[&"trace", &m, &"--rays", &rays, &"-o", &hits],
                &["--device", "cpu"],
            )
        };
        // Each instance's copy of the triangle is left out.
        let left_out = format!("{nodes} with NaN/Inf vertices");
        let (none_name, half_name) = (format!("none{nodes}.gltf"), format!("half{nodes}.gltf"));
        rows.extend([
            Row::new(
                format!("glTF, {what}: no usable triangle (build)"),
                Want::Fail(2),
                &[&"build", &none],
            )
            .names(&[&none_name, "no usable triangle"]),
            row_args(
                &format!("glTF, {what}: no usable triangle (trace)"),
                Want::Fail(2),
                trace(&none),
            )
            .names(&[&none_name, "no usable triangle"]),
            Row::new(
                format!("glTF, {what}: no usable triangle (rays)"),
                Want::Fail(2),
                &[
                    &"rays",
                    &none,
                    &"-o",
                    &s.path(&format!("gltf-left-out/r{nodes}.rays")),
                ],
            )
            .names(&[&none_name, "no usable triangle"]),
            Row::new(
                format!("glTF, {what}: one triangle left out (build)"),
                Want::Ok,
                &[&"build", &half],
            )
            .warns(&[&half_name, &left_out]),
            row_args(
                &format!("glTF, {what}: one triangle left out (trace)"),
                Want::Ok,
                trace(&half),
            )
            .warns(&[&half_name, &left_out]),
        ]);
    }
    // A glTF camera without a name is named by its index.
    let camera = s.write(
        "gltf-camera/cam.gltf",
        gltf(1, "half")
            .replacen(
                r#""nodes":[{"mesh":0,"translation":[0,0,0]}]"#,
                r#""nodes":[{"mesh":0,"translation":[0,0,0]},{"camera":0,"translation":[0,0,5]}],
            "cameras":[{"type":"perspective","perspective":{"yfov":0,"znear":0.1}}]"#,
                1,
            )
            .replacen(r#""nodes":[0]"#, r#""nodes":[0,1]"#, 1),
    );
    rows.push(
        row_args(
            "glTF: a degenerate camera without a name",
            Want::Ok,
            r(&[&"render", &camera, &"-o", &s.path("gltf-camera/x.png")]),
        )
        .check(|got: &Got| {
            let named = got
                .warnings()
                .iter()
                .any(|w| w.contains("camera \"#0\" not used"));
            match named {
                true => Vec::new(),
                false => vec!["no warning naming camera \"#0\"".into()],
            }
        })
        .lacks(&["None", "Some("]),
    );

    // ---- a check without a GPU, and views past f32's range
    rows.extend([
        Row::new(
            "check: --device cpu leaves nothing to check (a usage error, not a device's)",
            Want::Fail(2),
            &[
                &"check",
                &quad,
                &"--device",
                &"cpu",
                &"--width",
                &"4",
                &"--height",
                &"4",
            ],
        )
        .names(&["--device cpu"]),
        row_args(
            "render: an eye too far for f32",
            Want::Fail(2),
            r(&[
                &"render",
                &quad,
                &"-o",
                &s.path("far.png"),
                &"--look-from",
                &"1e38,0,0",
            ]),
        )
        .names(&["--look-from", "too far"])
        .absent(&s.path("far.png")),
        row_args(
            "render: a field of view so narrow the framed eye is too far for f32",
            Want::Fail(2),
            r(&[
                &"render",
                &quad,
                &"-o",
                &s.path("narrow.png"),
                &"--fov",
                &"1e-30",
            ]),
        )
        .names(&["--fov", "too far"])
        .absent(&s.path("narrow.png")),
    ]);

    // ---- missing, folder and unreadable inputs
    let missing_mesh_scene = s.write(
        "v-missing-mesh.toml",
        SCENE.replace("shape = \"sphere\"", "mesh = \"missing.obj\""),
    );
    let mut not_utf8 =
        b"[camera]\nposition = [0.0, 1.0, 5.0]\nlook_at = [0.0, 0.0, 0.0] # caf\xe9\n".to_vec();
    not_utf8.extend_from_slice(&SCENE.as_bytes()[SCENE.find("up =").unwrap()..]);
    let not_utf8 = s.write("latin1.toml", not_utf8);
    let not_utf8_obj = s.write(
        "latin1.obj",
        b"# ok\nv 0 0 0 # caf\xe9\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    rows.extend([
        Row::new(
            "build: missing mesh",
            Want::Fail(2),
            &[&"build", &"missing.obj"],
        )
        .names(&["missing.obj"]),
        Row::new(
            "build: a folder as mesh",
            Want::Fail(2),
            &[&"build", &mesh_dir],
        )
        .names(&["meshdir.obj"]),
        Row::new(
            "rays: a folder as mesh",
            Want::Fail(2),
            &[&"rays", &mesh_dir, &"-o", &"f.bin"],
        )
        .names(&["meshdir.obj"]),
        row_args(
            "render: missing scene",
            Want::Fail(2),
            r(&[&"render", &"missing.toml", &"-o", &"m.png"]),
        )
        .names(&["missing.toml"]),
        row_args(
            "render: a folder as scene",
            Want::Fail(2),
            r(&[&"render", &scene_dir, &"-o", &"m.png"]),
        )
        .names(&["scenedir.toml"]),
        row_args(
            "render: a folder as OBJ",
            Want::Fail(2),
            r(&[&"render", &mesh_dir, &"-o", &"m.png"]),
        )
        .names(&["meshdir.obj"]),
        Row::new(
            "trace: missing ray file",
            Want::Fail(2),
            &[
                &"trace",
                &quad,
                &"--rays",
                &"missing.bin",
                &"--out",
                &"h.bin",
                &"--device",
                &"cpu",
            ],
        )
        .names(&["missing.bin"]),
        Row::new(
            "trace: a folder as ray file",
            Want::Fail(2),
            &[
                &"trace",
                &quad,
                &"--rays",
                &plain_dir,
                &"--out",
                &"h.bin",
                &"--device",
                &"cpu",
            ],
        )
        .names(&["plaindir"]),
        row_args(
            "scene: mesh = \"missing.obj\"",
            Want::Fail(2),
            r(&[&"render", &missing_mesh_scene, &"-o", &"m.png"]),
        )
        .names(&["missing.obj"]),
        row_args(
            "scene: not UTF-8 (Latin-1 on line 3)",
            Want::Fail(2),
            r(&[&"render", &not_utf8, &"-o", &"m.png"]),
        )
        .names(&["latin1.toml:3"])
        .lacks(&["offset", "byte "]),
        Row::new(
            "build: OBJ not UTF-8 (line 2)",
            Want::Fail(2),
            &[&"build", &not_utf8_obj],
        )
        .names(&["latin1.obj:2"])
        .lacks(&["offset"]),
    ]);

    // ---- files named inside inputs: devices, FIFOs, huge textures, outputs over them
    let fifo = |rel: &str| {
        let p = s.path(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        let made = Command::new("mkfifo")
            .arg(&p)
            .status()
            .expect("mkfifo runs");
        assert!(made.success(), "mkfifo {}", p.display());
        p
    };
    let zero_mtl = s.write(
        "named/zero.obj",
        format!("mtllib /dev/zero\nusemtl a\n{QUAD}"),
    );
    fifo("named/fifo.mtl");
    let fifo_mtl = s.write(
        "named/fifomtl.obj",
        format!("mtllib fifo.mtl\nusemtl a\n{QUAD}"),
    );
    let fifo_mesh = fifo("named/fifo.obj");
    let zero_link = s.path("named/zero-link.obj");
    std::os::unix::fs::symlink("/dev/zero", &zero_link).unwrap();
    fifo("named/fifo.png");
    let fifo_tex_scene = s.write(
        "named/fifotex.toml",
        std::fs::read_to_string(&textured)
            .unwrap()
            .replace("checker.png", "fifo.png"),
    );
    s.write("named/big.png", png_header(22_000, 22_000));
    let big_tex_scene = s.write(
        "named/bigtex.toml",
        std::fs::read_to_string(&textured)
            .unwrap()
            .replace("checker.png", "big.png"),
    );
    // A Radiance HDR of 0×0 pixels, which the image decoder accepts.
    s.write(
        "named/empty.hdr",
        "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 0\n",
    );
    let empty_tex_scene = s.write(
        "named/emptytex.toml",
        std::fs::read_to_string(&textured)
            .unwrap()
            .replace("checker.png", "empty.hdr"),
    );
    // An OBJ whose MTL names a texture: every command's output refuses the texture's name.
    let tex_obj = s.write("named/tex.obj", format!("mtllib tex.mtl\nusemtl a\n{QUAD}"));
    s.write(
        "named/tex.mtl",
        "newmtl a\nKd 0.5 0.5 0.5\nmap_Kd tex.png\n",
    );
    let tex_png = s.copy_scene("checker.png", "named/tex.png");
    rows.extend([
        row_args(
            "render: mtllib /dev/zero",
            Want::Ok,
            r(&[&"render", &zero_mtl, &"-o", &"zero-mtl.png"]),
        )
        .warns(&["/dev/zero", "not a regular file"])
        .within(60.0),
        row_args(
            "render: mtllib a FIFO",
            Want::Ok,
            r(&[&"render", &fifo_mtl, &"-o", &"fifo-mtl.png"]),
        )
        .warns(&["fifo.mtl", "not a regular file"])
        .within(60.0),
        Row::new("build: mtllib a FIFO", Want::Ok, &[&"build", &fifo_mtl]).within(30.0),
        Row::new(
            "build: the mesh a FIFO",
            Want::Fail(2),
            &[&"build", &fifo_mesh],
        )
        .names(&["fifo.obj", "not a regular file"])
        .within(30.0),
        Row::new(
            "build: the mesh a link to /dev/zero",
            Want::Fail(2),
            &[&"build", &zero_link],
        )
        .names(&["zero-link.obj", "not a regular file"])
        .within(30.0),
        row_args(
            "render: a texture that is a FIFO",
            Want::Fail(2),
            r(&[&"render", &fifo_tex_scene, &"-o", &"fifo-tex.png"]),
        )
        .names(&["fifo.png", "not a regular file"])
        .within(60.0),
        row_args(
            "render: a 22000×22000 texture (its PNG header)",
            Want::Fail(2),
            r(&[&"render", &big_tex_scene, &"-o", &"big-tex.png"]),
        )
        .names(&["big.png", "22000×22000", "16384"])
        .within(60.0),
        row_args(
            "render: a 0×0 texture (an HDR header)",
            Want::Fail(2),
            r(&[&"render", &empty_tex_scene, &"-o", &"empty-tex.png"]),
        )
        .names(&["empty.hdr", "0×0", "no texels"])
        .within(60.0),
        Row::new(
            "heatmap: output = the MTL's texture",
            Want::Fail(2),
            &[&"heatmap", &tex_obj, &"-o", &tex_png, &"--device", &"cpu"],
        )
        .names(&["tex.png"])
        .unchanged(&[&tex_png]),
        Row::new(
            "build: output = the MTL's texture",
            Want::Fail(2),
            &[&"build", &tex_obj, &"--out", &tex_png],
        )
        .names(&["tex.png"])
        .unchanged(&[&tex_png]),
        Row::new(
            "rays: output = the MTL's texture",
            Want::Fail(2),
            &[&"rays", &tex_obj, &"-o", &tex_png],
        )
        .names(&["tex.png"])
        .unchanged(&[&tex_png]),
        Row::new(
            "trace: output = the MTL's texture",
            Want::Fail(2),
            &[
                &"trace",
                &tex_obj,
                &"--rays",
                &rays,
                &"-o",
                &tex_png,
                &"--device",
                &"cpu",
            ],
        )
        .names(&["tex.png"])
        .unchanged(&[&tex_png]),
        Row::new(
            "bench structures: --chart = the MTL's texture",
            Want::Fail(2),
            &[&"bench", &"structures", &tex_obj, &"--chart", &tex_png],
        )
        .names(&["tex.png"])
        .unchanged(&[&tex_png]),
        Row::new(
            "bench structures: --json and --chart one file (a chart is a .png)",
            Want::Fail(2),
            &[
                &"bench",
                &"structures",
                &quad,
                &"--json",
                &"same.json",
                &"--chart",
                &"same.json",
            ],
        )
        .names(&["same.json", ".png"])
        .absent(&s.path("same.json"))
        .within(30.0),
    ]);

    // The albedo row accepts either policy: refused with FILE:LINE, or clamped with a warning.
    let (text, lo, hi) = scene_with("albedo = [0.5, 0.5, 0.5]", "albedo = [2.0, 0.5, 0.5]");
    let bright = s.write("v-albedo-2.toml", text);
    let albedo_args = r(&[&"render", &bright, &"-o", &"albedo.png"]);

    run_table(s.dir(), rows);
    albedo_above_one(s.dir(), albedo_args, lo, hi);
}

fn dev_full_intact(_: &Got) -> Vec<String> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        match std::fs::metadata("/dev/full") {
            Ok(m) if m.file_type().is_char_device() => Vec::new(),
            _ => vec!["/dev/full is no longer a character device".into()],
        }
    }
    #[cfg(not(unix))]
    Vec::new()
}

fn is_dir(p: &Path) -> impl Fn(&Got) -> Vec<String> {
    let p = p.to_path_buf();
    move |_| {
        if p.is_dir() {
            Vec::new()
        } else {
            vec![format!("{} is no longer a folder", p.display())]
        }
    }
}

/// `albedo = [2, 0.5, 0.5]`: exit 0 with a warning about the albedo (naming the file), or
/// exit 2 naming the file and line; nothing else.
fn albedo_above_one(dir: &Path, args: Vec<String>, lo: usize, hi: usize) {
    let got = run_in(dir, &args);
    println!(
        "albedo above 1\n    $ {}\n    {}",
        command_line(&args),
        got.show()
    );
    let (want, extra): (Want, Vec<String>) = match got.code {
        Some(0) => {
            let warned = got
                .warnings()
                .iter()
                .any(|w| w.contains("albedo") && w.contains("v-albedo-2.toml"));
            let why = if warned {
                Vec::new()
            } else {
                vec!["exit 0 without a warning naming v-albedo-2.toml and the albedo".into()]
            };
            (Want::Ok, why)
        }
        _ => (Want::Fail(2), names_line("v-albedo-2.toml", lo, hi)(&got)),
    };
    let row = row_args("scene: albedo [2, 0.5, 0.5]", want, args.clone());
    let mut p = problems(&row, &got);
    p.extend(extra);
    assert!(
        p.is_empty(),
        "albedo above 1 (want exit 0 with a warning, or exit 2 with FILE:LINE):\n    $ {}\n    {}\n    !! {}",
        command_line(&args),
        got.show(),
        p.join("\n    !! ")
    );
}

// ---------------------------------------------------------------------------------------------
// Huge coordinates: work with finite results, or refuse / drop with the range named.

fn finite_ray_file(path: &Path) -> Vec<String> {
    match std::fs::read(path) {
        Ok(bytes) => {
            let bad = bytes
                .chunks_exact(4)
                .filter(|c| !f32::from_le_bytes([c[0], c[1], c[2], c[3]]).is_finite())
                .count();
            if bad > 0 {
                vec![format!(
                    "{}: {bad} non-finite floats in the rays written",
                    path.display()
                )]
            } else if bytes.is_empty() {
                vec![format!("{}: no rays written", path.display())]
            } else {
                Vec::new()
            }
        }
        Err(e) => vec![format!("{}: exit 0 but no ray file: {e}", path.display())],
    }
}

fn finite_hit_file(path: &Path) -> Vec<String> {
    match lancer::trace::files::read_hits(path) {
        Ok(hits) => {
            let bad = hits
                .iter()
                .filter(|h| !(h.t.is_finite() && h.u.is_finite() && h.v.is_finite()))
                .count();
            if bad > 0 {
                vec![format!(
                    "{}: {bad} hits with non-finite t/u/v",
                    path.display()
                )]
            } else {
                Vec::new()
            }
        }
        Err(e) => vec![format!(
            "{}: exit 0 but no readable hit file: {e}",
            path.display()
        )],
    }
}

#[test]
fn huge_coordinates_work_or_are_refused_with_the_range() {
    let s = Scratch::new();
    let mut failed = Vec::new();
    for scale in ["1e13", "1e30"] {
        let alone = s.write(
            &format!("big-{scale}.obj"),
            format!("v 0 0 0\nv {scale} 0 0\nv 0 {scale} 0\nf 1 2 3\n"),
        );
        let mixed = s.write(
            &format!("mixed-{scale}.obj"),
            format!("v 0 0 0\nv {scale} 0 0\nv 0 {scale} 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\nf 4 5 6\n"),
        );
        let rays = s.path(&format!("aim-{scale}.bin"));
        let far: f32 = scale.parse().unwrap();
        let near: Vec<Ray> = [(0.25f32, 0.25f32, 5.0f32), (far * 0.25, far * 0.25, far)]
            .iter()
            .map(|&(x, y, z)| Ray::new(Vec3::new(x, y, z), Vec3::NEG_Z, 0.0, 1e30))
            .collect();
        lancer::trace::files::write_rays(&rays, &near).unwrap();

        for mesh in [&alone, &mixed] {
            let stem = mesh.file_stem().unwrap().to_str().unwrap().to_string();
            let r_out = s.path(&format!("{stem}.rays"));
            let h_cpu = s.path(&format!("{stem}-cpu.hits"));
            let h_gpu = s.path(&format!("{stem}-gpu.hits"));
            let png = s.path(&format!("{stem}.png"));
            let m = mesh.to_str().unwrap().to_string();
            // `trace` of the aimed rays on `device`, the hits to `hits`: a finite hit file.
            let trace = |device: &str, hits: &Path| -> (Vec<String>, Box<ModelCheck>) {
                let args = with(
                    &[&"trace", &m, &"--rays", &rays, &"--out", &hits],
                    &["--device", device],
                );
                let hits = hits.to_path_buf();
                (args, Box::new(move || finite_hit_file(&hits)))
            };
            let runs: Vec<(Vec<String>, Box<ModelCheck>)> = vec![
                (
                    vec!["build".into(), m.clone(), "--json".into()],
                    Box::new(Vec::new),
                ),
                (
                    vec![
                        "rays".into(),
                        m.clone(),
                        "--width".into(),
                        "8".into(),
                        "--height".into(),
                        "8".into(),
                        "-o".into(),
                        r_out.to_str().unwrap().into(),
                    ],
                    Box::new({
                        let r_out = r_out.clone();
                        move || finite_ray_file(&r_out)
                    }),
                ),
                trace("cpu", &h_cpu),
                trace("gpu", &h_gpu),
                (
                    with(
                        &[&"render", &m, &"-o", &png],
                        &[
                            "--device", "cpu", "--width", "8", "--height", "8", "--spp", "1",
                        ],
                    ),
                    Box::new({
                        let png = png.clone();
                        move || match image::open(&png) {
                            Ok(_) => Vec::new(),
                            Err(e) => vec![format!("exit 0 but no readable image: {e}")],
                        }
                    }),
                ),
            ];
            for (args, output_ok) in runs {
                let got = run_in(s.dir(), &args);
                let want = if got.code == Some(0) {
                    Want::Ok
                } else {
                    Want::Fail(2)
                };
                let row = row_args(&format!("{stem}: {}", args[0]), want, args.clone());
                let mut p = problems(&row, &got);
                // stdout only: the invalid-ray warning legitimately says "NaN/Inf".
                for bad in ["NaN", "nan", "null", "inf", "Infinity"] {
                    let words = got.stdout.split(|c: char| !c.is_ascii_alphanumeric());
                    if words.clone().any(|w| w == bad) {
                        p.push(format!("stdout shows {bad:?} (SAH cost, bounds or counts)"));
                    }
                }
                let names_range = |t: &str| t.contains("range") || t.contains("1e11");
                if got.code == Some(0) {
                    p.extend(output_ok());
                    if args[0] == "build" {
                        match serde_json::from_str::<serde_json::Value>(got.stdout.trim()) {
                            Ok(j) => {
                                if !j["sah_cost"].as_f64().is_some_and(f64::is_finite) {
                                    p.push(format!(
                                        "sah_cost is not a finite number: {}",
                                        j["sah_cost"]
                                    ));
                                }
                            }
                            Err(e) => p.push(format!("build --json printed no JSON object: {e}")),
                        }
                    }
                    // A dropped triangle is counted in a warning naming the supported range.
                    for w in got.warnings() {
                        if w.contains("left out") && !names_range(w) {
                            p.push(format!(
                                "a warning about dropped triangles names no range: {w}"
                            ));
                        }
                    }
                    if mesh == &mixed && !got.warnings().iter().any(|w| names_range(w)) {
                        // Kept: then the results must be finite (checked above); say so.
                        println!("    note: {stem} {} kept the {scale} triangle", args[0]);
                    }
                } else if !names_range(&got.stderr) {
                    p.push("refused without naming the supported coordinate range".into());
                }
                let verdict = if p.is_empty() { "ok" } else { "FAIL" };
                println!(
                    "[{verdict}] {stem}\n    $ {}\n    {}",
                    command_line(&args),
                    got.show()
                );
                for x in &p {
                    println!("    !! {x}");
                }
                if !p.is_empty() {
                    failed.push(format!(
                        "$ {}\n    {}\n    !! {}",
                        command_line(&args),
                        got.show(),
                        p.join("\n    !! ")
                    ));
                }
            }
        }
    }
    assert!(
        failed.is_empty(),
        "huge coordinates:\n\n{}",
        failed.join("\n\n")
    );
}

// ---------------------------------------------------------------------------------------------
// Signals: the render saves what it has and exits 130.

#[cfg(unix)]
fn interrupted_render_saves_and_exits_130(signal: &str) {
    let s = Scratch::new();
    let png = s.path("x.png");
    let args: Vec<String> = with(
        &[&"render", &scene("cornell.toml"), &"-o", &png],
        &[
            "--device", "cpu", "--spp", "100000", "--width", "32", "--height", "32",
        ],
    );
    let start = Instant::now();
    let mut child = spawn(s.dir(), &args);
    // Let it load, build and start sampling; it must still be running after ~2 s.
    let mut early = None;
    while start.elapsed() < Duration::from_secs(2) {
        if let Some(status) = child.try_wait().unwrap() {
            early = Some(status);
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    if early.is_none() {
        let kill = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .expect("run kill");
        assert!(kill.success(), "kill -{signal} failed");
    }
    let got = finish(child, start);
    println!(
        "SIG{signal}\n    $ {}\n    {}",
        command_line(&args),
        got.show()
    );
    assert!(
        early.is_none(),
        "the render ended before the signal: {}",
        got.show()
    );
    let mut p = Vec::new();
    if got.code != Some(130) {
        p.push(format!(
            "want exit 130 after SIG{signal}, got {:?}",
            got.code
        ));
    }
    if got.hung {
        p.push("did not stop after the signal".into());
    }
    if got.stderr.contains("panicked at") {
        p.push("stderr shows a panic".into());
    }
    match image::open(&png) {
        Ok(img) => {
            if (img.width(), img.height()) != (32, 32) {
                p.push(format!(
                    "saved image is {}x{}, want 32x32",
                    img.width(),
                    img.height()
                ));
            }
        }
        Err(e) => p.push(format!("no valid PNG saved at {}: {e}", png.display())),
    }
    let leftovers: Vec<String> = std::fs::read_dir(s.dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    if !leftovers.is_empty() {
        p.push(format!("temporary files left behind: {leftovers:?}"));
    }
    assert!(
        p.is_empty(),
        "SIG{signal}:\n    $ {}\n    {}\n    !! {}",
        command_line(&args),
        got.show(),
        p.join("\n    !! ")
    );
}

#[cfg(unix)]
#[test]
fn sigterm_saves_the_image_and_exits_130() {
    interrupted_render_saves_and_exits_130("TERM");
}

#[cfg(unix)]
#[test]
fn sigint_saves_the_image_and_exits_130() {
    interrupted_render_saves_and_exits_130("INT");
}

// Signals: any other command ends with 130 and leaves its outputs as they were.

#[cfg(unix)]
#[test]
fn an_interrupted_write_leaves_no_temporary_file() {
    let s = Scratch::new();
    let mesh = s.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let out = s.path("big.bin");
    // 16M rays, 512 MB: long enough to be caught while the file is written.
    let args: Vec<String> = with(
        &[&"rays", &mesh, &"-o", &out],
        &["--width", "4096", "--height", "4096"],
    );
    let temporaries = || -> Vec<String> {
        std::fs::read_dir(s.dir())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    };
    let start = Instant::now();
    let mut child = spawn(s.dir(), &args);
    let mut seen = false;
    while !seen && start.elapsed() < Duration::from_secs(60) {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        seen = !temporaries().is_empty();
        std::thread::sleep(Duration::from_millis(2));
    }
    if seen {
        let kill = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .expect("run kill");
        assert!(kill.success(), "kill -INT failed");
    }
    let got = finish(child, start);
    println!("    $ {}\n    {}", command_line(&args), got.show());
    assert!(seen, "never caught the temporary file: {}", got.show());
    assert_eq!(got.code, Some(130), "{}", got.show());
    assert!(
        got.stderr.contains("interrupted: nothing saved"),
        "{}",
        got.show()
    );
    assert_eq!(temporaries(), Vec::<String>::new(), "temporary files left");
    assert!(
        !out.exists(),
        "a partial output was left at {}",
        out.display()
    );
}

/// `--rays -` reads whatever stdin is: a ray file redirected to it is an input, so the hits
/// may not go over it (as with `--rays /dev/stdin`).
#[cfg(unix)]
#[test]
fn a_file_redirected_to_stdin_is_an_input() {
    let s = Scratch::new();
    let quad = s.write("quad.obj", QUAD);
    let rays = s.path("r.bin");
    write_ray_file(&rays);
    let before = std::fs::read(&rays).unwrap();
    for out in ["r.bin", "./r.bin"] {
        let args: Vec<String> = [
            "trace", "quad.obj", "--rays", "-", "-o", out, "--device", "cpu",
        ]
        .map(String::from)
        .to_vec();
        let got = Command::new(env!("CARGO_BIN_EXE_lancer"))
            .args(&args)
            .current_dir(s.dir())
            .stdin(std::fs::File::open(&rays).unwrap())
            .output()
            .expect("run lancer");
        let stderr = String::from_utf8_lossy(&got.stderr);
        assert_eq!(
            got.status.code(),
            Some(2),
            "{}: {stderr}",
            command_line(&args)
        );
        assert!(
            stderr.contains("is an input"),
            "{}: {stderr}",
            command_line(&args)
        );
        assert_eq!(std::fs::read(&rays).unwrap(), before, "r.bin changed");
    }
    // Stdin from elsewhere: the same output is fine.
    let hits = Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args([
            "trace", "quad.obj", "--rays", "-", "-o", "h.bin", "--device", "cpu",
        ])
        .current_dir(s.dir())
        .stdin(std::fs::File::open(&rays).unwrap())
        .status()
        .expect("run lancer");
    assert!(hits.success());
    let _ = quad;
}

/// More threads than the system gives (here: their stacks beyond an address-space limit)
/// is a refusal naming --threads, not a panic at the first parallel step.
#[cfg(target_os = "linux")]
#[test]
fn threads_the_system_refuses_are_refused() {
    let s = Scratch::new();
    let quad = s.write("quad.obj", QUAD);
    let run = |threads: &str| {
        Command::new("prlimit")
            .arg("--as=2000000000")
            .arg(env!("CARGO_BIN_EXE_lancer"))
            .args(["build", "quad.obj", "--threads", threads, "--out", "q.bvh"])
            .current_dir(s.dir())
            .output()
            .expect("prlimit (util-linux) runs lancer")
    };
    let many = run("1024");
    let stderr = String::from_utf8_lossy(&many.stderr);
    assert_eq!(many.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--threads 1024: cannot start that many threads"),
        "{stderr}"
    );
    assert!(!s.path("q.bvh").exists());
    let few = run("2");
    assert!(
        few.status.success(),
        "{}",
        String::from_utf8_lossy(&few.stderr)
    );
    let _ = quad;
}
