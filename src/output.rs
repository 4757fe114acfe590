//! Writing outputs safely: an output path is checked before any long work (its folder exists
//! and takes files, it is not a folder or a device, it is none of the inputs), and every
//! file is written to a temporary file in the same folder, flushed, then renamed over the
//! target, so a failed or interrupted write never leaves a truncated file or destroys the
//! old one.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `path` atomically: `write` fills a buffered temporary file next to it, which
/// replaces `path` only once fully written and flushed. Any error removes the temporary
/// file and leaves `path` as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temporary_path(path);
    let result = (|| {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// `.NAME.PID.tmp` in the same folder as `path` (a rename within one file system).
fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Checks an output path before work starts: refuses (exit code 2) a path that exists but is
/// not a regular file, one that is any of `inputs` (the same file, whatever the spelling), and
/// one whose folder is missing or does not take new files.
pub fn check_output(out: &Path, inputs: &[PathBuf]) -> Result<()> {
    let bad = |msg: String| Error::input(out, None, msg);
    if let Ok(meta) = std::fs::metadata(out) {
        if !meta.is_file() {
            return Err(bad(
                "exists and is not a regular file (a folder or a device): choose a file name"
                    .into(),
            ));
        }
        if let Some(input) = inputs.iter().find(|i| same_file(out, i)) {
            return Err(bad(format!(
                "is an input ({}): lancer never writes over its inputs; choose another name",
                input.display()
            )));
        }
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(bad(format!(
            "the folder {} does not exist: create it or choose another",
            dir.display()
        )));
    }
    let probe = temporary_path(out);
    File::create(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
        .map_err(|e| bad(format!("cannot write in {}: {e}", dir.display())))
}

/// Whether two paths name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
        false
    }
    #[cfg(not(unix))]
    {
        matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.bin");
        std::fs::write(&out, b"old").unwrap();
        let e = write_atomic(&out, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("disk full"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_bytes(&out, b"new").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
    }

    #[test]
    fn outputs_that_are_inputs_folders_or_devices_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("mesh.obj");
        std::fs::write(&input, b"v 0 0 0\n").unwrap();
        let spelled_otherwise = dir.path().join(".").join("mesh.obj");
        let refuse = |out: &Path| check_output(out, std::slice::from_ref(&input)).unwrap_err();
        assert!(refuse(&spelled_otherwise)
            .to_string()
            .contains("is an input"));
        assert!(refuse(dir.path())
            .to_string()
            .contains("not a regular file"));
        assert!(refuse(Path::new("/dev/full"))
            .to_string()
            .contains("not a regular file"));
        let missing = dir.path().join("nodir").join("x.png");
        assert!(refuse(&missing).to_string().contains("does not exist"));
        assert_eq!(refuse(&input).exit_code(), 2);
        check_output(&dir.path().join("new.png"), &[input]).unwrap();
    }
}
