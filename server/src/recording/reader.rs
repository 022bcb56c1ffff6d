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
const FOOTER_AND_MAGIC: u64 = 1 + 8 + 20 + 8;

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

    fn from_source(file: String, source: Source, unfinished: bool) -> Result<Self, ReadError> {
        let io = |e: std::io::Error| ReadError::Io {
            file: file.clone(),
            source: Arc::new(e),
        };
        let len = source.len().map_err(io)?;
        let magic = MAGIC.len() as u64;
        let mut head = [0u8; 8];
        if len < magic || source.read_exact_at(0, &mut head).is_err() || head[..] != MAGIC[..] {
            return Err(ReadError::NotMcap { file });
        }
        let mut tail = [0u8; 8];
        let footed = len >= 2 * magic
            && source.read_exact_at(len - magic, &mut tail).is_ok()
            && tail[..] == MAGIC[..];
        match (footed, unfinished) {
            (true, _) => Self::finished(file, source, len),
            (false, true) => Self::walked(file, source, len),
            (false, false) => Err(ReadError::Truncated { file }),
        }
    }

    /// A file with its footer: the summary it points to, then the metadata.
    fn finished(file: String, source: Source, len: u64) -> Result<Self, ReadError> {
        let corrupt = |message: String| ReadError::Corrupt {
            file: file.clone(),
            message,
        };
        if len < MAGIC.len() as u64 + FOOTER_AND_MAGIC {
            return Err(corrupt("it is too short for a footer".into()));
        }
        let footer_at = len - FOOTER_AND_MAGIC;
        let footer = source
            .read_at(footer_at, FOOTER_AND_MAGIC, FOOTER_AND_MAGIC)
            .map_err(|e| corrupt(e.to_string()))?;
        if footer[0] != op::FOOTER {
            return Err(corrupt(format!("no footer record at byte {footer_at}")));
        }
        let summary_start = u64::from_le_bytes(footer[9..17].try_into().expect("8 bytes"));
        if summary_start == 0 {
            return Err(ReadError::Truncated { file });
        }
        if summary_start > footer_at || footer_at - summary_start > MAX_SUMMARY_BYTES {
            return Err(corrupt(format!(
                "its footer puts the summary at byte {summary_start}, which is not within \
                 {MAX_SUMMARY_BYTES} bytes before the footer at byte {footer_at}"
            )));
        }
        let summary = {
            let mut cursor = source.cursor();
            let mut reader = SummaryReader::new_with_options(
                SummaryReaderOptions::default()
                    .with_file_size(len)
                    .with_record_length_limit(MAX_SUMMARY_BYTES as usize),
            );
            while let Some(event) = reader.next_event() {
                match event.map_err(|e| corrupt(e.to_string()))? {
                    SummaryReadEvent::ReadRequest(n) => {
                        let read = cursor
                            .read(reader.insert(n))
                            .map_err(|e| corrupt(e.to_string()))?;
                        reader.notify_read(read);
                    }
                    SummaryReadEvent::SeekRequest(to) => {
                        let at = cursor.seek(to).map_err(|e| corrupt(e.to_string()))?;
                        reader.notify_seeked(at);
                    }
                }
            }
            reader
                .finish()
                .ok_or_else(|| ReadError::Truncated { file: file.clone() })?
        };
        let not_ours = |message: String| ReadError::NotARecording {
            file: file.clone(),
            message,
        };
        let index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == METADATA_NAME)
            .ok_or_else(|| not_ours(format!("it has no `{METADATA_NAME}` metadata record")))?;
        let record = source
            .read_at(index.offset, index.length, MAX_RECORD_BYTES)
            .map_err(|e| corrupt(format!("its metadata index: {e}")))
            .and_then(|b| parse_one(&b).map_err(corrupt))?;
        let Record::Metadata(metadata) = record else {
            return Err(corrupt(
                "its metadata index points at another record".into(),
            ));
        };
        let meta = meta_from(&file, metadata.metadata)?;
        let surface: Vec<u16> = summary
            .channels
            .values()
            .filter(|c| c.topic == TOPIC_SURFACE)
            .map(|c| c.id)
            .collect();
        let mut chunks: Vec<ChunkAt> = summary
            .chunk_indexes
            .iter()
            .map(|c| ChunkAt {
                at: c.chunk_start_offset,
                surface: (!c.message_index_offsets.is_empty()).then(|| {
                    c.message_index_offsets
                        .keys()
                        .any(|id| surface.contains(id))
                }),
            })
            .collect();
        chunks.sort_by_key(|c| c.at);
        Ok(Recording {
            file,
            source,
            meta,
            summary,
            chunks,
            data_end: summary_start,
            complete: true,
        })
    }

    /// A file without its footer, walked (see the type's documentation). The walk
    /// ends at the first record cut short or damaged: what `recover` would keep,
    /// but for damage inside a chunk not opened here, which the reading that
    /// reaches it reports.
    fn walked(file: String, source: Source, len: u64) -> Result<Self, ReadError> {
        let corrupt = |message: String| ReadError::Corrupt {
            file: file.clone(),
            message,
        };
        let mut schemas: HashMap<u16, Arc<Schema<'static>>> = HashMap::new();
        let mut channels: HashMap<u16, Arc<Channel<'static>>> = HashMap::new();
        let add = |schemas: &mut HashMap<u16, Arc<Schema<'static>>>,
                   channels: &mut HashMap<u16, Arc<Channel<'static>>>,
                   record: Record<'static>| match record {
            Record::Schema { header, data } => {
                schemas.entry(header.id).or_insert_with(|| {
                    Arc::new(Schema {
                        id: header.id,
                        name: header.name,
                        encoding: header.encoding,
                        data,
                    })
                });
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id).cloned();
                channels.entry(c.id).or_insert_with(|| {
                    Arc::new(Channel {
                        id: c.id,
                        topic: c.topic,
                        schema,
                        message_encoding: c.message_encoding,
                        metadata: c.metadata,
                    })
                });
            }
            _ => {}
        };
        let mut metadata = None;
        let mut chunks = Vec::new();
        let mut newest = VecDeque::with_capacity(MAX_DURATION_CHUNKS);
        let mut opened = 0;
        let mut at = MAGIC.len() as u64;
        let mut walked = 0u64;
        while let Ok(Some(framed)) = frame_at(&source, at, len) {
            walked += 1;
            if walked > MAX_WALKED_RECORDS {
                return Err(corrupt(format!(
                    "it has more than {MAX_WALKED_RECORDS} records and no summary; \
                     recovering it writes one"
                )));
            }
            match framed.op {
                op::CHUNK if metadata.is_none() && opened < MAX_HEAD_CHUNKS => {
                    opened += 1;
                    let records = match read_record(&source, &framed) {
                        Ok(Record::Chunk { header, data }) => chunk_records(&header, &data),
                        Ok(_) => Err("not a chunk".into()),
                        Err(e) => Err(e),
                    };
                    let Ok(records) = records else { break };
                    let mut surface = false;
                    for r in records {
                        if let Record::Message { header, .. } = &r {
                            surface |= channels
                                .get(&header.channel_id)
                                .is_some_and(|c| c.topic == TOPIC_SURFACE);
                        }
                        add(&mut schemas, &mut channels, r);
                    }
                    chunks.push(ChunkAt {
                        at: framed.at,
                        surface: Some(surface),
                    });
                }
                op::CHUNK => {
                    // Only the newest are ever opened (for the duration).
                    if newest.len() == MAX_DURATION_CHUNKS {
                        newest.pop_front();
                    }
                    newest.push_back(ChunkAt {
                        at: framed.at,
                        surface: None,
                    });
                }
                op::SCHEMA | op::CHANNEL | op::METADATA => match read_record(&source, &framed) {
                    Ok(Record::Metadata(m)) if m.name == METADATA_NAME => metadata = Some(m),
                    Ok(r) => add(&mut schemas, &mut channels, r),
                    Err(_) => break,
                },
                op::DATA_END | op::FOOTER => break,
                _ => {}
            }
            at = framed.end();
        }
        let Some(metadata) = metadata else {
            return Err(ReadError::NotARecording {
                file,
                message: format!(
                    "it has no `{METADATA_NAME}` metadata record in what it holds so far"
                ),
            });
        };
        let meta = meta_from(&file, metadata.metadata)?;
        chunks.extend(newest);
        Ok(Recording {
            file,
            source,
            meta,
            summary: Summary {
                schemas,
                channels,
                ..Summary::default()
            },
            chunks,
            data_end: at,
            complete: false,
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
    /// surface frame's, as [`super::summarize`] counts the duration. Frames are
    /// written in tick order, so it is in the newest chunk holding one: an indexed
    /// file (every file the recorder finishes or recovery writes) says which; in
    /// another the newest chunks are opened one at a time, at most
    /// [`MAX_DURATION_CHUNKS`] of them. A chunk that does not read is an error in a
    /// finished file, and skipped in an unfinished one (its session may be writing
    /// over it).
    pub fn duration_s(&self) -> Result<f64, ReadError> {
        let mut topics = topics(&self.summary);
        let mut unknown = 0;
        for chunk in self.chunks.iter().rev() {
            match chunk.surface {
                Some(false) => continue,
                Some(true) => {}
                None if unknown == MAX_DURATION_CHUNKS => break,
                None => unknown += 1,
            }
            let records = match self.chunk_at(chunk.at) {
                Ok(r) => r,
                Err(e) if self.complete => return Err(e),
                Err(_) => continue,
            };
            let frames = records.into_iter().filter_map(|r| match r {
                Record::Channel(c) => {
                    topics.insert(c.id, c.topic);
                    None
                }
                Record::Message { header, data }
                    if topics.get(&header.channel_id).map(String::as_str)
                        == Some(TOPIC_SURFACE) =>
                {
                    Some(Ok((header, data.into_owned())))
                }
                _ => None,
            });
            let mut any = false;
            let t = self.latest_frame_time(frames.inspect(|_| any = true))?;
            if any {
                return Ok(t);
            }
        }
        Ok(0.0)
    }

    /// The records of the chunk whose record starts at `at`.
    fn chunk_at(&self, at: u64) -> Result<Vec<Record<'static>>, ReadError> {
        let framed = frame_at(&self.source, at, self.data_end)
            .map_err(|e| self.corrupt(e.to_string()))?
            .ok_or_else(|| self.corrupt(format!("an index points at byte {at}, past its data")))?;
        match read_record(&self.source, &framed).map_err(|e| self.corrupt(e))? {
            Record::Chunk { header, data } => {
                chunk_records(&header, &data).map_err(|e| self.corrupt(e))
            }
            _ => Err(self.corrupt(format!(
                "its chunk index points at byte {at}, where no chunk starts"
            ))),
        }
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

    /// Messages per topic, from the file's statistics; a file without them (an
    /// unfinished one) is read through, a chunk at a time, and counted up to its
    /// first error.
    pub fn message_counts(&self) -> BTreeMap<String, u64> {
        let mut counts = BTreeMap::new();
        if self.summary.stats.is_none() {
            for m in self.raw() {
                let Ok((topic, _, _)) = m else { break };
                *counts.entry(topic).or_default() += 1;
            }
        }
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
        Self::messages_of(self)
    }

    /// [`messages`](Self::messages) owning the recording: an iterator that can be
    /// kept between reads (a replay reads in bursts, moving it to a blocking thread
    /// for each).
    pub fn into_messages(
        self: std::sync::Arc<Self>,
    ) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> + Send + 'static {
        Self::messages_of(self)
    }

    fn messages_of<R: std::ops::Deref<Target = Recording> + Clone>(
        this: R,
    ) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> {
        let decoder = this.clone();
        Self::raw_of(this).filter_map(move |m| {
            let (topic, header, data) = match m {
                Ok(m) => m,
                Err(e) => return Some(Err(e)),
            };
            let d = &*decoder;
            let decoded = match topic.as_str() {
                TOPIC_SCENE => d.decode(&topic, &header, &data).map(Recorded::Scene),
                TOPIC_POSES => d.decode(&topic, &header, &data).map(Recorded::Pose),
                TOPIC_SURFACE => d.decode(&topic, &header, &data).map(Recorded::Surface),
                TOPIC_INSTRUMENTS => d.decode(&topic, &header, &data).map(Recorded::Instrument),
                TOPIC_EVENTS => d.decode(&topic, &header, &data).map(Recorded::Event),
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

    /// Every message in file order, undecoded, with its topic: the data section
    /// walked a record at a time, each chunk read and decompressed as it is reached
    /// (one in memory at a time), indexes and other records skipped unread. A
    /// record that does not fit in the file as it is now (cut or rewritten while
    /// read) ends the messages with an error, as a damaged one does.
    fn raw(
        &self,
    ) -> impl Iterator<Item = Result<(String, MessageHeader, Vec<u8>), ReadError>> + '_ {
        Self::raw_of(self)
    }

    /// [`raw`](Self::raw) of a recording held by `this` (a reference or an `Arc`).
    fn raw_of<R: std::ops::Deref<Target = Recording>>(
        this: R,
    ) -> impl Iterator<Item = Result<(String, MessageHeader, Vec<u8>), ReadError>> {
        let mut topics = topics(&this.summary);
        let mut at = MAGIC.len() as u64;
        let mut pending: VecDeque<Record<'static>> = VecDeque::new();
        let mut done = false;
        std::iter::from_fn(move || {
            loop {
                if done {
                    return None;
                }
                let Some(record) = pending.pop_front() else {
                    let framed = match frame_at(&this.source, at, this.data_end) {
                        Ok(Some(f)) => f,
                        Ok(None) => return None,
                        Err(e) => {
                            done = true;
                            return Some(Err(this.corrupt(e.to_string())));
                        }
                    };
                    at = framed.end();
                    let read = || read_record(&this.source, &framed);
                    let records = match framed.op {
                        op::CHUNK => read().and_then(|r| match r {
                            Record::Chunk { header, data } => chunk_records(&header, &data),
                            _ => Err("not a chunk".into()),
                        }),
                        op::MESSAGE | op::CHANNEL => read().map(|r| vec![r]),
                        op::DATA_END | op::FOOTER => {
                            done = true;
                            return None;
                        }
                        _ => continue,
                    };
                    match records {
                        Ok(r) => pending.extend(r),
                        Err(e) => {
                            done = true;
                            return Some(Err(this.corrupt(e)));
                        }
                    }
                    continue;
                };
                match record {
                    Record::Channel(c) => {
                        topics.insert(c.id, c.topic);
                    }
                    Record::Message { header, data } => {
                        let Some(topic) = topics.get(&header.channel_id) else {
                            done = true;
                            return Some(Err(this.corrupt(format!(
                                "message {} is on channel {}, which the file does not define",
                                header.sequence, header.channel_id
                            ))));
                        };
                        return Some(Ok((topic.clone(), header, data.into_owned())));
                    }
                    _ => {}
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

/// The recording's description from its `laparo.scene` metadata fields.
fn meta_from(file: &str, mut fields: BTreeMap<String, String>) -> Result<RecordingMeta, ReadError> {
    let not_ours = |message: String| ReadError::NotARecording {
        file: file.to_string(),
        message,
    };
    let mut take = |key: &str| {
        fields
            .remove(key)
            .ok_or_else(|| not_ours(format!("its `{METADATA_NAME}` metadata has no `{key}`")))
    };
    let format_version = take("format_version")?;
    if format_version != FORMAT_VERSION {
        return Err(ReadError::UnsupportedVersion {
            file: file.to_string(),
            found: format_version,
        });
    }
    let start = take("start_unix_ns")?;
    Ok(RecordingMeta {
        format_version,
        session_id: take("session_id")?,
        scene: take("scene")?,
        start_unix_ns: start
            .parse()
            .map_err(|_| not_ours(format!("its start time `{start}` is not a number of ns")))?,
        scene_toml: take("scene_toml")?,
        scene_dir: fields.remove("scene_dir").map(std::path::PathBuf::from),
    })
}
