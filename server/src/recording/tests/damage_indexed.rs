//! Damage a finished file's own framing cannot step over: its checked summary
//! (chunk index, schemas, channels) frames what follows.

use super::*;
use mcap::records::ChunkIndex;

use crate::recording::chunked::MAGIC;
use crate::recording::recover::{Existing, recover};

/// A finished recording as written.
struct Finished {
    bytes: Vec<u8>,
    /// Every message, raw, in file order.
    all: Vec<(String, u64, Vec<u8>)>,
    /// Its chunk indexes, in file order.
    chunks: Vec<ChunkIndex>,
}

/// A finished recording of 24 ticks, a chunk closed every 4.
fn finished(dir: &Path) -> Finished {
    let full = dir.join("full.mcap");
    let (boundaries, bytes) = chunked(&full, 24, 4);
    let mut chunks = Recording::open(&full)
        .unwrap()
        .mcap_summary()
        .chunk_indexes
        .clone();
    chunks.sort_by_key(|c| c.chunk_start_offset);
    assert!(chunks.len() >= 4, "{}", chunks.len());
    // The session's description has a chunk of its own; then each flush closed
    // one chunk, which starts where the file ended before it.
    assert_eq!(chunks.len(), boundaries.len());
    for (chunk, before) in chunks[1..].iter().zip(&boundaries) {
        assert_eq!(chunk.chunk_start_offset, before.0);
    }
    Finished {
        bytes,
        all: raw_messages(&full),
        chunks,
    }
}

/// `bytes` with the u64 at `at` replaced by `value`.
fn with_u64(bytes: &[u8], at: u64, value: u64) -> Vec<u8> {
    let mut out = bytes.to_vec();
    out[at as usize..at as usize + 8].copy_from_slice(&value.to_le_bytes());
    out
}

#[test]
fn a_chunk_whose_length_is_damaged_is_framed_by_the_index_and_kept_whole() {
    let dir = temp();
    let Finished { bytes, all, chunks } = finished(dir.path());
    // The second chunk states a length 100 bytes short: its record ends inside
    // its own data, and nothing after it frames on its own.
    let chunk = &chunks[1];
    let damaged = with_u64(
        &bytes,
        chunk.chunk_start_offset + 1,
        chunk.chunk_length - 9 - 100,
    );
    // The footer's summary CRC is computed; files of earlier builds hold 0 there,
    // and their summary is used when its chunk index is consistent.
    let crc_at = bytes.len() - 8 - 4;
    assert_ne!(bytes[crc_at..crc_at + 4], [0; 4]);
    let mut no_crc = damaged.clone();
    no_crc[crc_at..crc_at + 4].fill(0);
    for damaged in [damaged, no_crc] {
        let path = dir.path().join("damaged.mcap");
        std::fs::write(&path, &damaged).unwrap();
        let out = dir.path().join("fixed.mcap");
        let _ = std::fs::remove_file(&out);
        let report = recover(&path, &out, Existing::Refuse).unwrap();
        assert_eq!(report.reframed_chunks, 1, "{report:?}");
        assert!(!report.lost_more_than_a_tail(), "{report:?}");
        assert_eq!(report.chunks as usize, chunks.len());
        // Every message, in order.
        assert_eq!(raw_messages(&out), all);
        assert!(Recording::open(&out).unwrap().is_complete());
    }
}

#[test]
fn a_record_whose_length_frames_nothing_is_stepped_over_to_the_next_chunk() {
    let dir = temp();
    let Finished { bytes, all, chunks } = finished(dir.path());
    // The first message index after the second chunk states a length past the
    // file's end: the walk cannot frame it, nor anything after it.
    let index_at = *chunks[1]
        .message_index_offsets
        .values()
        .min()
        .expect("the chunk has message indexes");
    let damaged = with_u64(&bytes, index_at + 1, u64::MAX / 2);
    let path = dir.path().join("damaged.mcap");
    std::fs::write(&path, &damaged).unwrap();
    let out = dir.path().join("fixed.mcap");
    let report = recover(&path, &out, Existing::Refuse).unwrap();
    assert_eq!(report.damaged_spans.len(), 1, "{report:?}");
    let span = format!("bytes {index_at}..{}", chunks[2].chunk_start_offset);
    assert!(report.damaged_spans[0].contains(&span), "{report:?}");
    assert!(report.stopped_at.is_none(), "{report:?}");
    // Message indexes are written anew: no message is lost.
    assert_eq!(raw_messages(&out), all);
    assert_eq!(report.orphaned_messages, 0);
    // In place it is refused all the same: the span was not read.
    let err = recover(&path, &path, Existing::Refuse).unwrap_err();
    assert!(err.to_string().contains("damaged span"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), damaged);
}

#[test]
fn a_channel_lost_with_a_damaged_span_comes_from_the_summary() {
    let dir = temp();
    let Finished { bytes, all, chunks } = finished(dir.path());
    // Schemas and channels are top-level records before the first chunk. The
    // last channel record states a length past the file's end: the span from it
    // to the first chunk is stepped over, and that channel's record with it.
    let mut at = MAGIC.len() as u64;
    let mut last_channel = None;
    while at < chunks[0].chunk_start_offset {
        let i = at as usize;
        if bytes[i] == mcap::records::op::CHANNEL {
            last_channel = Some(at);
        }
        at += 9 + u64::from_le_bytes(bytes[i + 1..i + 9].try_into().unwrap());
    }
    let channel_at = last_channel.expect("a channel record before the first chunk");
    let damaged = with_u64(&bytes, channel_at + 1, u64::MAX / 2);
    let path = dir.path().join("damaged.mcap");
    std::fs::write(&path, &damaged).unwrap();
    let out = dir.path().join("fixed.mcap");
    let report = recover(&path, &out, Existing::Refuse).unwrap();
    assert_eq!(report.damaged_spans.len(), 1, "{report:?}");
    // Its messages are not orphaned: the channel is written from the summary.
    assert_eq!(report.orphaned_messages, 0, "{report:?}");
    assert_eq!(raw_messages(&out), all);
}

#[test]
fn a_summary_that_fails_its_crc_is_not_trusted() {
    let dir = temp();
    let Finished { bytes, all, chunks } = finished(dir.path());
    // A damaged length, as above, and a summary whose bytes no longer match the
    // footer's CRC: the recovery stops at the damage, keeping what came before.
    let chunk = &chunks[1];
    let mut damaged = with_u64(
        &bytes,
        chunk.chunk_start_offset + 1,
        chunk.chunk_length - 9 - 100,
    );
    let footer_at = bytes.len() - 8 - 29;
    let summary_start =
        u64::from_le_bytes(bytes[footer_at + 9..footer_at + 17].try_into().unwrap()) as usize;
    damaged[summary_start + 20] ^= 0x01;
    let path = dir.path().join("damaged.mcap");
    std::fs::write(&path, &damaged).unwrap();
    let out = dir.path().join("fixed.mcap");
    let report = recover(&path, &out, Existing::Refuse).unwrap();
    assert_eq!(report.reframed_chunks, 0, "{report:?}");
    assert!(report.lost_more_than_a_tail(), "{report:?}");
    let kept = raw_messages(&out);
    assert!(!kept.is_empty() && kept.len() < all.len());
    assert_eq!(kept, all[..kept.len()]);
}
