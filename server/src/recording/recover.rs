//! Recovering the file a killed server leaves: a data section that stops anywhere,
//! possibly inside a chunk, with no summary and no footer.
//!
//! The file is read record by record; every record before the first that is cut
//! short or does not parse is kept — a chunk only whole, when it decompresses
//! completely and its CRC matches — and the kept schemas, channels (with their
//! ids), messages (with their sequence numbers and times) and metadata are written
//! anew, with a summary, indexes and a footer. So at most what the recorder had not
//! yet closed into a chunk (the last second, see [`super::writer::FLUSH_INTERVAL`])
//! is lost. A chunk whose record is whole but whose contents are damaged (a CRC
//! that does not match, data that does not decompress) is left out and the walk
//! goes on after it, since its stated length still frames the records that follow;
//! messages of a channel that only such a chunk declared are left out too.
//! A finished file (one with its footer) whose summary section passes the
//! footer's CRC ([`super::intact_summary`]) is walked with its chunk index: a
//! chunk is framed by its index entry, so one whose own length or opcode was
//! damaged is still read (and kept when its CRC matches), a record damaged so
//! that nothing after it frames is stepped over to the next indexed chunk
//! ([`Recovery::damaged_spans`]), and a schema or channel lost with it is
//! written from the summary's copy.
//! Schema records, written outside chunks with no CRC, are checked by decoding
//! them; a damaged one is written from this build's descriptors and reported
//! ([`Recovery::damaged_schemas`]).
//! A file with nothing recoverable (no `laparo.scene` metadata before the damage:
//! junk after the magic, a file cut inside its first chunk) is an error
//! ([`RecoverError::NothingToRecover`]), and no file is written.
//!
//! What is written: a file beside the output (`OUT.<pid>.part`, created new) renamed
//! over it once complete, so the output is either as it was or whole. The output
//! must be a regular file or absent: a device, a symbolic link or a directory is
//! refused, never replaced. Recovering a file in place drops only what a killed
//! server leaves unfinished; when the recovery would drop more (a damaged chunk, or
//! anything of a file that had its footer), the input is left as it is and the
//! recovery must be written elsewhere ([`RecoverError::WouldLose`]).

use std::borrow::Cow;
use std::collections::HashSet;
use std::io::{Seek, Write};
use std::path::Path;

use foxglove::Encode;
use foxglove::schemas::SceneUpdate;
use mcap::records::{Channel, Record, op};
use mcap::{Compression, MAGIC, McapError, WriteOptions};

use super::METADATA_NAME;
use super::intact_summary::{IntactSummary, intact_summary};
use super::records::{Framed, chunk_records, frame_at, read_record};
use super::source::{Follow, Source};
use crate::engine::scene::{file_kind, same_file};
use crate::output::{WholeFile, part_path};

/// What a recovery kept and left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recovery {
    /// Complete chunks kept.
    pub chunks: u64,
    /// Messages kept.
    pub messages: u64,
    /// Bytes of the input up to the end of the last record kept.
    pub bytes_kept: u64,
    /// Bytes after it, left out (a chunk being written, a damaged tail).
    pub bytes_dropped: u64,
    /// Whether the input already ended with a summary and footer.
    pub was_complete: bool,
    /// Why reading stopped before the end, if it did.
    pub stopped_at: Option<String>,
    /// Chunks left out whole because their contents were damaged, each with why.
    pub damaged_chunks: Vec<String>,
    /// Messages left out because their channel was declared only in a damaged chunk.
    pub orphaned_messages: u64,
    /// Schema records whose data was damaged, each with what was done about it
    /// ([`checked_schema`]).
    pub damaged_schemas: Vec<String>,
    /// Spans of a finished file stepped over because a record in them was damaged
    /// where its length no longer framed what follows, each with why: the file's
    /// checked summary said where the next chunk starts.
    pub damaged_spans: Vec<String>,
    /// Chunks whose own opcode or length was damaged, framed by the file's checked
    /// chunk index instead and kept whole (their CRC matched).
    pub reframed_chunks: u64,
}

impl Recovery {
    /// Whether anything besides an unfinished tail (what a killed server leaves)
    /// was left out: a damaged chunk, or part of a file that had its footer.
    pub fn lost_more_than_a_tail(&self) -> bool {
        !self.damaged_chunks.is_empty()
            || !self.damaged_spans.is_empty()
            || self.orphaned_messages > 0
            || (self.was_complete && self.stopped_at.is_some())
    }
}

/// Why a file cannot be recovered.
#[derive(Debug, thiserror::Error)]
pub enum RecoverError {
    #[error("cannot read {file}: {source}")]
    Read {
        file: String,
        source: std::io::Error,
    },
    #[error("{file} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap { file: String },
    #[error("cannot write the recovered recording {file}: {message}")]
    Write { file: String, message: String },
    /// The output exists and is not a regular file.
    #[error(
        "will not write the recovered recording over {file}: it is a {kind}, not a \
         regular file; give another --out"
    )]
    OutputNotRegular { file: String, kind: &'static str },
    /// A recovery in place would drop more than an unfinished tail.
    #[error(
        "{file} was left as it is: recovering it in place would leave out {what}; \
         give --out OTHER.mcap to write what can be recovered beside it"
    )]
    WouldLose { file: String, what: String },
    /// Nothing before the first record cut short or damaged says what the file
    /// records (its `laparo.scene` metadata record): a recovered file would be an
    /// empty MCAP file, so none is written.
    #[error(
        "{file} holds nothing recoverable: no `{METADATA_NAME}` record before {why}; \
         no file written"
    )]
    NothingToRecover { file: String, why: String },
    /// The input, or the file the output would replace, is locked by a live
    /// recorder ([`super::lock`]).
    #[error(
        "{file} is being recorded: a running server holds it (its session has not \
         ended); recovering it now would cut the rest of the session off, so it is \
         left as it is"
    )]
    BeingRecorded { file: String },
    /// The output is another file that exists, and replacing it was not asked for.
    #[error(
        "will not write the recovered recording over {file}: it exists and is not the file \
         recovered; give another --out, or --replace to replace it"
    )]
    OutputExists { file: String },
}

/// What [`recover`] does with an output that exists and is not the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Existing {
    /// Refuse it ([`RecoverError::OutputExists`]): another recording there would
    /// be lost without a word.
    Refuse,
    /// Replace it (a regular file not being recorded; the new file is renamed over
    /// it, so a reader of the old one keeps reading it).
    Replace,
}

/// Rewrites the recording `input` into a complete one at `output` (which may be
/// `input`: the new file is written beside it and renamed over it). Another file
/// at `output` is replaced only if `existing` says so.
///
/// The input is read a record at a time through a [`Source`] and each kept record
/// is written at once, so memory holds one chunk whatever the file's size.
pub fn recover(input: &Path, output: &Path, existing: Existing) -> Result<Recovery, RecoverError> {
    let file = input.display().to_string();
    let source = Source::open(input, Follow::Links).map_err(|source| RecoverError::Read {
        file: file.clone(),
        source,
    })?;
    if source.being_written() {
        return Err(RecoverError::BeingRecorded { file });
    }
    let out_name = output.display().to_string();
    let write_error = |message: String| RecoverError::Write {
        file: out_name.clone(),
        message,
    };
    let in_place = match std::fs::symlink_metadata(output) {
        Ok(meta) if !meta.is_file() => {
            return Err(RecoverError::OutputNotRegular {
                file: out_name,
                kind: file_kind(&meta),
            });
        }
        Ok(_) if super::lock::path_being_written(output) => {
            return Err(RecoverError::BeingRecorded { file: out_name });
        }
        Ok(_) => match same_file(input, output) {
            false if existing == Existing::Refuse => {
                return Err(RecoverError::OutputExists { file: out_name });
            }
            same => same,
        },
        Err(_) => false,
    };
    let out = WholeFile::create(output)
        .map_err(|e| write_error(format!("{}: {e}", part_path(output).display())))?;
    let (recovery, out) = recover_source(&file, &source, out).map_err(|e| match e {
        RecoverError::Write { message, .. } => write_error(message),
        e => e,
    })?;
    if in_place && recovery.lost_more_than_a_tail() {
        // Dropping `out` removes the part file; the input stays as it is.
        return Err(RecoverError::WouldLose {
            file: file.clone(),
            what: lost(&recovery),
        });
    }
    out.commit().map_err(|e| write_error(e.to_string()))?;
    Ok(recovery)
}

/// What a recovery left out besides the unfinished tail, in words.
pub fn lost(recovery: &Recovery) -> String {
    let mut what = Vec::new();
    match recovery.damaged_chunks.len() {
        0 => {}
        1 => what.push(format!("a damaged chunk ({})", recovery.damaged_chunks[0])),
        n => what.push(format!(
            "{n} damaged chunks (the first: {})",
            recovery.damaged_chunks[0]
        )),
    }
    match recovery.damaged_spans.len() {
        0 => {}
        1 => what.push(format!("a damaged span ({})", recovery.damaged_spans[0])),
        n => what.push(format!(
            "{n} damaged spans (the first: {})",
            recovery.damaged_spans[0]
        )),
    }
    match recovery.orphaned_messages {
        0 => {}
        1 => what.push("a message of a channel declared only in a damaged chunk".into()),
        n => what.push(format!(
            "{n} messages of channels declared only in a damaged chunk"
        )),
    }
    if let Some(why) = &recovery.stopped_at {
        what.push(format!("{} bytes after {why}", recovery.bytes_dropped));
    }
    what.join(", ")
}

/// Recovers the recording held in `bytes` (named `file` in errors) onto `out`.
pub fn recover_bytes<W: Write + Seek>(
    file: &str,
    bytes: &[u8],
    out: W,
) -> Result<(Recovery, W), RecoverError> {
    recover_source(file, &Source::held(bytes.to_vec()), out)
}

/// Recovers the recording `source` (named `file` in errors) onto `out`; on an
/// error `out` holds a partial file, which the caller discards.
fn recover_source<W: Write + Seek>(
    file: &str,
    source: &Source,
    out: W,
) -> Result<(Recovery, W), RecoverError> {
    let size = source.len().map_err(|source| RecoverError::Read {
        file: file.into(),
        source,
    })?;
    let magic_len = MAGIC.len() as u64;
    let mut magic = [0u8; MAGIC.len()];
    if size < magic_len || source.read_exact_at(0, &mut magic).is_err() || magic != MAGIC {
        return Err(RecoverError::NotMcap { file: file.into() });
    }
    let mut recovery = Recovery {
        was_complete: size >= 2 * magic_len
            && source.read_exact_at(size - magic_len, &mut magic).is_ok()
            && magic == MAGIC,
        bytes_kept: magic_len,
        ..Recovery::default()
    };
    let write = |e: McapError| RecoverError::Write {
        file: file.into(),
        message: e.to_string(),
    };
    let mut out = Some(out);
    let mut writer: Option<mcap::Writer<W>> = None;
    let mut profile = String::new();
    let mut described = false;
    let mut known = Known::default();
    let summary = recovery
        .was_complete
        .then(|| intact_summary(source, size))
        .flatten();
    let mut at = magic_len;
    loop {
        // A chunk the checked summary indexes is framed by its index: the CRC of
        // its contents still decides whether it is kept.
        let indexed = summary.as_ref().and_then(|s| s.chunks.get(&at));
        let framed = match indexed {
            // Its length counts the opcode and length prefix, at least 9 bytes
            // (`intact_summary` keeps no shorter entry).
            Some(&length) => Ok(Framed {
                op: op::CHUNK,
                at,
                length: length - 9,
            }),
            None => match frame_at(source, at, size) {
                Ok(Some(f)) => Ok(f),
                Ok(None) => break,
                Err(e) => Err(format!("a record cut short at byte {at}: {e}")),
            },
        };
        let read = framed.and_then(|f| Ok((f, read_record(source, &f)?)));
        let (framed, record) = match read {
            Ok(read) => read,
            Err(e) => {
                // A damaged record whose length no longer frames what follows:
                // the index says where the next chunk starts.
                if let Some(next) = summary.as_ref().and_then(|s| s.next_chunk_after(at)) {
                    recovery
                        .damaged_spans
                        .push(format!("{e}, bytes {at}..{next}"));
                    at = next;
                    continue;
                }
                recovery.stopped_at = Some(e);
                break;
            }
        };
        if indexed.is_some() && framed_differently(source, &framed) {
            recovery.reframed_chunks += 1;
        }
        let end = framed.end();
        let kept: Vec<Record<'static>> = match record {
            Record::Header(h) => {
                profile = h.profile;
                Vec::new()
            }
            Record::Chunk { header, data } => match chunk_records(&header, &data) {
                Ok(records) => {
                    recovery.chunks += 1;
                    records
                }
                Err(e) => {
                    // The record framed whole: what follows it still frames.
                    recovery
                        .damaged_chunks
                        .push(format!("{e}, bytes {}..{end}", framed.at));
                    at = end;
                    continue;
                }
            },
            Record::DataEnd(_) | Record::Footer(_) => {
                recovery.bytes_kept = end;
                break;
            }
            r => vec![r],
        };
        for record in kept {
            let w = match &mut writer {
                Some(w) => w,
                None => writer.insert(
                    WriteOptions::new()
                        .profile(profile.clone())
                        .compression(Some(Compression::Zstd))
                        .compression_threads(0)
                        .create(out.take().expect("the output is taken once"))
                        .map_err(write)?,
                ),
            };
            described |= matches!(&record, Record::Metadata(m) if m.name == METADATA_NAME);
            match keep(w, &mut known, summary.as_ref(), record).map_err(write)? {
                Kept::Message => recovery.messages += 1,
                Kept::Orphan => recovery.orphaned_messages += 1,
                Kept::DamagedSchema(what) => recovery.damaged_schemas.push(what),
                Kept::Other => {}
            }
        }
        recovery.bytes_kept = end;
        at = end;
    }
    recovery.bytes_dropped = size - recovery.bytes_kept;
    if !described {
        return Err(RecoverError::NothingToRecover {
            file: file.into(),
            why: recovery
                .stopped_at
                .clone()
                .unwrap_or_else(|| format!("its end at byte {size}")),
        });
    }
    let mut writer = writer.expect("a metadata record was written");
    writer.finish().map_err(write)?;
    Ok((recovery, writer.into_inner()))
}

/// The schema and channel ids written so far: a record that refers to one
/// declared only in a damaged chunk is left out.
#[derive(Default)]
struct Known {
    schemas: HashSet<u16>,
    channels: HashSet<u16>,
}

/// What [`keep`] did with a record.
enum Kept {
    Message,
    /// A message (or a channel) whose channel (or schema) was never written.
    Orphan,
    /// A schema whose data was damaged, with what was done about it.
    DamagedSchema(String),
    Other,
}

/// A schema record's data, checked. Schema records are written outside chunks,
/// with no CRC, so damage to one would go unseen: laparo's own reader decodes
/// with the types it was built with, but a generic MCAP reader (Foxglove) decodes
/// each channel with its schema. A `protobuf` schema must decode as a
/// FileDescriptorSet that defines the message it names; one that does not is
/// replaced by this build's descriptors of that name when this build has them
/// (laparo's, foxglove's `SceneUpdate`) and kept as found otherwise. The second
/// value says which, for the report; `None` for a sound schema or another
/// encoding.
fn checked_schema<'a>(
    name: &str,
    encoding: &str,
    data: &'a [u8],
) -> (Cow<'a, [u8]>, Option<String>) {
    let defines = |data: &[u8]| {
        prost_reflect::DescriptorPool::decode(data)
            .is_ok_and(|pool| pool.get_message_by_name(name).is_some())
    };
    if encoding != "protobuf" || defines(data) {
        return (Cow::Borrowed(data), None);
    }
    let foxglove = SceneUpdate::get_schema().filter(|s| s.name == name);
    let own = match foxglove {
        Some(schema) => Some(schema.data.into_owned()),
        None => Some(laparo_proto::FILE_DESCRIPTOR_SET.to_vec()).filter(|d| defines(d)),
    };
    match own {
        Some(own) => (
            Cow::Owned(own),
            Some("its data does not define the message; written from this build's".into()),
        ),
        None => (
            Cow::Borrowed(data),
            Some(
                "its data does not define the message; kept as found (this build does not know it)"
                    .into(),
            ),
        ),
    }
}

/// Writes the records worth carrying over (schemas, channels with their ids,
/// messages, metadata); indexes and statistics are written anew. A schema or
/// channel the walk lost with a damaged span is written from the checked
/// `summary` when a record needs it; one already written is not written again.
fn keep<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    known: &mut Known,
    summary: Option<&IntactSummary>,
    record: Record<'_>,
) -> Result<Kept, McapError> {
    match record {
        Record::Schema { header, data } if !known.schemas.contains(&header.id) => {
            let (data, damage) = checked_schema(&header.name, &header.encoding, &data);
            writer.add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
            known.schemas.insert(header.id);
            if let Some(what) = damage {
                return Ok(Kept::DamagedSchema(format!(
                    "schema {} `{}`: {what}",
                    header.id, header.name
                )));
            }
        }
        Record::Channel(c) if !known.channels.contains(&c.id) => {
            add_channel(writer, known, summary, &c)?;
        }
        Record::Message { header, data } => {
            if !known_channel(writer, known, summary, header.channel_id)? {
                return Ok(Kept::Orphan);
            }
            writer.write_to_known_channel(&header, &data)?;
            return Ok(Kept::Message);
        }
        Record::Metadata(m) => writer.write_metadata(&m)?,
        _ => {}
    }
    Ok(Kept::Other)
}

/// Whether schema `id` is written (0, no schema, always is), writing it from
/// `summary` when only the summary still holds it.
fn known_schema<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    known: &mut Known,
    summary: Option<&IntactSummary>,
    id: u16,
) -> Result<bool, McapError> {
    if id == 0 || known.schemas.contains(&id) {
        return Ok(true);
    }
    let Some((header, data)) = summary.and_then(|s| s.schemas.get(&id)) else {
        return Ok(false);
    };
    let (data, _) = checked_schema(&header.name, &header.encoding, data);
    writer.add_schema_with_id(id, &header.name, &header.encoding, &data)?;
    known.schemas.insert(id);
    Ok(true)
}

/// Whether channel `id` is written, writing it (and its schema) from `summary`
/// when only the summary still holds it.
fn known_channel<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    known: &mut Known,
    summary: Option<&IntactSummary>,
    id: u16,
) -> Result<bool, McapError> {
    if known.channels.contains(&id) {
        return Ok(true);
    }
    let Some(c) = summary.and_then(|s| s.channels.get(&id)) else {
        return Ok(false);
    };
    add_channel(writer, known, summary, c)
}

/// Writes channel `c` when its schema is written (schema id 0: none needed), the
/// schema from `summary` if need be; whether it was written.
fn add_channel<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    known: &mut Known,
    summary: Option<&IntactSummary>,
    c: &Channel,
) -> Result<bool, McapError> {
    if !known_schema(writer, known, summary, c.schema_id)? {
        return Ok(false);
    }
    writer.add_channel_with_id(
        c.id,
        c.schema_id,
        &c.topic,
        &c.message_encoding,
        &c.metadata,
    )?;
    known.channels.insert(c.id);
    Ok(true)
}

/// Whether the file's own prefix of the chunk `framed` (framed by its index)
/// states another opcode or length: a damaged prefix the index stepped over.
fn framed_differently(source: &Source, framed: &Framed) -> bool {
    let mut prefix = [0u8; 9];
    source.read_exact_at(framed.at, &mut prefix).is_err()
        || prefix[0] != framed.op
        || prefix[1..9] != framed.length.to_le_bytes()
}
