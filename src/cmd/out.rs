//! Where a command's output goes: data (JSON, ray and hit files) to a file or to stdout
//! (`-`), and the human summary to stdout, or to stderr when stdout carries data, so that
//! `lancer … --json | jq` and `lancer rays … -o - | lancer trace … --rays -` see data only.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use lancer::{Error, Result};
use serde::Serialize;

/// `-q`: errors only, so no human-readable lines (data still goes out).
static QUIET: AtomicBool = AtomicBool::new(false);

/// Sets `-q` for the whole run (before the command runs).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// The human-readable lines of one command: on stdout, or on stderr when stdout carries
/// data; none under `-q`.
#[derive(Clone, Copy, Debug)]
pub struct Say {
    stderr: bool,
}

impl Say {
    /// Lines on stderr when `stdout_is_data`, else on stdout.
    pub fn new(stdout_is_data: bool) -> Say {
        Say {
            stderr: stdout_is_data,
        }
    }

    /// Prints one line (nothing under `-q`). A closed stdout ends the run quietly, as a
    /// pipe into `head` expects; a full one ends it with exit code 1.
    pub fn line(&self, args: std::fmt::Arguments) {
        if QUIET.load(Ordering::Relaxed) {
            return;
        }
        if self.stderr {
            eprintln!("{args}");
            return;
        }
        let mut stdout = std::io::stdout().lock();
        if let Err(e) = writeln!(stdout, "{args}").and_then(|_| stdout.flush()) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            eprintln!("error: writing to stdout: {e}");
            std::process::exit(1);
        }
    }
}

/// `say!(say, "format", args…)`: one human-readable line where `say` sends them.
macro_rules! say {
    ($say:expr) => {
        $say.line(format_args!(""))
    };
    ($say:expr, $($arg:tt)*) => {
        $say.line(format_args!($($arg)*))
    };
}
pub(crate) use say;

/// Whether a path is `-` (stdin or stdout).
pub fn is_std(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Checks an output path before work starts (`-`, stdout, needs no check); an input `-`
/// is whatever stdin reads (a file redirected to it is an input like any other).
pub fn check_output(out: &Path, inputs: &[PathBuf]) -> Result<()> {
    if is_std(out) {
        return Ok(());
    }
    let inputs: Vec<PathBuf> = (inputs.iter())
        .map(|p| match is_std(p) {
            true => PathBuf::from("/dev/stdin"),
            false => p.clone(),
        })
        .collect();
    lancer::output::check_output(out, &inputs)
}

/// The bytes of a file, or of stdin for `-` (both bounded: [`lancer::input`]).
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    match is_std(path) {
        true => lancer::input::read_stream(Path::new("<stdin>"), std::io::stdin().lock()),
        false => lancer::input::read(path),
    }
}

/// The rays of a ray file, or of stdin for `-` (named `<stdin>` in errors and warnings).
pub fn read_rays(path: &Path) -> Result<Vec<lancer::geometry::Ray>> {
    let name = if is_std(path) {
        Path::new("<stdin>")
    } else {
        path
    };
    lancer::trace::files::decode_rays(name, &read_input(path)?)
}

/// Writes `bytes` to a file atomically, or to stdout for `-`.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    if !is_std(path) {
        return lancer::output::write_bytes(path, bytes);
    }
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(bytes)
        .and_then(|_| stdout.flush())
        .map_err(|e| Error::io(Path::new("<stdout>"), e))
}

/// Where `--json` sends its one object: stdout (`--json` alone, or `--json -`) or a file.
#[derive(Clone, Debug)]
pub enum JsonTo {
    /// One line on stdout; the human summary goes to stderr.
    Stdout,
    /// A file (indented), written atomically; the summary stays on stdout.
    File(PathBuf),
}

/// `--json [FILE.json]`: a file name must end in .json, so that a mesh written after
/// `--json` is refused rather than overwritten.
pub fn json_to(s: &str) -> std::result::Result<JsonTo, String> {
    if s == "-" {
        return Ok(JsonTo::Stdout);
    }
    let path = PathBuf::from(s);
    match path.extension() {
        Some(e) if e.eq_ignore_ascii_case("json") => Ok(JsonTo::File(path)),
        _ => Err(format!(
            "{s} is not a .json file name: give FILE.json, or - or nothing for stdout (put the \
             mesh before --json)"
        )),
    }
}

impl JsonTo {
    /// Whether stdout carries the JSON.
    pub fn is_stdout(&self) -> bool {
        matches!(self, JsonTo::Stdout)
    }

    /// Checks the file before work starts.
    pub fn check(&self, inputs: &[PathBuf]) -> Result<()> {
        match self {
            JsonTo::Stdout => Ok(()),
            JsonTo::File(path) => lancer::output::check_output(path, inputs),
        }
    }

    /// Writes the object; says where for a file.
    pub fn write(&self, value: &impl Serialize, say: Say) -> Result<()> {
        match self {
            JsonTo::Stdout => print_json(value),
            JsonTo::File(path) => {
                let text = serde_json::to_string_pretty(value)
                    .map_err(|e| Error::io(path, std::io::Error::other(e)))?;
                lancer::output::write_bytes(path, text.as_bytes())?;
                say!(say, "JSON -> {}", path.display());
                Ok(())
            }
        }
    }
}

/// One JSON object on one line of stdout.
pub fn print_json(value: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string(value)
        .map_err(|e| Error::io(Path::new("<stdout>"), std::io::Error::other(e)))?;
    write_output(Path::new("-"), format!("{text}\n").as_bytes())
}

/// A progress bar of `len` steps on stderr; hidden under `-q` (and by indicatif where
/// stderr is not a terminal).
pub fn progress_bar(len: u64) -> indicatif::ProgressBar {
    if QUIET.load(Ordering::Relaxed) {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(len)
    }
}
