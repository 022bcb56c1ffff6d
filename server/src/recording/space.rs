//! Room for a new recording: a session is recorded only while the recordings
//! directory's file system keeps [`MIN_FREE_BYTES`] free.
//!
//! A recorder that runs out of space says so in its session's events and the
//! session goes on unrecorded (see [`recorder`](super::recorder)); but a file
//! system already full would make every new recorded session such a session, and
//! each new file, a few kilobytes of scene and header, would take the last of it
//! from the recordings still being written. So a recorded session is refused
//! before it starts, with a status that names the limit.

use std::io;
use std::path::Path;

/// The free space a new recording needs on the recordings directory's file
/// system, bytes: 64 MiB, about ten minutes of the default scene (its recording
/// grows about 6 MB a minute with nobody in it: 2.0 MB for 20 s, measured), so
/// that a session is not refused on a file system with room for a lesson's
/// worth, and is refused on one that has all but run out.
pub const MIN_FREE_BYTES: u64 = 64 << 20;

/// Whether `dir` can take a new recording's file: made when missing (so that one
/// removed while the server runs comes back), then a directory. `Err` says what it
/// is instead, without the path (clients are told, and know no server paths): a
/// `--recordings` naming a file, a dangling link or a loop of links would
/// otherwise let a session answer that it records, and its recorder fail a tick
/// later.
pub fn usable_dir(dir: &Path) -> Result<(), String> {
    let _ = std::fs::create_dir_all(dir);
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err("is not a directory".into()),
        Err(e) => Err(format!("cannot be made or reached: {e}")),
    }
}

/// Bytes an unprivileged process may still write on the file system of `dir`
/// (`statvfs`: available blocks times the fragment size).
pub fn free_bytes(dir: &Path) -> io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let path = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "a path with a NUL byte"))?;
    let mut stat = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: `path` is a NUL-terminated string and `stat` room for one statvfs,
    // which the call fills when it returns 0.
    if unsafe { libc::statvfs(path.as_ptr(), stat.as_mut_ptr()) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: filled by the successful call.
    let stat = unsafe { stat.assume_init() };
    Ok(stat.f_bavail.saturating_mul(stat.f_frsize))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_directory_has_free_bytes_and_a_missing_one_is_an_error() {
        // What the bytes are is the file system's to say (and other processes move
        // them); that they come, and that a bad path is an error, not 0, is ours.
        let free = free_bytes(&std::env::temp_dir()).unwrap();
        assert!(free > 0);
        let missing = free_bytes(Path::new("/no/such/laparo/dir")).unwrap_err();
        assert_eq!(missing.kind(), io::ErrorKind::NotFound);
        let nul = free_bytes(Path::new("a\0b")).unwrap_err();
        assert_eq!(nul.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn a_directory_is_made_when_missing_and_a_file_or_a_loop_is_not_one() {
        let base = tempfile::tempdir().unwrap();
        let made = base.path().join("a/b");
        assert_eq!(usable_dir(&made), Ok(()));
        assert!(made.is_dir());
        let file = base.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        assert_eq!(usable_dir(&file), Err("is not a directory".into()));
        let looped = base.path().join("loop");
        std::os::unix::fs::symlink(&looped, &looped).unwrap();
        let e = usable_dir(&looped).unwrap_err();
        assert!(e.starts_with("cannot be made or reached: "), "{e}");
    }
}
