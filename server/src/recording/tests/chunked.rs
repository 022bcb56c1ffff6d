//! The chunked writer's files, read back by the mcap crate's own readers (linear,
//! and indexed through the summary this writer read back from its data section).

use std::io::Cursor;

use crate::recording::chunked::{ChunkedWriter, MAGIC};

/// A message as written: channel, sequence, log time, payload.
type Sent = (u16, u32, u64, Vec<u8>);

/// Messages on three channels over `chunks` chunks of `per_chunk` messages, with
/// a metadata record after the first chunk; the file and what was written.
fn written(chunks: u32, per_chunk: u32) -> (Vec<u8>, Vec<Sent>) {
    let mut w = ChunkedWriter::new(Cursor::new(Vec::new()), "protobuf").unwrap();
    let s1 = w.add_schema("a.A", "protobuf", b"schema a").unwrap();
    let s2 = w.add_schema("b.B", "jsonschema", b"{}").unwrap();
    let channels = [
        w.add_channel(s1, "/a", "protobuf").unwrap(),
        w.add_channel(s2, "/b", "json").unwrap(),
        w.add_channel(s1, "/c", "protobuf").unwrap(),
    ];
    let mut sent = Vec::new();
    let mut sequence = 0u32;
    for c in 0..chunks {
        for m in 0..per_chunk {
            // Channel /c only in even chunks; log times not monotonic within a chunk.
            let channel = channels[(m % if c % 2 == 0 { 3 } else { 2 }) as usize];
            let log_time = 1_000_000 + u64::from(c) * 1000 + u64::from((m * 7) % per_chunk);
            let payload: Vec<u8> = (0..(m % 40)).map(|k| (k * 31 + c) as u8).collect();
            w.write_message(channel, sequence, log_time, log_time + 5, &payload)
                .unwrap();
            sent.push((channel, sequence, log_time, payload));
            sequence += 1;
        }
        w.flush().unwrap();
        if c == 0 {
            w.write_metadata("laparo.scene", [("a", "1"), ("b", "two")])
                .unwrap();
        }
    }
    (w.finish().unwrap().into_inner(), sent)
}

#[test]
fn a_file_reads_back_linearly_message_for_message() {
    let (file, sent) = written(7, 50);
    assert_eq!(&file[..8], MAGIC);
    assert_eq!(&file[file.len() - 8..], MAGIC);
    let read: Vec<_> = mcap::MessageStream::new(&file)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.id, m.sequence, m.log_time, m.data.to_vec())
        })
        .collect();
    assert_eq!(read, sent);
}

#[test]
fn the_summary_read_back_from_the_data_section_indexes_every_chunk() {
    let (file, sent) = written(9, 40);
    let summary = mcap::Summary::read(&file).unwrap().expect("a summary");
    let stats = summary.stats.as_ref().expect("statistics");
    assert_eq!(stats.message_count, sent.len() as u64);
    assert_eq!(stats.chunk_count, 9);
    assert_eq!(stats.channel_count, 3);
    assert_eq!(stats.schema_count, 2);
    assert_eq!(stats.metadata_count, 1);
    assert_eq!(
        stats.message_start_time,
        sent.iter().map(|m| m.2).min().unwrap()
    );
    assert_eq!(
        stats.message_end_time,
        sent.iter().map(|m| m.2).max().unwrap()
    );
    for (id, n) in &stats.channel_message_counts {
        assert_eq!(*n, sent.iter().filter(|m| m.0 == *id).count() as u64);
    }
    assert_eq!(summary.channels.len(), 3);
    assert_eq!(summary.channels[&2].topic, "/b");
    assert_eq!(summary.channels[&2].schema.as_ref().unwrap().name, "b.B");
    // Every chunk through its index: its messages, its time bounds, and message
    // indexes that point at each of its messages.
    assert_eq!(summary.chunk_indexes.len(), 9);
    let mut through_index = Vec::new();
    for index in &summary.chunk_indexes {
        let messages: Vec<_> = summary
            .stream_chunk(&file, index)
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        let times = messages.iter().map(|m| m.log_time);
        assert_eq!(index.message_start_time, times.clone().min().unwrap());
        assert_eq!(index.message_end_time, times.max().unwrap());
        assert_eq!(index.compression, "zstd");
        let indexed = summary.read_message_indexes(&file, index).unwrap();
        let entries: usize = indexed.values().map(Vec::len).sum();
        assert_eq!(entries, messages.len());
        for (channel, entries) in &indexed {
            let on_channel: Vec<u64> = messages
                .iter()
                .filter(|m| m.channel.id == channel.id)
                .map(|m| m.log_time)
                .collect();
            let logged: Vec<u64> = entries.iter().map(|e| e.log_time).collect();
            assert_eq!(logged, on_channel, "channel {}", channel.topic);
        }
        through_index.extend(
            messages
                .into_iter()
                .map(|m| (m.channel.id, m.sequence, m.log_time, m.data.to_vec())),
        );
    }
    assert_eq!(through_index, sent);
    let meta = &summary.metadata_indexes;
    assert_eq!(meta.len(), 1);
    let m = mcap::read::metadata(&file, &meta[0]).unwrap();
    assert_eq!(m.name, "laparo.scene");
    assert_eq!(m.metadata["b"], "two");
}

#[test]
fn an_empty_file_and_a_dropped_writer_are_complete_files() {
    let w = ChunkedWriter::new(Cursor::new(Vec::new()), "protobuf").unwrap();
    let file = w.finish().unwrap().into_inner();
    let summary = mcap::Summary::read(&file).unwrap().expect("a summary");
    assert_eq!(summary.stats.unwrap().message_count, 0);
    assert!(summary.chunk_indexes.is_empty());

    // Dropped with a chunk open: the chunk is closed and the summary written.
    let mut buf = Vec::new();
    {
        let mut w = ChunkedWriter::new(Cursor::new(&mut buf), "protobuf").unwrap();
        let s = w.add_schema("a.A", "protobuf", b"").unwrap();
        let c = w.add_channel(s, "/a", "protobuf").unwrap();
        w.write_message(c, 0, 10, 10, b"kept").unwrap();
    }
    let summary = mcap::Summary::read(&buf).unwrap().expect("a summary");
    assert_eq!(summary.chunk_indexes.len(), 1);
    let m: Vec<_> = mcap::MessageStream::new(&buf).unwrap().collect();
    assert_eq!(&m[0].as_ref().unwrap().data[..], b"kept");
}

#[test]
fn a_message_on_an_unknown_channel_is_refused_and_writes_nothing() {
    let mut w = ChunkedWriter::new(Cursor::new(Vec::new()), "protobuf").unwrap();
    assert!(w.write_message(1, 0, 0, 0, b"x").is_err());
    assert!(w.write_message(0, 0, 0, 0, b"x").is_err());
    assert_eq!(w.open_bytes(), 0);
    let s = w.add_schema("a.A", "protobuf", b"").unwrap();
    for _ in 0..crate::recording::chunked::MAX_CHANNELS {
        w.add_channel(s, "/a", "protobuf").unwrap();
    }
    assert!(w.add_channel(s, "/a", "protobuf").is_err());
}

#[test]
fn the_summary_crc_covers_the_summary_and_the_footer_up_to_its_offsets() {
    let (bytes, _) = written(5, 30);
    // MCAP: the CRC-32 of every byte from `summary_start` through the footer's
    // `summary_offset_start`; computed (not the 0 of "not computed").
    let crc_at = bytes.len() - MAGIC.len() - 4;
    let stored = u32::from_le_bytes(bytes[crc_at..crc_at + 4].try_into().unwrap());
    let summary_start = u64::from_le_bytes(bytes[crc_at - 16..crc_at - 8].try_into().unwrap());
    assert_ne!(stored, 0);
    assert_eq!(
        stored,
        crc32fast::hash(&bytes[summary_start as usize..crc_at])
    );
}

/// Reads `bytes` with the mcap crate's linear reader (chunks whole), checking the
/// summary's CRC; the first error.
fn linear_read_checking_the_summary_crc(bytes: &[u8]) -> Result<(), mcap::McapError> {
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let options = LinearReaderOptions::default()
        .with_record_length_limit(bytes.len())
        .with_emit_chunks(true)
        .with_validate_summary_section_crc(true);
    let mut reader = LinearReader::new_with_options(options);
    let mut rest = bytes;
    while let Some(event) = reader.next_event() {
        if let LinearReadEvent::ReadRequest(need) = event? {
            let n = need.min(rest.len());
            reader.insert(n).copy_from_slice(&rest[..n]);
            reader.notify_read(n);
            rest = &rest[n..];
        }
    }
    Ok(())
}

#[test]
fn the_mcap_crate_checks_the_summary_crc_and_finds_it_right() {
    let (bytes, _) = written(5, 30);
    linear_read_checking_the_summary_crc(&bytes).unwrap();
    // One byte of the summary changed: the crate's reader refuses it.
    let crc_at = bytes.len() - MAGIC.len() - 4;
    let summary_start = u64::from_le_bytes(bytes[crc_at - 16..crc_at - 8].try_into().unwrap());
    let mut damaged = bytes.clone();
    damaged[summary_start as usize + 20] ^= 0x10;
    let e = linear_read_checking_the_summary_crc(&damaged).unwrap_err();
    assert!(matches!(e, mcap::McapError::BadSummaryCrc { .. }), "{e}");
}
