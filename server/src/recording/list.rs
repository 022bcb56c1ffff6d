//! What a recordings directory holds, as `laparo recordings list` prints it and the
//! `ListRecordings` call answers it: each `.mcap` file with its session, scene,
//! start, duration and size, or why it cannot be read.
//!
//! Only regular files directly in the directory are listed: a symbolic link (to a
//! file anywhere, or to a FIFO or a device), a directory or a socket is not, even
//! with a `.mcap` name, and files are opened without following a link
//! ([`Recording::open_served`]), so nothing outside the directory is ever read.
//!
//! A listing reads what it needs of each file and no more (see [`Recording`]): for
//! a finished file its footer, summary, metadata record and newest chunk holding a
//! frame; for an unfinished one the prefixes of its records, its first chunk and
//! its newest chunks ([`super::reader::MAX_WALKED_RECORDS`],
//! [`super::reader::MAX_DURATION_CHUNKS`]). A [`Lister`] keeps what it found by
//! file name, size, modification time and inode, so a file that has not changed
//! is not read again, and lists one directory at a time, so concurrent listings
//! hold at most one file's reading in memory and the ones that waited find the
//! answers cached.
//!
//! A file without its summary and footer is read as far as it goes: it is
//! [`FileState::InProgress`] when the caller knows a session is still writing it
//! (the server does), otherwise [`FileState::Unfinished`] — a server stopped
//! mid-session, or a session the caller does not know of.

use std::collections::HashMap;
use std::os::unix::fs::MetadataExt;
use std::path::Path;
use std::sync::Mutex;
use std::time::SystemTime;

use super::reader::{ReadError, Recording};

/// Most files a listing reads and answers: the most recently modified. A listing
/// reads a few kilobytes to a few chunks of each file it has not seen (see the
/// module documentation) and answers ~200 bytes a file, so 2,048 files bound a
/// first listing's reading to seconds and its answer to well under the largest
/// message the server sends; older files stay replayable by name.
pub const MAX_LISTED_FILES: usize = 2048;

/// How a recording's file ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileState {
    /// With its summary and footer: the session ended and the file is finished.
    Complete,
    /// A session is still being recorded to it; what is listed is what its complete
    /// chunks hold so far.
    InProgress,
    /// No summary and footer, and no session known to be writing it: cut short by a
    /// stopped server (`laparo recordings recover` completes it), or still being
    /// written by a server the lister does not ask.
    Unfinished,
}

/// What a recording file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Listing {
    pub session_id: String,
    /// The recorded scene's name.
    pub scene: String,
    /// When the session started, ns since the Unix epoch.
    pub start_unix_ns: u64,
    /// Simulated time of the last tick recorded, s.
    pub duration_s: f64,
    pub state: FileState,
}

/// One `.mcap` file of a directory.
#[derive(Debug)]
pub struct Listed {
    /// The file's name within the directory.
    pub file: String,
    /// Its size when listed, bytes.
    pub size_bytes: u64,
    /// What it records, or why it cannot be read.
    pub entry: Result<Listing, ReadError>,
    /// Bytes this listing read of the file (0 when its answer was cached).
    pub bytes_read: u64,
    /// Whether this listing read the file (new or changed since the last), rather
    /// than answering from the cache: what a caller says of a file it cannot list,
    /// it says once a version.
    pub fresh: bool,
}

/// What a file was found to hold; its state but for whether a session writes it.
#[derive(Clone, Debug)]
struct Found {
    session_id: String,
    scene: String,
    start_unix_ns: u64,
    duration_s: f64,
    complete: bool,
}

/// What identifies a version of a file: size, modification time, inode and device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Version {
    size: u64,
    modified: Option<SystemTime>,
    inode: (u64, u64),
}

impl Version {
    fn of(m: &std::fs::Metadata) -> Self {
        Version {
            size: m.len(),
            modified: m.modified().ok(),
            inode: (m.dev(), m.ino()),
        }
    }
}

/// A file's last version read, and what it held.
type Cached = (Version, Result<Found, ReadError>);

/// Lists directories, caching what it reads (see the module documentation).
#[derive(Debug, Default)]
pub struct Lister {
    /// By file name; also the lock that lets one listing read at a time.
    cache: Mutex<HashMap<String, Cached>>,
}

/// Reads the recording at `path`, named `file` (its name alone: errors go to
/// clients, which know no directory).
fn find(path: &Path, file: &str) -> (Result<Found, ReadError>, u64) {
    match Recording::open_served(path, file.to_string()) {
        Err(e) => (Err(e), 0),
        Ok(recording) => {
            let meta = recording.meta();
            let found = recording.duration_s().map(|duration_s| Found {
                session_id: meta.session_id.clone(),
                scene: meta.scene.clone(),
                start_unix_ns: meta.start_unix_ns,
                duration_s,
                complete: recording.is_complete(),
            });
            (found, recording.bytes_read())
        }
    }
}

/// Opens the recording at `path` as far as it goes, without following a link, and
/// says how its file ends; `is_recording` tells whether a session is still writing
/// a file. Errors name the file by its name alone.
///
/// A file read unfinished and not being written is read once more: its session may
/// have finished it between the read and the question.
pub fn open(
    path: &Path,
    is_recording: impl Fn(&Path) -> bool,
) -> Result<(Recording, FileState), ReadError> {
    let file = path
        .file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy()
        .into_owned();
    let recording = Recording::open_served(path, file.clone())?;
    if recording.is_complete() {
        return Ok((recording, FileState::Complete));
    }
    if is_recording(path) {
        return Ok((recording, FileState::InProgress));
    }
    let again = Recording::open_served(path, file)?;
    let state = if again.is_complete() {
        FileState::Complete
    } else {
        FileState::Unfinished
    };
    Ok((again, state))
}

impl Lister {
    pub fn new() -> Self {
        Self::default()
    }

    /// Every regular file of `dir` whose name ends in `.mcap` (one whose name is not
    /// UTF-8 as [`ReadError::NameNotText`]), at
    /// most the [`MAX_LISTED_FILES`] most recently modified, oldest recording first
    /// (by start time, then name), the files that cannot be read last (by name).
    pub fn list(
        &self,
        dir: &Path,
        is_recording: impl Fn(&Path) -> bool,
    ) -> std::io::Result<Vec<Listed>> {
        let (listed, left_out) = self.list_at_most(dir, MAX_LISTED_FILES, is_recording)?;
        if left_out > 0 {
            tracing::warn!(
                dir = %dir.display(),
                "{left_out} older recordings not listed (at most {MAX_LISTED_FILES} are)"
            );
        }
        Ok(listed)
    }

    /// [`Lister::list`] of at most the `max` most recently modified files, and how
    /// many files were left out.
    pub fn list_at_most(
        &self,
        dir: &Path,
        max: usize,
        is_recording: impl Fn(&Path) -> bool,
    ) -> std::io::Result<(Vec<Listed>, usize)> {
        // Names and metadata first (cheap): only the newest are read.
        let mut candidates = Vec::new();
        for entry in std::fs::read_dir(dir)? {
            let entry = entry?;
            let name = entry.file_name();
            // A name that is not text is listed, as unreadable, under a lossy copy
            // of it: left out, a user would not know why their file is missing.
            let text = name.to_str().is_some();
            let file = name.to_string_lossy().into_owned();
            if !file.ends_with(".mcap") {
                continue;
            }
            let path = dir.join(&name);
            // Not through symbolic links: only what the directory itself holds.
            let Ok(metadata) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if !metadata.file_type().is_file() {
                continue;
            }
            candidates.push((file, path, metadata, text));
        }
        let left_out = candidates.len().saturating_sub(max);
        if left_out > 0 {
            candidates.sort_by(|a, b| {
                b.2.modified()
                    .ok()
                    .cmp(&a.2.modified().ok())
                    .then_with(|| a.0.cmp(&b.0))
            });
            candidates.truncate(max);
        }
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        let mut out = Vec::new();
        for (file, path, metadata, text) in candidates {
            let mut version = Version::of(&metadata);
            let (mut bytes_read, mut fresh) = (0, false);
            let mut read = |version: Version| match cache.get(&file) {
                Some((v, found)) if *v == version => found.clone(),
                _ => {
                    let (found, n) = match text {
                        true => find(&path, &file),
                        false => (Err(ReadError::NameNotText { file: file.clone() }), 0),
                    };
                    bytes_read += n;
                    fresh = true;
                    cache.insert(file.clone(), (version, found.clone()));
                    found
                }
            };
            let mut found = read(version);
            if matches!(&found, Ok(f) if !f.complete) && !is_recording(&path) {
                // Its session may have finished it since.
                if let Ok(m) = std::fs::symlink_metadata(&path) {
                    version = Version::of(&m);
                    found = read(version);
                }
            }
            let entry = found.map(|f| Listing {
                state: match (f.complete, is_recording(&path)) {
                    (true, _) => FileState::Complete,
                    (false, true) => FileState::InProgress,
                    (false, false) => FileState::Unfinished,
                },
                session_id: f.session_id,
                scene: f.scene,
                start_unix_ns: f.start_unix_ns,
                duration_s: f.duration_s,
            });
            out.push(Listed {
                file,
                size_bytes: version.size,
                entry,
                bytes_read,
                fresh,
            });
        }
        // Files gone from the directory are forgotten.
        cache.retain(|name, _| out.iter().any(|l| &l.file == name));
        drop(cache);
        out.sort_by(|a, b| {
            let key = |l: &Listed| l.entry.as_ref().map_or(u64::MAX, |e| e.start_unix_ns);
            key(a).cmp(&key(b)).then_with(|| a.file.cmp(&b.file))
        });
        Ok((out, left_out))
    }
}

/// [`Lister::list`] with nothing cached: every file is read.
pub fn list(dir: &Path, is_recording: impl Fn(&Path) -> bool) -> std::io::Result<Vec<Listed>> {
    Lister::new().list(dir, is_recording)
}
