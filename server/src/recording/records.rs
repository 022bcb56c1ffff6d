//! Walking an MCAP file record by record, trusting none of the lengths it states.
//!
//! A record is an opcode, a u64 length and a body; a chunk holds records
//! compressed. The mcap crate allocates whatever a chunk header or record claims,
//! so a damaged file could ask for exabytes: here each length is checked against
//! the bytes actually there, a chunk's uncompressed size is bounded by
//! [`MAX_CHUNK_BYTES`], a chunk is decompressed whole and its CRC checked before
//! any of its records is used, and each body is then parsed by the mcap crate.
//!
//! The walk: [`frame_at`] / [`read_record`] over a [`Source`], a record at a
//! time, where a record's body is read only when the caller wants it (a listing
//! skips the compressed data of every chunk but the few it needs; a recovery
//! holds one chunk at a time).

use std::borrow::Cow;

use mcap::records::{ChunkHeader, Record};

use super::source::{Source, SourceError};

/// Largest uncompressed chunk accepted. The recorder closes chunks near 1 MiB; a
/// single surface frame of a large mesh is a few MiB.
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// Largest record body read from a file: a chunk of [`MAX_CHUNK_BYTES`] that did
/// not compress (zstd's bound is n + n/256 + a little; n/128 covers it) and its
/// header. Every other record of a recording (the scene's metadata, a schema) is
/// far smaller.
pub const MAX_RECORD_BYTES: u64 = MAX_CHUNK_BYTES + (MAX_CHUNK_BYTES >> 7) + 4096;

/// Bytes of a record's opcode and length.
const PREFIX: u64 = 9;

/// Where a record of a file is: its opcode, where it starts, its body's length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Framed {
    pub op: u8,
    pub at: u64,
    pub length: u64,
}

impl Framed {
    /// Where the next record starts.
    pub fn end(&self) -> u64 {
        self.at + PREFIX + self.length
    }
}

/// The record of `source` at byte `at`, from its 9-byte prefix alone; `Ok(None)`
/// at `end`. The whole record must lie before `end` (a file's size, or the end of
/// its data section): a record cut short or stating a length past it is an error
/// ([`SourceError::Short`]), its body unread.
pub fn frame_at(source: &Source, at: u64, end: u64) -> Result<Option<Framed>, SourceError> {
    if at >= end {
        return Ok(None);
    }
    let short = |length| SourceError::Short {
        at,
        length,
        size: end,
    };
    if end - at < PREFIX {
        return Err(short(PREFIX));
    }
    let mut prefix = [0u8; PREFIX as usize];
    source.read_exact_at(at, &mut prefix)?;
    let length = u64::from_le_bytes(prefix[1..9].try_into().expect("8 bytes"));
    let framed = Framed {
        op: prefix[0],
        at,
        length,
    };
    match at.checked_add(PREFIX).and_then(|b| b.checked_add(length)) {
        Some(e) if e <= end => Ok(Some(framed)),
        _ => Err(short(length.saturating_add(PREFIX))),
    }
}

/// The record `framed` locates, read (at most [`MAX_RECORD_BYTES`]) and parsed.
pub fn read_record(source: &Source, framed: &Framed) -> Result<Record<'static>, String> {
    let body = source
        .read_at(framed.at + PREFIX, framed.length, MAX_RECORD_BYTES)
        .map_err(|e| e.to_string())?;
    mcap::parse_record(framed.op, &body)
        .map(Record::into_owned)
        .map_err(|e| format!("a damaged record at byte {}: {e}", framed.at))
}

/// The one record `bytes` holds (a record an index points to, at byte `at` of the
/// file: errors name that offset), parsed.
pub fn parse_one(bytes: &[u8], at: u64) -> Result<Record<'static>, String> {
    match frame(bytes, 0) {
        Ok(Some((op, body, next))) if next == bytes.len() => mcap::parse_record(op, body)
            .map(Record::into_owned)
            .map_err(|e| format!("a damaged record at byte {at}: {e}")),
        Ok(_) => Err(format!(
            "an index points at bytes that are not one record (at byte {at})"
        )),
        Err(_) => Err(format!(
            "the record an index points at (byte {at}) states a length past the bytes indexed"
        )),
    }
}

/// A record's opcode, body, and the offset just past it.
type Split<'a> = (u8, &'a [u8], usize);

/// Splits `buf[at..]` into its first record's opcode and body, and where the next
/// record starts. `Ok(None)` at the end of `buf`.
pub(super) fn frame(buf: &[u8], at: usize) -> Result<Option<Split<'_>>, String> {
    let rest = &buf[at..];
    if rest.is_empty() {
        return Ok(None);
    }
    if rest.len() < 9 {
        return Err(format!("a record cut short at byte {at}"));
    }
    let length = u64::from_le_bytes(rest[1..9].try_into().expect("8 bytes"));
    let body = usize::try_from(length)
        .ok()
        .and_then(|n| rest.get(9..9usize.checked_add(n)?))
        .ok_or_else(|| format!("a record cut short at byte {at}"))?;
    Ok(Some((rest[0], body, at + 9 + body.len())))
}

/// The records of a chunk, all or none: decompressed within bounds, CRC checked.
pub fn chunk_records(header: &ChunkHeader, data: &[u8]) -> Result<Vec<Record<'static>>, String> {
    if header.uncompressed_size > MAX_CHUNK_BYTES {
        return Err(format!(
            "a chunk claims {} bytes uncompressed (at most {MAX_CHUNK_BYTES} accepted)",
            header.uncompressed_size
        ));
    }
    let size = header.uncompressed_size as usize;
    let plain: Cow<'_, [u8]> = match header.compression.as_str() {
        "" => Cow::Borrowed(data),
        "zstd" => Cow::Owned(
            zstd::bulk::decompress(data, size)
                .map_err(|e| format!("a chunk does not decompress: {e}"))?,
        ),
        other => return Err(format!("a chunk compressed with `{other}`, not supported")),
    };
    if plain.len() != size {
        return Err(format!(
            "a chunk decompresses to {} bytes, not the {size} it states",
            plain.len()
        ));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(&plain);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "a chunk fails its CRC ({crc:08x}, stated {:08x})",
                header.uncompressed_crc
            ));
        }
    }
    let mut out = Vec::new();
    let mut at = 0;
    while let Some((op, body, next)) = frame(&plain, at)? {
        let record = mcap::parse_record(op, body)
            .map_err(|e| format!("a damaged record in a chunk: {e}"))?;
        out.push(record.into_owned());
        at = next;
    }
    Ok(out)
}
