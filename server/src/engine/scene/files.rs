//! Reading the files a scene names (the scene file itself and its mesh): only regular
//! files, never more than a stated size, and for a served scene only files inside the
//! server's scene directory.
//!
//! A path is checked before it is opened and the opened file again (the path may have
//! changed in between):
//! 1. confined reads canonicalise the path (following every symlink) and require it to
//!    start with the canonical scene directory, so `../`, absolute paths and symlinks
//!    cannot reach other files of the machine;
//! 2. the path's metadata must say "regular file": a FIFO would block the reader for
//!    ever, `/dev/zero` or `/dev/urandom` would never end, a directory cannot be read;
//! 3. the file is opened with `O_NONBLOCK` (which regular files ignore), so a FIFO
//!    swapped in after the check cannot block the open, and its metadata is checked
//!    again on the open descriptor;
//! 4. at most `limit + 1` bytes are read, so a file that grows past the limit after the
//!    check is refused rather than read whole.

use std::fmt;
use std::fs::{File, Metadata};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest mesh file read, bytes: 32 MiB, twice liver-300k's 16.7 MB `.msh` (60k
/// vertices, 309k tetrahedra). A mesh that size takes about half a second to build
/// and a few hundred MB of memory; the per-tick work bound
/// ([`super::limits::MAX_TICK_WORK`]) is what keeps its ticks finite.
pub const MAX_MESH_BYTES: u64 = 32 << 20;

/// Largest scene file read, bytes: 1 MiB. A scene is a page of TOML (the default is
/// 2 KB); even a thousand fixed node indices are a few KB.
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// Why a scene's file was not read.
#[derive(Debug)]
pub enum FileError {
    /// The path leads outside the scene directory (after following symlinks).
    Outside { root: PathBuf },
    /// Not a regular file: a FIFO, a device, a socket or a directory.
    NotRegular { kind: &'static str },
    /// Larger than the limit.
    TooLarge { bytes: u64, limit: u64 },
    /// The file could not be found, opened or read.
    Io(std::io::Error),
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FileError::Outside { root } => write!(
                f,
                "is outside the scene directory {} (a served scene reads files from \
                 its directory only)",
                root.display()
            ),
            FileError::NotRegular { kind } => {
                write!(f, "is a {kind}, not a regular file")
            }
            FileError::TooLarge { bytes, limit } => write!(
                f,
                "is {bytes} bytes or more, over the limit of {limit} bytes ({} MiB)",
                limit >> 20
            ),
            FileError::Io(e) => write!(f, "cannot read: {e}"),
        }
    }
}

impl std::error::Error for FileError {}

impl From<std::io::Error> for FileError {
    fn from(e: std::io::Error) -> Self {
        FileError::Io(e)
    }
}

/// Reads the regular file at `path`, at most `limit` bytes, and, with `root`, only if it
/// lies inside that directory (see the module notes for the order of the checks).
pub fn read_bounded(path: &Path, root: Option<&Path>, limit: u64) -> Result<Vec<u8>, FileError> {
    let path = match root {
        Some(root) => {
            let root = std::fs::canonicalize(root)?;
            let resolved = std::fs::canonicalize(path)?;
            if !resolved.starts_with(&root) {
                return Err(FileError::Outside { root });
            }
            resolved
        }
        None => path.to_path_buf(),
    };
    check_regular(&std::fs::metadata(&path)?, limit)?;
    let file = open_nonblocking(&path, true)?;
    check_regular(&file.metadata()?, limit)?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(FileError::TooLarge {
            bytes: bytes.len() as u64,
            limit,
        });
    }
    Ok(bytes)
}

fn check_regular(meta: &Metadata, limit: u64) -> Result<(), FileError> {
    if !meta.is_file() {
        return Err(FileError::NotRegular {
            kind: file_kind(meta),
        });
    }
    if meta.len() > limit {
        return Err(FileError::TooLarge {
            bytes: meta.len(),
            limit,
        });
    }
    Ok(())
}

/// What kind of file `meta` describes, for an error that refuses it: "directory",
/// "symbolic link" (only from `symlink_metadata`), "FIFO (named pipe)", … A regular
/// file gets "special file" too, so call it only for what is not one.
pub fn file_kind(meta: &Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_symlink() {
        return "symbolic link";
    }
    if t.is_dir() {
        return "directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "character device";
        }
        if t.is_block_device() {
            return "block device";
        }
        if t.is_socket() {
            return "socket";
        }
    }
    "special file"
}

/// Whether `a` and `b` are one existing file: on Unix the same device and inode, so
/// a symbolic or a hard link to it counts too (a canonical path would miss the hard
/// link); elsewhere the same canonical path.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        x.dev() == y.dev() && x.ino() == y.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (x, y);
        std::fs::canonicalize(a).ok() == std::fs::canonicalize(b).ok()
    }
}

/// Opens `path` for reading without blocking on a FIFO (`O_NONBLOCK`), so that a
/// pipe put in a file's place cannot hold the open; with `follow_links` false a
/// final symbolic link is refused (`O_NOFOLLOW`: the open fails with `ELOOP`).
/// Shared by scene and mesh files and by recordings.
#[cfg(unix)]
pub fn open_nonblocking(path: &Path, follow_links: bool) -> std::io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut flags = libc::O_NONBLOCK;
    if !follow_links {
        flags |= libc::O_NOFOLLOW;
    }
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(flags)
        .open(path)
}

#[cfg(not(unix))]
pub fn open_nonblocking(path: &Path, _follow_links: bool) -> std::io::Result<File> {
    File::open(path)
}
