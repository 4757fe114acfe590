//! Errors meant for people: each says which input is wrong, where, and what to do.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad user input (file content or arguments). The CLI exits with code 2.
    #[error("{}{}: {msg}", file.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Input {
        file: PathBuf,
        line: Option<usize>,
        msg: String,
    },
    #[error("{}: {source}", file.display())]
    Io {
        file: PathBuf,
        source: std::io::Error,
    },
    /// No usable GPU, or a GPU limit the scene exceeds.
    #[error("{0}")]
    Gpu(String),
}

impl Error {
    pub fn input(file: &Path, line: Option<usize>, msg: impl Into<String>) -> Error {
        Error::Input {
            file: file.to_path_buf(),
            line,
            msg: msg.into(),
        }
    }

    pub fn io(file: &Path, source: std::io::Error) -> Error {
        Error::Io {
            file: file.to_path_buf(),
            source,
        }
    }

    /// Exit code for the CLI: 2 for bad input, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } => 2,
            Error::Io { .. } | Error::Gpu(_) => 1,
        }
    }
}

pub type Result<T> = std::result::Result<T, Error>;
