//! Reading a recording back: open it, check that it is a laparo recording of a
//! version this server knows, and decode its messages with the contract's types.
//!
//! A file that is not MCAP, is corrupt or was cut short gets a [`ReadError`] naming
//! the file and what is wrong; nothing here panics on bad input. A file cut short
//! (a killed server, or a session still running) has no summary: [`Recording::open`]
//! says so and [`super::recover`] rewrites it into a complete one;
//! [`Recording::open_unfinished`] reads what it holds so far.

use std::collections::{BTreeMap, VecDeque};
use std::io::Cursor;
use std::path::Path;

use foxglove::schemas::SceneUpdate;
use laparo_proto::v1;
use mcap::records::{MessageHeader, Record};
use mcap::{MAGIC, Summary};

use super::records::{Records, chunk_records};
use super::recover::{RecoverError, recover_bytes};

use super::{
    FORMAT_VERSION, METADATA_NAME, TOPIC_EVENTS, TOPIC_FOXGLOVE_SCENE, TOPIC_INSTRUMENTS,
    TOPIC_POSES, TOPIC_SCENE, TOPIC_SURFACE,
};

/// Why a recording cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("cannot read {file}: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap { file: String },
    #[error(
        "{file} ends without its summary: it was cut short (a stopped server) or is still \
         being written; recovering it rewrites it into a complete file"
    )]
    Truncated { file: String },
    #[error("{file} is a corrupt MCAP file: {message}")]
    Corrupt { file: String, message: String },
    #[error("{file} is not a laparo recording: {message}")]
    NotARecording { file: String, message: String },
    #[error(
        "{file} is a laparo recording of format version `{found}`, which this server does \
         not read (it reads version {FORMAT_VERSION})"
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

/// A recording's bytes: a finished file mapped into memory, or bytes held.
///
/// A finished recording is not written again: its recorder has closed it, and
/// `recover` writes a new file and renames it over the old one, which leaves a map
/// of the old one intact. Mapping it lets a replay or a listing page through an
/// hour-long session instead of holding all of it. A file still being written
/// changes under a map (the open chunk's lengths are filled in when it closes), so
/// it is read into memory instead; a file is taken as finished when it ends with
/// the footer's magic bytes, which a recorder writes last.
enum Bytes {
    Held(Vec<u8>),
    Mapped(memmap2::Mmap),
}

impl std::ops::Deref for Bytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Held(v) => v,
            Bytes::Mapped(m) => m,
        }
    }
}

/// The file at `path` (named `file` in errors), mapped if finished (see [`Bytes`]).
fn load(path: &Path, file: &str) -> Result<Bytes, ReadError> {
    let io = |source| ReadError::Io {
        file: file.to_string(),
        source,
    };
    let mut f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    if len >= 2 * MAGIC.len() as u64 {
        // SAFETY: the map is read only, and kept only for a finished file, which
        // nothing writes again (see `Bytes`); a file changed in place by hand while
        // it is read can only give wrong bytes, which every reader here checks
        // (lengths, CRCs) as it would a corrupt file.
        let map = unsafe { memmap2::Mmap::map(&f) }.map_err(io)?;
        if map.starts_with(MAGIC) && map.ends_with(MAGIC) {
            return Ok(Bytes::Mapped(map));
        }
    }
    // The same open file: a map does not move its position.
    let mut bytes = Vec::with_capacity(len as usize);
    std::io::Read::read_to_end(&mut f, &mut bytes).map_err(io)?;
    Ok(Bytes::Held(bytes))
}

/// An open recording: a finished file mapped, an unfinished one read into memory
/// (see [`Bytes`]); compressed, as on disk, and decoded a chunk at a time as its
/// messages are read.
pub struct Recording {
    file: String,
    bytes: Bytes,
    meta: RecordingMeta,
    summary: Summary,
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

impl Recording {
    /// Reads and checks the recording at `path`.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let file = path.display().to_string();
        let bytes = load(path, &file)?;
        Self::from_loaded(file, bytes)
    }

    /// Reads the recording at `path` as far as it goes: a complete file as
    /// [`open`](Self::open) does; a file without its summary and footer (a session
    /// still being recorded, or a server stopped mid-session) up to its last complete
    /// chunk, exactly what [`super::recover`] would keep of it. A session creates its
    /// file with the scene and metadata in a first chunk, so an unfinished file reads
    /// as soon as it exists. [`is_complete`](Self::is_complete) tells which it was.
    pub fn open_unfinished(path: &Path) -> Result<Self, ReadError> {
        Self::open_unfinished_as(path, path.display().to_string())
    }

    /// [`open_unfinished`](Self::open_unfinished), naming the file `file` in errors.
    pub fn open_unfinished_as(path: &Path, file: String) -> Result<Self, ReadError> {
        match load(path, &file)? {
            mapped @ Bytes::Mapped(_) => Self::from_loaded(file, mapped),
            Bytes::Held(bytes) => Self::from_unfinished_bytes(file, bytes),
        }
    }

    /// [`open_unfinished`](Self::open_unfinished) of a file held in memory; `file`
    /// names it in errors.
    pub fn from_unfinished_bytes(file: String, bytes: Vec<u8>) -> Result<Self, ReadError> {
        // A file with its footer is finished: any fault in it is reported as such.
        let footed = bytes.len() >= 2 * MAGIC.len() && bytes.ends_with(MAGIC);
        if footed || !bytes.starts_with(MAGIC) {
            return Self::from_bytes(file, bytes);
        }
        // What the file holds so far, rewritten with a summary: the index and
        // statistics the reader relies on, for the complete chunks only.
        let (_, out) =
            recover_bytes(&file, &bytes, Cursor::new(Vec::new())).map_err(|e| match e {
                RecoverError::NotMcap { file } => ReadError::NotMcap { file },
                e => ReadError::Corrupt {
                    file: file.clone(),
                    message: e.to_string(),
                },
            })?;
        drop(bytes);
        let mut recording = Self::from_bytes(file, out.into_inner())?;
        recording.complete = false;
        Ok(recording)
    }

    /// Whether the file is mapped rather than held in memory (see [`Bytes`]).
    pub fn is_mapped(&self) -> bool {
        matches!(self.bytes, Bytes::Mapped(_))
    }

    /// Checks a recording held in memory; `file` names it in errors.
    pub fn from_bytes(file: String, bytes: Vec<u8>) -> Result<Self, ReadError> {
        Self::from_loaded(file, Bytes::Held(bytes))
    }

    fn from_loaded(file: String, bytes: Bytes) -> Result<Self, ReadError> {
        if !bytes.starts_with(MAGIC) {
            return Err(ReadError::NotMcap { file });
        }
        if !bytes.ends_with(MAGIC) {
            return Err(ReadError::Truncated { file });
        }
        let corrupt = |e: mcap::McapError| ReadError::Corrupt {
            file: file.clone(),
            message: e.to_string(),
        };
        let summary = Summary::read(&bytes)
            .map_err(corrupt)?
            .ok_or_else(|| ReadError::Truncated { file: file.clone() })?;
        let not_ours = |message: String| ReadError::NotARecording {
            file: file.clone(),
            message,
        };
        let index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == METADATA_NAME)
            .ok_or_else(|| not_ours(format!("it has no `{METADATA_NAME}` metadata record")))?;
        let mut fields = mcap::read::metadata(&bytes, index)
            .map_err(corrupt)?
            .metadata;
        let mut take = |key: &str| {
            fields
                .remove(key)
                .ok_or_else(|| not_ours(format!("its `{METADATA_NAME}` metadata has no `{key}`")))
        };
        let format_version = take("format_version")?;
        if format_version != FORMAT_VERSION {
            return Err(ReadError::UnsupportedVersion {
                file,
                found: format_version,
            });
        }
        let start = take("start_unix_ns")?;
        let meta = RecordingMeta {
            format_version,
            session_id: take("session_id")?,
            scene: take("scene")?,
            start_unix_ns: start
                .parse()
                .map_err(|_| not_ours(format!("its start time `{start}` is not a number of ns")))?,
            scene_toml: take("scene_toml")?,
            scene_dir: fields.remove("scene_dir").map(std::path::PathBuf::from),
        };
        Ok(Recording {
            file,
            bytes,
            meta,
            summary,
            complete: true,
        })
    }

    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// Whether the file had its summary and footer; `false` for a file read by
    /// [`open_unfinished`](Self::open_unfinished) as far as it went.
    pub fn is_complete(&self) -> bool {
        self.complete
    }

    /// Simulated time of the last tick recorded, s (0 without any): the newest
    /// surface frame's, as [`super::summarize`] counts the duration. An indexed file
    /// (every file the recorder finishes or recovery writes) has it from the last
    /// chunk that holds a frame; otherwise every frame is read.
    pub fn duration_s(&self) -> Result<f64, ReadError> {
        let chunks = &self.summary.chunk_indexes;
        let indexed =
            !chunks.is_empty() && chunks.iter().all(|c| !c.message_index_offsets.is_empty());
        if !indexed {
            let frames = self.raw().filter_map(|m| match m {
                Ok((topic, header, data)) => (topic == TOPIC_SURFACE).then_some(Ok((header, data))),
                Err(e) => Some(Err(e)),
            });
            return self.latest_frame_time(frames);
        }
        let surface: Vec<u16> = self
            .summary
            .channels
            .values()
            .filter(|c| c.topic == TOPIC_SURFACE)
            .map(|c| c.id)
            .collect();
        let Some(last) = chunks
            .iter()
            .filter(|c| {
                c.message_index_offsets
                    .keys()
                    .any(|id| surface.contains(id))
            })
            .max_by_key(|c| c.chunk_start_offset)
        else {
            return Ok(0.0);
        };
        let at = usize::try_from(last.chunk_start_offset).unwrap_or(usize::MAX);
        let records = match Records::at(&self.bytes, at).next() {
            Some(Ok((_, Record::Chunk { header, data }))) => {
                chunk_records(&header, &data).map_err(|e| self.corrupt(e))?
            }
            Some(Err(e)) => return Err(self.corrupt(e)),
            _ => {
                return Err(self.corrupt(format!(
                    "its chunk index points at byte {at}, where no chunk starts"
                )));
            }
        };
        let frames = records.into_iter().filter_map(|r| match r {
            Record::Message { header, data } if surface.contains(&header.channel_id) => {
                Some(Ok((header, data.into_owned())))
            }
            _ => None,
        });
        self.latest_frame_time(frames)
    }

    /// The largest simulated time of the surface frames given undecoded.
    fn latest_frame_time(
        &self,
        frames: impl Iterator<Item = Result<(MessageHeader, Vec<u8>), ReadError>>,
    ) -> Result<f64, ReadError> {
        let mut t: f64 = 0.0;
        for f in frames {
            let (header, data) = f?;
            let frame: v1::SurfaceFrame = self.decode(TOPIC_SURFACE, &header, &data)?;
            t = t.max(frame.sim_time_s);
        }
        Ok(t)
    }

    /// The file's MCAP summary (channels, schemas, statistics, indexes).
    pub fn mcap_summary(&self) -> &Summary {
        &self.summary
    }

    /// Messages per topic, from the file's statistics.
    pub fn message_counts(&self) -> BTreeMap<String, u64> {
        let mut counts = BTreeMap::new();
        if let Some(stats) = &self.summary.stats {
            for (id, n) in &stats.channel_message_counts {
                if let Some(c) = self.summary.channels.get(id) {
                    *counts.entry(c.topic.clone()).or_default() += n;
                }
            }
        }
        counts
    }

    /// Every message of the contract's topics in file order, decoded. Messages of
    /// other topics (`/foxglove/scene`, for viewers, and any this version does not
    /// know) are skipped undecoded; reading ends at the first error.
    pub fn messages(&self) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> + '_ {
        self.raw().filter_map(move |m| {
            let (topic, header, data) = match m {
                Ok(m) => m,
                Err(e) => return Some(Err(e)),
            };
            let decoded = match topic.as_str() {
                TOPIC_SCENE => self.decode(&topic, &header, &data).map(Recorded::Scene),
                TOPIC_POSES => self.decode(&topic, &header, &data).map(Recorded::Pose),
                TOPIC_SURFACE => self.decode(&topic, &header, &data).map(Recorded::Surface),
                TOPIC_INSTRUMENTS => self
                    .decode(&topic, &header, &data)
                    .map(Recorded::Instrument),
                TOPIC_EVENTS => self.decode(&topic, &header, &data).map(Recorded::Event),
                _ => return None,
            };
            Some(decoded.map(|message| Stamped {
                log_time: header.log_time,
                publish_time: header.publish_time,
                message,
            }))
        })
    }

    /// The messages of one topic, decoded as `T`, in file order.
    pub fn topic<T: prost::Message + Default>(
        &self,
        topic: &str,
    ) -> Result<Vec<Stamped<T>>, ReadError> {
        let mut out = Vec::new();
        for m in self.raw() {
            let (t, header, data) = m?;
            if t == topic {
                out.push(Stamped {
                    log_time: header.log_time,
                    publish_time: header.publish_time,
                    message: self.decode(&t, &header, &data)?,
                });
            }
        }
        Ok(out)
    }

    /// Every message in file order, undecoded, with its topic.
    fn raw(
        &self,
    ) -> impl Iterator<Item = Result<(String, MessageHeader, Vec<u8>), ReadError>> + '_ {
        let mut records = Records::new(&self.bytes);
        let mut pending: VecDeque<Record<'static>> = VecDeque::new();
        let mut done = false;
        std::iter::from_fn(move || {
            loop {
                if done {
                    return None;
                }
                let record = match pending.pop_front() {
                    Some(r) => r,
                    None => match records.next() {
                        None => return None,
                        Some(Err(e)) => {
                            done = true;
                            return Some(Err(self.corrupt(e)));
                        }
                        Some(Ok((_, Record::Chunk { header, data }))) => {
                            match chunk_records(&header, &data) {
                                Ok(r) => pending.extend(r),
                                Err(e) => {
                                    done = true;
                                    return Some(Err(self.corrupt(e)));
                                }
                            }
                            continue;
                        }
                        Some(Ok((_, Record::DataEnd(_) | Record::Footer(_)))) => {
                            done = true;
                            return None;
                        }
                        Some(Ok((_, r))) => r.into_owned(),
                    },
                };
                if let Record::Message { header, data } = record {
                    let Some(channel) = self.summary.channels.get(&header.channel_id) else {
                        done = true;
                        return Some(Err(self.corrupt(format!(
                            "message {} is on channel {}, which the summary does not list",
                            header.sequence, header.channel_id
                        ))));
                    };
                    return Some(Ok((channel.topic.clone(), header, data.into_owned())));
                }
            }
        })
    }

    /// The recorded scene: the first message on `/scene`, which the recorder writes
    /// first, so reading stops in the first chunk.
    pub fn scene(&self) -> Result<v1::SceneDescription, ReadError> {
        for m in self.raw() {
            let (topic, header, data) = m?;
            if topic == TOPIC_SCENE {
                return self.decode(&topic, &header, &data);
            }
        }
        Err(ReadError::NotARecording {
            file: self.file.clone(),
            message: format!("it has no message on {TOPIC_SCENE}"),
        })
    }

    pub fn poses(&self) -> Result<Vec<Stamped<v1::DevicePose>>, ReadError> {
        self.topic(TOPIC_POSES)
    }

    pub fn surfaces(&self) -> Result<Vec<Stamped<v1::SurfaceFrame>>, ReadError> {
        self.topic(TOPIC_SURFACE)
    }

    pub fn instrument_states(&self) -> Result<Vec<Stamped<v1::InstrumentState>>, ReadError> {
        self.topic(TOPIC_INSTRUMENTS)
    }

    pub fn events(&self) -> Result<Vec<Stamped<v1::Event>>, ReadError> {
        self.topic(TOPIC_EVENTS)
    }

    /// The Foxglove scene updates, decoded only when asked for.
    pub fn scene_updates(&self) -> Result<Vec<Stamped<SceneUpdate>>, ReadError> {
        self.topic(TOPIC_FOXGLOVE_SCENE)
    }

    fn decode<T: prost::Message + Default>(
        &self,
        topic: &str,
        header: &MessageHeader,
        data: &[u8],
    ) -> Result<T, ReadError> {
        T::decode(data).map_err(|e| ReadError::Decode {
            file: self.file.clone(),
            topic: topic.to_string(),
            sequence: header.sequence,
            message: e.to_string(),
        })
    }

    fn corrupt(&self, message: String) -> ReadError {
        ReadError::Corrupt {
            file: self.file.clone(),
            message,
        }
    }
}
