//! Recovering the file a killed server leaves: a data section that stops anywhere,
//! possibly inside a chunk, with no summary and no footer.
//!
//! The file is read record by record; every record before the first that is cut
//! short or damaged is kept — a chunk only whole, when it decompresses completely
//! and its CRC matches — and the kept schemas, channels (with their ids), messages
//! (with their sequence numbers and times) and metadata are written anew, with a
//! summary, indexes and a footer. So at most what the recorder had not yet closed
//! into a chunk (the last second, see [`super::writer::FLUSH_INTERVAL`]) is lost.
//! A file with nothing recoverable (no `laparo.scene` metadata before the damage:
//! junk after the magic, a file cut inside its first chunk) is an error
//! ([`RecoverError::NothingToRecover`]), and no file is written.

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use mcap::records::{Channel, MessageHeader, Metadata, Record};
use mcap::{Compression, MAGIC, McapError, WriteOptions};

use super::METADATA_NAME;
use super::records::{Records, chunk_records};

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
    /// Nothing before the first record cut short or damaged says what the file
    /// records (its `laparo.scene` metadata record): a recovered file would be an
    /// empty MCAP file, so none is written.
    #[error(
        "{file} holds nothing recoverable: no `{METADATA_NAME}` record before {why}; \
         no file written"
    )]
    NothingToRecover { file: String, why: String },
}

/// One record worth keeping, owned.
enum Kept {
    Schema {
        id: u16,
        name: String,
        encoding: String,
        data: Vec<u8>,
    },
    Channel(Channel),
    Message {
        header: MessageHeader,
        data: Vec<u8>,
    },
    Metadata(Metadata),
}

/// Rewrites the recording `input` into a complete one at `output` (which may be
/// `input`: the new file is written beside it and renamed over it).
pub fn recover(input: &Path, output: &Path) -> Result<Recovery, RecoverError> {
    let file = input.display().to_string();
    let bytes = std::fs::read(input).map_err(|source| RecoverError::Read {
        file: file.clone(),
        source,
    })?;
    let out_name = output.display().to_string();
    let write_error = |message: String| RecoverError::Write {
        file: out_name.clone(),
        message,
    };
    let mut part = output.as_os_str().to_owned();
    part.push(".part");
    let part = std::path::PathBuf::from(part);
    let result = (|| {
        let out = File::create(&part).map_err(|e| write_error(e.to_string()))?;
        let (recovery, out) =
            recover_bytes(&file, &bytes, BufWriter::new(out)).map_err(|e| match e {
                RecoverError::Write { message, .. } => write_error(message),
                e => e,
            })?;
        let out = out
            .into_inner()
            .map_err(|e| write_error(e.into_error().to_string()))?;
        out.sync_all().map_err(|e| write_error(e.to_string()))?;
        std::fs::rename(&part, output).map_err(|e| write_error(e.to_string()))?;
        Ok(recovery)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&part);
    }
    result
}

/// Recovers the recording held in `bytes` (named `file` in errors) onto `out`.
pub fn recover_bytes<W: Write + Seek>(
    file: &str,
    bytes: &[u8],
    out: W,
) -> Result<(Recovery, W), RecoverError> {
    if !bytes.starts_with(MAGIC) {
        return Err(RecoverError::NotMcap { file: file.into() });
    }
    let mut recovery = Recovery {
        was_complete: bytes.len() >= 2 * MAGIC.len() && bytes.ends_with(MAGIC),
        ..Recovery::default()
    };
    let (profile, kept) = scan(bytes, &mut recovery);
    recovery.bytes_dropped = bytes.len() as u64 - recovery.bytes_kept;
    let described = kept
        .iter()
        .any(|k| matches!(k, Kept::Metadata(m) if m.name == METADATA_NAME));
    if !described {
        return Err(RecoverError::NothingToRecover {
            file: file.into(),
            why: recovery
                .stopped_at
                .clone()
                .unwrap_or_else(|| format!("its end at byte {}", bytes.len())),
        });
    }
    let write = |e: McapError| RecoverError::Write {
        file: file.into(),
        message: e.to_string(),
    };
    let mut writer = WriteOptions::new()
        .profile(profile)
        .compression(Some(Compression::Zstd))
        .compression_threads(0)
        .create(out)
        .map_err(write)?;
    for k in kept {
        match k {
            Kept::Schema {
                id,
                name,
                encoding,
                data,
            } => {
                writer
                    .add_schema_with_id(id, &name, &encoding, &data)
                    .map_err(write)?;
            }
            Kept::Channel(c) => {
                writer
                    .add_channel_with_id(
                        c.id,
                        c.schema_id,
                        &c.topic,
                        &c.message_encoding,
                        &c.metadata,
                    )
                    .map_err(write)?;
            }
            Kept::Message { header, data } => {
                writer
                    .write_to_known_channel(&header, &data)
                    .map_err(write)?;
                recovery.messages += 1;
            }
            Kept::Metadata(m) => writer.write_metadata(&m).map_err(write)?,
        }
    }
    writer.finish().map_err(write)?;
    Ok((recovery, writer.into_inner()))
}

/// Reads records until the data section ends or a record is cut short or
/// damaged; returns the header's profile and what to keep.
fn scan(bytes: &[u8], recovery: &mut Recovery) -> (String, Vec<Kept>) {
    let mut profile = String::new();
    let mut kept = Vec::new();
    recovery.bytes_kept = MAGIC.len() as u64;
    for record in Records::new(bytes) {
        let (end, record) = match record {
            Ok(r) => r,
            Err(e) => {
                recovery.stopped_at = Some(e);
                break;
            }
        };
        match record {
            Record::Header(h) => profile = h.profile,
            Record::Chunk { header, data } => match chunk_records(&header, &data) {
                Ok(records) => {
                    kept.extend(records.into_iter().filter_map(keep));
                    recovery.chunks += 1;
                }
                Err(e) => {
                    recovery.stopped_at = Some(format!("{e} (the chunk ending at byte {end})"));
                    break;
                }
            },
            Record::DataEnd(_) | Record::Footer(_) => {
                recovery.bytes_kept = end as u64;
                break;
            }
            r => kept.extend(keep(r)),
        }
        recovery.bytes_kept = end as u64;
    }
    (profile, kept)
}

/// The records worth carrying over; indexes and statistics are written anew.
fn keep(record: Record<'_>) -> Option<Kept> {
    match record {
        Record::Schema { header, data } => Some(Kept::Schema {
            id: header.id,
            name: header.name,
            encoding: header.encoding,
            data: data.into_owned(),
        }),
        Record::Channel(c) => Some(Kept::Channel(c)),
        Record::Message { header, data } => Some(Kept::Message {
            header,
            data: data.into_owned(),
        }),
        Record::Metadata(m) => Some(Kept::Metadata(m)),
        _ => None,
    }
}
