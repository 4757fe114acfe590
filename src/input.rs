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
/// further than that size (a file that grows meanwhile is cut there). A big file is read in
/// parts on all threads ([`PARALLEL_READ`]).
pub fn read(path: &Path) -> Result<Vec<u8>> {
    let (file, len) = open(path)?;
    check_memory(
        &path.display().to_string(),
        len as u128,
        "free memory, or give a smaller file",
    )?;
    #[cfg(unix)]
    if len >= PARALLEL_READ {
        // A file that shrank meanwhile is read again, as it is now.
        let parts = read_in_parts(&file, len as usize, READ_PART);
        if let Some(bytes) = parts.map_err(|e| Error::read(path, e))? {
            return Ok(bytes);
        }
    }
    let mut bytes = Vec::with_capacity(len as usize);
    (&file)
        .take(len)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(path, e))?;
    Ok(bytes)
}

/// Files of at least this many bytes are read in parts of 8 MiB on all threads: the copy
/// from the system's cache into fresh pages (and the faulting-in of those pages) is most of
/// a big file's read, and goes as fast on each thread (a 196 MB binary PLY on this project's
/// 2-core machine: 170 ms on one thread).
pub const PARALLEL_READ: u64 = 32 << 20;

/// Bytes of each part a big file is read in.
const READ_PART: usize = 8 << 20;

/// The first `len` bytes of `file`, read in parts of `part` bytes on all threads; None where
/// the file ends before them. The parts are read straight into the vector's unwritten
/// memory: zeroing it first (a reused allocation is cleared byte by byte) cost more than the
/// threads saved.
#[cfg(unix)]
fn read_in_parts(file: &File, len: usize, part: usize) -> std::io::Result<Option<Vec<u8>>> {
    use rayon::prelude::*;
    use std::os::fd::AsRawFd;
    let mut bytes: Vec<u8> = Vec::with_capacity(len);
    // Addresses as integers (shared across threads); each part's bytes are written by its
    // own read alone.
    let base = bytes.as_mut_ptr() as usize;
    let fd = file.as_raw_fd();
    let read_part = |k: usize| -> std::io::Result<bool> {
        let (mut at, end) = (k * part, ((k + 1) * part).min(len));
        while at < end {
            let offset = libc::off_t::try_from(at).map_err(std::io::Error::other)?;
            // SAFETY: at..end lies within the vector's capacity (len) and within this part,
            // which no other read writes; `pread` writes at most `end − at` bytes there and
            // reads none.
            let n = unsafe { libc::pread(fd, (base + at) as *mut libc::c_void, end - at, offset) };
            match n {
                0 => return Ok(false),
                n if n > 0 => at += n as usize,
                _ => match std::io::Error::last_os_error() {
                    e if e.kind() == std::io::ErrorKind::Interrupted => {}
                    e => return Err(e),
                },
            }
        }
        Ok(true)
    };
    let whole = (0..len.div_ceil(part))
        .into_par_iter()
        .map(read_part)
        .try_reduce(|| true, |a, b| Ok(a && b))?;
    if !whole {
        return Ok(None);
    }
    // SAFETY: every byte below len was written by the reads above (each part read whole).
    unsafe { bytes.set_len(len) };
    Ok(Some(bytes))
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

    /// A file read in parts is the file (parts of any size, the last one short); one that
    /// ends before the size asked for is none (`read` reads it again as it is); a file of
    /// [`PARALLEL_READ`] bytes and more goes that way.
    #[cfg(unix)]
    #[test]
    fn files_read_in_parts_are_the_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bytes");
        let bytes: Vec<u8> = (0..100_003u32).map(|i| ((i * 7919) >> 3) as u8).collect();
        std::fs::write(&p, &bytes).unwrap();
        let file = File::open(&p).unwrap();
        for part in [1000, 4096, 100_003, 1 << 20] {
            let got = read_in_parts(&file, bytes.len(), part).unwrap();
            assert!(got.as_deref() == Some(&bytes[..]), "parts of {part}");
        }
        let short = read_in_parts(&file, bytes.len() + 1, 4096).unwrap();
        assert!(short.is_none());
        let big: Vec<u8> = (0..PARALLEL_READ as usize + 12345)
            .map(|i| (i % 251) as u8)
            .collect();
        std::fs::write(&p, &big).unwrap();
        assert!(read(&p).unwrap() == big);
    }

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
