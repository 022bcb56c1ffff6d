//! Reading a recording back: open it, check that it is a laparo recording of a
//! version this server knows, and decode its messages with the contract's types.
//!
//! A file that is not MCAP, is corrupt or was cut short gets a [`ReadError`] naming
//! the file and what is wrong; nothing here panics on bad input. A file cut short
//! (a killed server, or a session still running) has no summary: [`Recording::open`]
//! says so and [`super::recover`](fn@super::recover) rewrites it into a complete one;
//! [`Recording::open_unfinished`] reads what it holds so far. Bytes come through a
//! [`Source`], a record at a time, with the bounds stated by the constants here and
//! in [`super::records`].
//!
//! Here: the recording, its errors and its description; `open` finds the summary
//! or walks the records; `messages` reads the messages and the duration.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::io::{Read, Seek};
use std::path::Path;
use std::sync::Arc;

use foxglove::schemas::SceneUpdate;
use laparo_proto::v1;
use mcap::records::{MessageHeader, Record, op};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use mcap::{Channel, MAGIC, Schema, Summary};

use super::records::{MAX_RECORD_BYTES, chunk_records, frame_at, parse_one, read_record};
use super::source::{Follow, Source};

mod messages;
mod open;

use super::{
    FORMAT_VERSION, METADATA_NAME, TOPIC_EVENTS, TOPIC_FOXGLOVE_SCENE, TOPIC_INSTRUMENTS,
    TOPIC_POSES, TOPIC_SCENE, TOPIC_SURFACE,
};

/// Why a recording cannot be read. Cloned into a listing's cache, so an I/O error
/// is shared.
#[derive(Clone, Debug, thiserror::Error)]
pub enum ReadError {
    #[error("cannot read {file}: {source}")]
    Io {
        file: String,
        source: Arc<std::io::Error>,
    },
    #[error("{file} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap { file: String },
    #[error(
        "{file} ends without its summary: it was cut short (a stopped server) or is still \
         being written; recovering it rewrites it into a complete file"
    )]
    Truncated { file: String },
    #[error(
        "{file} is a corrupt MCAP file: {message}; `laparo recordings recover` writes \
         what is intact to another file (--out)"
    )]
    Corrupt { file: String, message: String },
    #[error(
        "{file} ends before the recording's description (its `laparo.scene` \
         metadata; its whole records stop at byte {end}): it was cut short as its \
         session started (a stopped server) or is damaged there, and holds nothing to \
         replay or recover"
    )]
    CutBeforeDescription { file: String, end: u64 },
    #[error(
        "{file}: its name is not UTF-8 text (shown with � for the bytes that are not \
         text), and recordings are named by text: rename it to list, replay or recover it"
    )]
    NameNotText { file: String },
    #[error("{file} is not a laparo recording: {message}")]
    NotARecording { file: String, message: String },
    #[error(
        "{file} is a laparo recording of format version `{found}`, which this build of \
         laparo does not read (it reads version {FORMAT_VERSION})"
    )]
    UnsupportedVersion { file: String, found: String },
    #[error("{file}: message {sequence} on {topic} does not decode: {message}")]
    Decode {
        file: String,
        topic: String,
        sequence: u32,
        message: String,
    },
}

/// What the `laparo.scene` metadata record says.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingMeta {
    pub format_version: String,
    pub session_id: String,
    pub scene: String,
    /// When the session started, ns since the Unix epoch.
    pub start_unix_ns: u64,
    /// The scene's TOML text.
    pub scene_toml: String,
    /// The folder the scene's relative paths resolve against, as the server saw it
    /// (absent for the embedded default scene).
    pub scene_dir: Option<std::path::PathBuf>,
}

/// A decoded message of a recording.
///
/// Unboxed like the contract's own oneofs: a message is decoded, looked at and
/// dropped, and boxing would cost an allocation for each.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Recorded {
    Scene(v1::SceneDescription),
    Pose(v1::DevicePose),
    Surface(v1::SurfaceFrame),
    Instrument(v1::InstrumentState),
    Event(v1::Event),
}

/// A decoded message with its times, ns since the Unix epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct Stamped<T> {
    pub log_time: u64,
    pub publish_time: u64,
    pub message: T,
}

/// Largest summary section read (schemas, channels, statistics, the chunk and
/// metadata indexes): an hour-long session's is about a megabyte (a chunk index
/// of some 150 bytes for each of its ~7,200 chunks), so this leaves room for days
/// and refuses a footer pointing at most of a large file.
pub const MAX_SUMMARY_BYTES: u64 = 64 << 20;

/// Most top-level records walked in a file without a summary (its chunks, their
/// message indexes, the metadata): a session closes a chunk at least every half
/// second with about nine records, so this is over 100 hours; at 9 bytes read a
/// record, the walk of the largest file reads at most 36 MiB of prefixes, and it
/// keeps only the places of its first and newest chunks ([`MAX_HEAD_CHUNKS`],
/// [`MAX_DURATION_CHUNKS`]). A file with more is refused (recovering it first lists
/// it).
pub const MAX_WALKED_RECORDS: u64 = 1 << 22;

/// Most chunks decompressed, while walking a file without a summary, looking for
/// its `laparo.scene` metadata: the recorder writes it after the first chunk (the
/// schemas, channels and scene).
pub const MAX_HEAD_CHUNKS: usize = 4;

/// Most chunks decompressed, newest first, looking for the last surface frame when
/// no index says which chunk holds it (a file without a summary). A session
/// records a frame every tick, so its newest chunk holds one; a file whose last
/// chunks hold none reads as lasting as long as its newest frame among them, 0 if
/// there is none.
pub const MAX_DURATION_CHUNKS: usize = 16;

/// Bytes of the footer record and the end magic.
pub(super) const FOOTER_AND_MAGIC: u64 = 1 + 8 + 20 + 8;

/// A chunk of the file: where its record starts, and whether it holds a surface
/// frame when an index (or a look inside) says so.
#[derive(Clone, Copy, Debug)]
struct ChunkAt {
    at: u64,
    surface: Option<bool>,
}

/// An open recording, read a record at a time through its file (see
/// [`super::source`]: never mapped, never held whole) and decoded a chunk at a
/// time as its messages are read.
///
/// A finished file is opened from its end: footer, summary, then the metadata
/// record its index points to. A file without a summary (a session still being
/// recorded, or a server stopped mid-session) is walked from the start a record
/// prefix at a time, skipping the chunks' compressed data, up to its last complete
/// record; only the first chunks are opened, for the channels and the metadata
/// (see [`MAX_WALKED_RECORDS`], [`MAX_HEAD_CHUNKS`]).
pub struct Recording {
    file: String,
    source: Source,
    meta: RecordingMeta,
    summary: Summary,
    /// The chunks in file order: all of a finished file's (from its index), the
    /// first and newest of an unfinished one's (what [`Recording::duration_s`]
    /// may open).
    chunks: Vec<ChunkAt>,
    /// Where the records read as data end: the summary's start for a finished file,
    /// the end of the last complete record for an unfinished one (read as it was
    /// when opened, even while its session appends to it).
    data_end: u64,
    /// Whether the file had its summary and footer (see
    /// [`open_unfinished`](Self::open_unfinished)).
    complete: bool,
}

impl std::fmt::Debug for Recording {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recording")
            .field("file", &self.file)
            .field("meta", &self.meta)
            .finish_non_exhaustive()
    }
}

/// Channel ids to topics, as a summary or a walk found them.
fn topics(summary: &Summary) -> HashMap<u16, String> {
    summary
        .channels
        .iter()
        .map(|(id, c)| (*id, c.topic.clone()))
        .collect()
}

impl Recording {
    /// Reads and checks the recording at `path` (through a symbolic link).
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let file = path.display().to_string();
        let source = Self::source(path, Follow::Links, &file)?;
        Self::from_source(file, source, false)
    }

    /// Reads the recording at `path` as far as it goes: a complete file as
    /// [`open`](Self::open) does; a file without its summary and footer (a session
    /// still being recorded, or a server stopped mid-session) up to its last complete
    /// record. A session creates its file with the scene and metadata in a first
    /// chunk, so an unfinished file reads as soon as it exists.
    /// [`is_complete`](Self::is_complete) tells which it was.
    pub fn open_unfinished(path: &Path) -> Result<Self, ReadError> {
        Self::open_unfinished_as(path, path.display().to_string())
    }

    /// [`open_unfinished`](Self::open_unfinished), naming the file `file` in errors.
    pub fn open_unfinished_as(path: &Path, file: String) -> Result<Self, ReadError> {
        let source = Self::source(path, Follow::Links, &file)?;
        Self::from_source(file, source, true)
    }

    /// [`open_unfinished_as`](Self::open_unfinished_as) of a file a server serves
    /// from its directory: only a regular file, never through a symbolic link.
    pub fn open_served(path: &Path, file: String) -> Result<Self, ReadError> {
        let source = Self::source(path, Follow::NoLinks, &file)?;
        Self::from_source(file, source, true)
    }

    fn source(path: &Path, follow: Follow, file: &str) -> Result<Source, ReadError> {
        Source::open(path, follow).map_err(|source| ReadError::Io {
            file: file.to_string(),
            source: Arc::new(source),
        })
    }

    /// [`open_unfinished`](Self::open_unfinished) of a file held in memory; `file`
    /// names it in errors.
    pub fn from_unfinished_bytes(file: String, bytes: Vec<u8>) -> Result<Self, ReadError> {
        Self::from_source(file, Source::held(bytes), true)
    }

    /// Checks a recording held in memory; `file` names it in errors.
    pub fn from_bytes(file: String, bytes: Vec<u8>) -> Result<Self, ReadError> {
        Self::from_source(file, Source::held(bytes), false)
    }

    /// Bytes read from the file so far (opening, listing, replaying).
    pub fn bytes_read(&self) -> u64 {
        self.source.bytes_read()
    }

    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// Whether the file had its summary and footer; `false` for a file read by
    /// [`open_unfinished`](Self::open_unfinished) as far as it went.
    pub fn is_complete(&self) -> bool {
        self.complete
    }
}
