//! Errors meant for people: each says which input is wrong, where, and what to do.

use std::path::{Path, PathBuf};

/// What went wrong, for people: the CLI prints it on one line.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad user input (file content or arguments). The CLI exits with code 2.
    #[error("{}{}: {msg}", file.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Input {
        /// The file (or argument) at fault.
        file: PathBuf,
        /// Its line, when known.
        line: Option<usize>,
        /// What is wrong and what to do.
        msg: String,
    },
    /// A bad option or value not tied to a file. The CLI exits with code 2.
    #[error("{0}")]
    Usage(String),
    /// Reading or writing a file failed.
    #[error("{}: {source}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// Two compared results differ beyond the tolerance (`lancer compare`, `lancer check`).
    /// The CLI exits with code 1, as `cmp` and `diff` do.
    #[error("{0}")]
    Differ(String),
    /// No usable GPU, or a GPU limit the scene exceeds.
    #[error("{0}")]
    Gpu(String),
    /// The run was cancelled before anything could be saved.
    #[error("{0}")]
    Cancelled(String),
}

impl Error {
    /// Bad input in `file` (at `line`, when known).
    pub fn input(file: &Path, line: Option<usize>, msg: impl Into<String>) -> Error {
        Error::Input {
            file: file.to_path_buf(),
            line,
            msg: msg.into(),
        }
    }

    /// An input file that cannot be read (missing, a folder, no permission): exit code 2.
    pub fn read(file: &Path, source: std::io::Error) -> Error {
        Error::input(file, None, format!("cannot read: {source}"))
    }

    /// Text that must be UTF-8 but is not: names the line of the first bad byte.
    pub fn not_utf8(file: &Path, bytes: &[u8], e: &std::str::Utf8Error) -> Error {
        let at = e.valid_up_to();
        let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
        Error::input(file, Some(line), "not UTF-8 text: save the file as UTF-8")
    }

    /// An I/O error writing `file`: exit code 1.
    pub fn io(file: &Path, source: std::io::Error) -> Error {
        Error::Io {
            file: file.to_path_buf(),
            source,
        }
    }

    /// Exit code for the CLI: 2 for bad input, 130 for a cancelled run, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } | Error::Usage(_) => 2,
            Error::Cancelled(_) => 130,
            Error::Io { .. } | Error::Gpu(_) | Error::Differ(_) => 1,
        }
    }
}

/// lancer's result type.
pub type Result<T> = std::result::Result<T, Error>;
