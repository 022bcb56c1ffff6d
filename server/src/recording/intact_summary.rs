//! The summary section of a finished recording, read through its footer and
//! trusted only when the footer's CRC of it matches: where each chunk lies, and
//! every schema and channel. A recovery uses it to step over a damaged record
//! whose own length no longer frames what follows ([`mod@super::recover`]).
//!
//! The footer is the 29-byte record before the closing magic: opcode `0x02`,
//! length 20, `summary_start` (u64), `summary_offset_start` (u64) and
//! `summary_crc` (u32), the CRC-32 of every byte from `summary_start` up to and
//! including `summary_offset_start`. A zero CRC means "not computed" (laparo's
//! writer computes it since the recovery has used it; earlier files hold 0):
//! such a summary is used only when it parses whole and its chunk index is
//! consistent, each chunk inside the data section and after the one before. A
//! chunk it frames wrongly still fails its own CRC, so it costs no wrong data.

use std::collections::{BTreeMap, HashMap};

use mcap::MAGIC;
use mcap::records::{Channel, Record, SchemaHeader, op};

use super::reader::{FOOTER_AND_MAGIC, MAX_SUMMARY_BYTES};
use super::records::{frame, parse_one};
use super::source::Source;

/// Bytes of the footer record: opcode, length, two offsets and the CRC.
const FOOTER_BYTES: usize = FOOTER_AND_MAGIC as usize - MAGIC.len();

/// What a CRC-checked summary section says about its file.
#[derive(Debug, Default)]
pub struct IntactSummary {
    /// Each chunk record's first byte → its whole length (opcode and length
    /// prefix included), from the chunk indexes.
    pub chunks: BTreeMap<u64, u64>,
    /// Every schema by id, with its data.
    pub schemas: HashMap<u16, (SchemaHeader, Vec<u8>)>,
    /// Every channel by id.
    pub channels: HashMap<u16, Channel>,
}

impl IntactSummary {
    /// The first chunk that starts after byte `at`, and where.
    pub fn next_chunk_after(&self, at: u64) -> Option<u64> {
        self.chunks.range(at + 1..).next().map(|(&start, _)| start)
    }
}

/// The summary of `source` (of `size` bytes), when it ends with a footer whose
/// CRC matches its summary section and the section parses whole; `None` for a
/// file without one (cut short, still being written) or whose summary is damaged.
pub fn intact_summary(source: &Source, size: u64) -> Option<IntactSummary> {
    let magic = MAGIC.len() as u64;
    let footer_at = size.checked_sub(FOOTER_AND_MAGIC)?;
    let mut footer = [0u8; FOOTER_BYTES];
    source.read_exact_at(footer_at, &mut footer).ok()?;
    let u64_at = |i: usize| u64::from_le_bytes(footer[i..i + 8].try_into().expect("8 bytes"));
    if footer[0] != op::FOOTER || u64_at(1) != FOOTER_BYTES as u64 - 9 {
        return None;
    }
    let (start, crc) = (
        u64_at(9),
        u32::from_le_bytes(footer[25..29].try_into().expect("4 bytes")),
    );
    if start < magic || start >= footer_at {
        return None;
    }
    // The section and the footer's first 25 bytes, as the CRC covers them.
    let mut covered = source
        .read_at(start, footer_at - start, MAX_SUMMARY_BYTES)
        .ok()?;
    covered.extend_from_slice(&footer[..25]);
    if crc != 0 && crc32fast::hash(&covered) != crc {
        return None;
    }
    let section = &covered[..(footer_at - start) as usize];
    let mut summary = IntactSummary::default();
    let mut at = 0;
    while let Some((_, _, next)) = frame(section, at).ok()? {
        match parse_one(&section[at..next], start + at as u64).ok()? {
            Record::ChunkIndex(c) => {
                summary.chunks.insert(c.chunk_start_offset, c.chunk_length);
            }
            Record::Schema { header, data } => {
                summary
                    .schemas
                    .insert(header.id, (header, data.into_owned()));
            }
            Record::Channel(c) => {
                summary.channels.insert(c.id, c);
            }
            _ => {}
        }
        at = next;
    }
    // Each chunk inside the data section, after the one before it.
    let mut end = magic;
    for (&chunk, &length) in &summary.chunks {
        if chunk < end || length < 9 {
            return None;
        }
        end = chunk.checked_add(length)?;
    }
    (end <= start).then_some(summary)
}
