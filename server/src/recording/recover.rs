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

use mcap::records::Record;
use mcap::{Compression, MAGIC, McapError, WriteOptions};

use super::METADATA_NAME;
use super::records::{chunk_records, frame_at, read_record};
use super::source::{Follow, Source};

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

/// Rewrites the recording `input` into a complete one at `output` (which may be
/// `input`: the new file is written beside it and renamed over it).
///
/// The input is read a record at a time through a [`Source`] and each kept record
/// is written at once, so memory holds one chunk whatever the file's size.
pub fn recover(input: &Path, output: &Path) -> Result<Recovery, RecoverError> {
    let file = input.display().to_string();
    let source = Source::open(input, Follow::Links).map_err(|source| RecoverError::Read {
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
            recover_source(&file, &source, BufWriter::new(out)).map_err(|e| match e {
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
    let mut at = magic_len;
    loop {
        let framed = match frame_at(source, at, size) {
            Ok(Some(f)) => f,
            Ok(None) => break,
            Err(e) => {
                recovery.stopped_at = Some(format!("a record cut short at byte {at}: {e}"));
                break;
            }
        };
        let record = match read_record(source, &framed) {
            Ok(r) => r,
            Err(e) => {
                recovery.stopped_at = Some(e);
                break;
            }
        };
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
                    recovery.stopped_at = Some(format!("{e} (the chunk ending at byte {end})"));
                    break;
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
            if keep(w, record).map_err(write)? {
                recovery.messages += 1;
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

/// Writes the records worth carrying over (schemas, channels with their ids,
/// messages, metadata); indexes and statistics are written anew. True for a
/// message.
fn keep<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    record: Record<'_>,
) -> Result<bool, McapError> {
    match record {
        Record::Schema { header, data } => {
            writer.add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
        }
        Record::Channel(c) => {
            writer.add_channel_with_id(
                c.id,
                c.schema_id,
                &c.topic,
                &c.message_encoding,
                &c.metadata,
            )?;
        }
        Record::Message { header, data } => {
            writer.write_to_known_channel(&header, &data)?;
            return Ok(true);
        }
        Record::Metadata(m) => writer.write_metadata(&m)?,
        _ => {}
    }
    Ok(false)
}
