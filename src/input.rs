//! Reading what users give. Every file lancer opens — named on the command line or inside
//! another file (an MTL library and its textures, a scene's meshes and textures, a glTF's
//! buffers and images, tiles, ray and hit files, BVH files) — is refused unless it is a
//! regular file: a symlink counts as what it points to, and a device (`/dev/zero`), a FIFO or
//! a directory is refused before it is opened, so nothing blocks. A file is read whole only
//! after its size passes the memory check, and never past that size.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};
use crate::limits::{available_memory, check_memory};
use crate::util::human_bytes;

/// Checks that `path` is a regular file (following symlinks); returns its size in bytes.
pub fn regular_file(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::read(path, e))?;
    if meta.is_dir() {
        return Err(Error::input(path, None, "a directory: give a file"));
    }
    if !meta.is_file() {
        return Err(Error::input(
            path,
            None,
            "not a regular file (a device, a FIFO or a socket): give a file",
        ));
    }
    Ok(meta.len())
}

/// Opens a regular file for reading ([`regular_file`] first, so a FIFO is never opened);
/// returns it with its size.
pub fn open(path: &Path) -> Result<(File, u64)> {
    let len = regular_file(path)?;
    let file = File::open(path).map_err(|e| Error::read(path, e))?;
    Ok((file, len))
}

/// The bytes of a regular file: its size checked against the memory left first, and read no
/// further than that size (a file that grows meanwhile is cut there).
pub fn read(path: &Path) -> Result<Vec<u8>> {
    let (file, len) = open(path)?;
    check_memory(
        &path.display().to_string(),
        len as u128,
        "free memory, or give a smaller file",
    )?;
    let mut bytes = Vec::with_capacity(len as usize);
    (file.take(len))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(path, e))?;
    Ok(bytes)
}

/// A whole UTF-8 text file ([`read`]), with [`Error::not_utf8`] naming the line of the
/// first bad byte.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read(path)?;
    String::from_utf8(bytes).map_err(|e| Error::not_utf8(path, e.as_bytes(), &e.utf8_error()))
}

/// All of a stream (stdin), named `name` in errors: refused once it passes half the memory
/// left (a stream has no size to check first).
pub fn read_stream(name: &Path, stream: impl Read) -> Result<Vec<u8>> {
    let limit = available_memory().map_or(u64::MAX / 2, |m| m / 2);
    let mut bytes = Vec::new();
    (stream.take(limit.saturating_add(1)))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(name, e))?;
    if bytes.len() as u64 > limit {
        return Err(Error::input(
            name,
            None,
            format!(
                "more than {} (half the memory left): give a file",
                human_bytes(limit)
            ),
        ));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_directories_are_refused_before_opening() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            // Opening a FIFO with no writer would block: refused without opening it.
            let e = read(&fifo).unwrap_err().to_string();
            assert!(e.contains("not a regular file"), "{e}");
        }
        let e = read(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(
            e.contains("/dev/zero") && e.contains("not a regular file"),
            "{e}"
        );
        let e = read(dir.path()).unwrap_err().to_string();
        assert!(e.contains("a directory"), "{e}");
        #[cfg(unix)]
        {
            let link = dir.path().join("zero.obj");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            let e = read_text(&link).unwrap_err().to_string();
            assert!(e.contains("not a regular file"), "{e}");
        }
        let file = dir.path().join("a.txt");
        std::fs::write(&file, "hello").unwrap();
        assert_eq!(read_text(&file).unwrap(), "hello");
    }

    #[test]
    fn a_stream_is_read_whole() {
        let bytes = read_stream(Path::new("<stdin>"), &b"abc"[..]).unwrap();
        assert_eq!(bytes, b"abc");
    }
}
