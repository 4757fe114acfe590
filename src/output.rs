//! Writing outputs safely: an output path is checked before any long work (it names a file,
//! its folder exists and takes files, it is not a folder or a device, it is none of the
//! inputs, and it can be replaced), and every file is written to a temporary file in the
//! same folder, flushed, then renamed over the target, so a failed or interrupted write never
//! leaves a truncated file or destroys the old one. An output that is a symbolic link is
//! written through it (the link stays). Temporary files being written are recorded, so that
//! a program stopped by a signal can remove them ([`remove_temporaries`]).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::{Error, Result};

/// Temporary files being written now, by any thread.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Longest file name most file systems take, in bytes.
const NAME_MAX: usize = 255;

/// Writes `path` atomically: `write` fills a buffered temporary file next to it, which
/// replaces `path` only once fully written and flushed. Any error removes the temporary
/// file and leaves `path` as it was. Where `path` is a symbolic link, the file it leads to
/// is written (in that file's folder) and the link kept.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let target = through_links(path);
    let tmp = temporary_path(&target);
    record(&tmp, true);
    let result = (|| {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, &target)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    record(&tmp, false);
    result.map_err(|e| Error::io(path, e))
}

/// Adds `tmp` to the temporary files being written, or takes it off.
fn record(tmp: &Path, writing: bool) {
    let mut list = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    match writing {
        true => list.push(tmp.to_path_buf()),
        false => list.retain(|p| p != tmp),
    }
}

/// Removes every temporary file being written (for a program stopped by a signal, just
/// before it exits: its outputs stay as they were). Returns how many it removed.
pub fn remove_temporaries() -> usize {
    let list = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    list.iter()
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count()
}

/// The file a path leads to: `path` itself, or where its symbolic links lead (relative
/// links read from the link's folder), as long as that exists.
fn through_links(path: &Path) -> PathBuf {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    }
}

/// `.NAME.PID.tmp` in the same folder as `path` (a rename within one file system); a name
/// too long for that keeps its first bytes and a hash of the whole.
fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let pid = std::process::id();
    let mut tmp = format!(".{name}.{pid}.tmp");
    if tmp.len() > NAME_MAX {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        name.hash(&mut h);
        let mut keep = NAME_MAX - format!("..{:016x}.{pid}.tmp", h.finish()).len();
        while !name.is_char_boundary(keep) {
            keep -= 1;
        }
        tmp = format!(".{}.{:016x}.{pid}.tmp", &name[..keep], h.finish());
    }
    path.with_file_name(tmp)
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Checks an output path before work starts: refuses (exit code 2) a path that does not name
/// a file (it ends in `/`), a link to nothing, one that exists but is not a regular file, one that is any of
/// `inputs` (the same file, whatever the spelling), one whose folder is missing or does not
/// take new files, and one this user may not replace (another user's file in a folder that
/// keeps others' files: /tmp's sticky bit).
pub fn check_output(out: &Path, inputs: &[PathBuf]) -> Result<()> {
    let bad = |msg: String| Error::input(out, None, msg);
    if out.as_os_str().to_string_lossy().ends_with('/') || out.file_name().is_none() {
        return Err(bad("names a folder, not a file: give a file name".into()));
    }
    let existing = std::fs::metadata(out).ok();
    let link = std::fs::symlink_metadata(out).is_ok_and(|m| m.file_type().is_symlink());
    if link && existing.is_none() {
        return Err(bad(
            "is a symbolic link to nothing: make the file it names, or choose another name".into(),
        ));
    }
    if let Some(meta) = &existing {
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
    let target = through_links(out);
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(bad(format!(
            "the folder {} does not exist: create it or choose another",
            dir.display()
        )));
    }
    let probe = temporary_path(&target);
    let made = File::create(&probe).and_then(|f| f.metadata());
    let _ = std::fs::remove_file(&probe);
    let made = made.map_err(|e| bad(format!("cannot write in {}: {e}", dir.display())))?;
    if let Some(meta) = existing {
        if !may_replace(&meta, &made, dir) {
            return Err(bad(format!(
                "belongs to another user, in a folder ({}) where only a file's owner may                  replace it: choose another name",
                dir.display()
            )));
        }
    }
    Ok(())
}

/// Whether a file (`file`'s metadata) in `dir` may be renamed over by this user, whose new
/// files look like `mine`.
fn may_replace(file: &std::fs::Metadata, mine: &std::fs::Metadata, dir: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let Ok(folder) = std::fs::metadata(dir) else {
            return true;
        };
        replace_allowed(folder.mode(), folder.uid(), file.uid(), mine.uid())
    }
    #[cfg(not(unix))]
    {
        let _ = (file, mine, dir);
        true
    }
}

/// The rule for renaming over a file: allowed anywhere but in a sticky folder (mode bit
/// 0o1000), where only the file's owner, the folder's owner or root may.
fn replace_allowed(folder_mode: u32, folder_owner: u32, file_owner: u32, me: u32) -> bool {
    const STICKY: u32 = 0o1000;
    folder_mode & STICKY == 0 || me == 0 || file_owner == me || folder_owner == me
}

/// Whether two output paths would write the same file, whether or not it exists yet: the
/// same folder (whatever the spelling, links followed) and the same name.
pub fn same_output(a: &Path, b: &Path) -> bool {
    let place = |p: &Path| {
        let p = through_links(p);
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        (
            std::fs::canonicalize(&dir).unwrap_or(dir),
            p.file_name().map(|n| n.to_owned()),
        )
    };
    place(a) == place(b)
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

    /// A name ending in `/` (a file's or a missing folder's) is refused before any work;
    /// a link to nothing too.
    #[test]
    fn outputs_must_name_a_file() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["x.png/", "newdir/"] {
            let out = PathBuf::from(format!("{}/{name}", dir.path().display()));
            let e = check_output(&out, &[]).unwrap_err();
            assert!(e.to_string().contains("names a folder, not a file"), "{e}");
            assert_eq!(e.exit_code(), 2);
        }
        let dangling = dir.path().join("dangling.png");
        std::os::unix::fs::symlink(dir.path().join("nothing"), &dangling).unwrap();
        let e = check_output(&dangling, &[]).unwrap_err().to_string();
        assert!(e.contains("symbolic link to nothing"), "{e}");
    }

    /// An output that is a link is written through it: the link stays, the file it leads
    /// to takes the bytes.
    #[test]
    fn a_link_is_written_through() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("keep")).unwrap();
        let real = dir.path().join("keep/real.bin");
        std::fs::write(&real, b"old").unwrap();
        let link = dir.path().join("link.bin");
        std::os::unix::fs::symlink("keep/real.bin", &link).unwrap();
        check_output(&link, &[]).unwrap();
        write_bytes(&link, b"new").unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
        assert_eq!(
            std::fs::read_dir(dir.path().join("keep")).unwrap().count(),
            1
        );
    }

    /// A name as long as a file system takes still has a temporary name it takes, distinct
    /// from another long name's with the same start.
    #[test]
    fn long_names_have_temporary_names() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join(format!("{}a.png", "é".repeat(120)));
        let b = dir.path().join(format!("{}b.png", "é".repeat(120)));
        let (ta, tb) = (temporary_path(&a), temporary_path(&b));
        assert!(
            ta.file_name().unwrap().len() <= NAME_MAX,
            "{}",
            ta.display()
        );
        assert_ne!(ta, tb);
        check_output(&a, &[]).unwrap();
        write_bytes(&a, b"x").unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"x");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// Outputs spelled differently but landing on one file are the same output; a file
    /// and another name in one folder are not.
    #[test]
    fn same_outputs_whatever_the_spelling() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let plain = dir.path().join("k.json");
        let dotted = dir.path().join("sub/../k.json");
        assert!(same_output(&plain, &dotted));
        assert!(same_output(&plain, &dir.path().join("./k.json")));
        assert!(!same_output(&plain, &dir.path().join("k.png")));
    }

    /// In a sticky folder only the file's owner, the folder's or root replaces a file.
    #[test]
    fn sticky_folders_keep_others_files() {
        let (tmp, plain) = (0o41777, 0o40777);
        assert!(!replace_allowed(tmp, 0, 1000, 1001));
        assert!(replace_allowed(tmp, 0, 1001, 1001));
        assert!(replace_allowed(tmp, 1001, 1000, 1001));
        assert!(replace_allowed(tmp, 0, 1000, 0));
        assert!(replace_allowed(plain, 0, 1000, 1001));
    }

    /// Temporaries being written are recorded until written, and removed on request.
    #[test]
    fn temporaries_are_recorded_while_written() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("slow.bin");
        let tmp = temporary_path(&out);
        write_atomic(&out, |w| {
            w.write_all(b"part")?;
            w.flush()?;
            assert!(TEMPORARIES.lock().unwrap().contains(&tmp));
            assert!(tmp.exists());
            Ok(())
        })
        .unwrap();
        assert!(!TEMPORARIES.lock().unwrap().contains(&tmp));
        record(&tmp, true);
        std::fs::write(&tmp, b"left").unwrap();
        assert!(remove_temporaries() >= 1);
        assert!(!tmp.exists());
        record(&tmp, false);
    }
}
