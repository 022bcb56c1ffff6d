//! What a recordings directory holds, as `laparo recordings list` prints it and the
//! `ListRecordings` call answers it: each `.mcap` file with its session, scene,
//! start, duration and size, or why it cannot be read.
//!
//! A file without its summary and footer is read as far as it goes
//! ([`Recording::open_unfinished`]): it is [`FileState::InProgress`] when the
//! caller knows a session is still writing it (the server does), otherwise
//! [`FileState::Unfinished`] — a server stopped mid-session, or a session the
//! caller does not know of.

use std::path::Path;

use super::reader::{ReadError, Recording};

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
}

/// Opens the recording at `path` as far as it goes and says how its file ends;
/// `is_recording` tells whether a session is still writing a file. Errors name the
/// file by its name alone: they go to clients, which know no directory.
///
/// A file read unfinished and not being written is read once more: its session may
/// have finished it between the read and the question.
pub fn open(
    path: &Path,
    is_recording: impl Fn(&Path) -> bool,
) -> Result<(Recording, FileState), ReadError> {
    let read = || {
        let file = path
            .file_name()
            .unwrap_or(path.as_os_str())
            .to_string_lossy()
            .into_owned();
        Recording::open_unfinished_as(path, file)
    };
    let recording = read()?;
    if recording.is_complete() {
        return Ok((recording, FileState::Complete));
    }
    if is_recording(path) {
        return Ok((recording, FileState::InProgress));
    }
    let again = read()?;
    let state = if again.is_complete() {
        FileState::Complete
    } else {
        FileState::Unfinished
    };
    Ok((again, state))
}

/// What the recording at `path` holds (see [`open`]).
pub fn inspect(path: &Path, is_recording: impl Fn(&Path) -> bool) -> Result<Listing, ReadError> {
    let (recording, state) = open(path, is_recording)?;
    let meta = recording.meta();
    Ok(Listing {
        session_id: meta.session_id.clone(),
        scene: meta.scene.clone(),
        start_unix_ns: meta.start_unix_ns,
        duration_s: recording.duration_s()?,
        state,
    })
}

/// Every file of `dir` whose name ends in `.mcap` (and is UTF-8), oldest recording
/// first (by start time, then name), the files that cannot be read last (by name).
/// Files are read one at a time; each is held in memory only while it is listed.
pub fn list(dir: &Path, is_recording: impl Fn(&Path) -> bool) -> std::io::Result<Vec<Listed>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let Ok(file) = entry.file_name().into_string() else {
            continue;
        };
        if !file.ends_with(".mcap") {
            continue;
        }
        let path = dir.join(&file);
        // Through symbolic links, as reading does; directories are not recordings.
        let Ok(metadata) = std::fs::metadata(&path) else {
            continue;
        };
        if !metadata.is_file() {
            continue;
        }
        let entry = inspect(&path, &is_recording);
        let size_bytes = std::fs::metadata(&path).map_or(metadata.len(), |m| m.len());
        out.push(Listed {
            file,
            size_bytes,
            entry,
        });
    }
    out.sort_by(|a, b| {
        let key = |l: &Listed| l.entry.as_ref().map_or(u64::MAX, |e| e.start_unix_ns);
        key(a).cmp(&key(b)).then_with(|| a.file.cmp(&b.file))
    });
    Ok(out)
}
