//! Walking an MCAP file record by record, trusting none of the lengths it states.
//!
//! A record is an opcode, a u64 length and a body; a chunk holds records
//! compressed. The mcap crate allocates whatever a chunk header or record claims,
//! so a damaged file could ask for exabytes: here each length is checked against
//! the bytes actually there, a chunk's uncompressed size is bounded by
//! [`MAX_CHUNK_BYTES`], a chunk is decompressed whole and its CRC checked before
//! any of its records is used, and each body is then parsed by the mcap crate.

use std::borrow::Cow;

use mcap::MAGIC;
use mcap::records::{ChunkHeader, Record};

/// Largest uncompressed chunk accepted. The recorder closes chunks near 1 MiB; a
/// single surface frame of a large mesh is a few MiB.
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// A record's opcode, body, and the offset just past it.
type Framed<'a> = (u8, &'a [u8], usize);

/// Splits `buf[at..]` into its first record's opcode and body, and where the next
/// record starts. `Ok(None)` at the end of `buf`.
fn frame(buf: &[u8], at: usize) -> Result<Option<Framed<'_>>, String> {
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

/// The top-level records of a file, after its start magic: each with the offset
/// just past it. Ends at the end of the bytes or at the first error.
pub struct Records<'a> {
    bytes: &'a [u8],
    at: usize,
    done: bool,
}

impl<'a> Records<'a> {
    /// `bytes` is a whole file, starting with the MCAP magic (checked by the caller).
    pub fn new(bytes: &'a [u8]) -> Self {
        Records {
            bytes,
            at: MAGIC.len().min(bytes.len()),
            done: false,
        }
    }

    /// The records of `bytes` (a whole file) from offset `at` on, e.g. a chunk an
    /// index points to; from an offset past the end there are none.
    pub fn at(bytes: &'a [u8], at: usize) -> Self {
        Records {
            bytes,
            at: at.min(bytes.len()),
            done: false,
        }
    }

    /// Where the next record starts.
    pub fn position(&self) -> usize {
        self.at
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Result<(usize, Record<'a>), String>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let result = match frame(self.bytes, self.at) {
            Ok(None) => None,
            Ok(Some((op, body, next))) => Some(
                mcap::parse_record(op, body)
                    .map(|r| (next, r))
                    .map_err(|e| format!("a damaged record at byte {}: {e}", self.at)),
            ),
            Err(e) => Some(Err(e)),
        };
        match &result {
            Some(Ok((next, _))) => self.at = *next,
            _ => self.done = true,
        }
        result
    }
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
