//! An MCAP writer whose memory does not grow with the recording.
//!
//! The mcap crate's `Writer` keeps every closed chunk's index entry (times,
//! offsets, a map of message-index offsets, the compression's name: about 600
//! bytes once allocated) until `finish` writes the summary. A recorder closes a
//! chunk every [`super::writer::FLUSH_INTERVAL`] so that a killed server loses at
//! most the last second; at two chunks a second that is about 4 MiB an hour per
//! session, growing as long as the session records. This writer holds only the
//! open chunk, the file's schemas and channels, and fixed counters; at
//! [`ChunkedWriter::finish`] it reads the chunk index back from the file itself
//! (each chunk's header and the message-index records after it) and writes it
//! into the summary, a chunk at a time.
//!
//! The file is plain MCAP (the format's specification, version 0), read here by
//! the mcap crate's own reader in the tests:
//!
//! ```text
//! magic, Header,
//! data section: Schema, Channel (top level, as added), Metadata (top level,
//!   closing any open chunk first), Chunk (zstd; its records are Message records)
//!   followed by one Message Index per channel it holds, …, Data End,
//! summary: Schema…, Channel…, Statistics, Metadata Index…, Chunk Index…,
//!   Summary Offset…, Footer, magic.
//! ```
//!
//! Every record is an opcode (u8), a body length (u64) and the body; integers are
//! little-endian, a string is a u32 length and UTF-8 bytes, a map a u32 byte
//! length and its pairs. A chunk's CRC is the CRC-32 of its uncompressed records;
//! the data section's CRC is written as 0, which the format defines as "not
//! computed"; the summary's is computed, so that a recovery can trust the chunk
//! index of a file damaged later ([`super::intact_summary`]).

use std::io::{self, Read, Seek, SeekFrom, Write};

use mcap::records::op;

/// The format's magic, at both ends of the file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Most channels a file may have: the recording has six. Ids are 1-based, as the
/// mcap crate numbers them.
pub const MAX_CHANNELS: usize = 16;

/// zstd level of the chunks: the format's and zstd's default.
const ZSTD_LEVEL: i32 = 3;

/// A schema or channel record kept for the summary.
struct Kept {
    op: u8,
    body: Vec<u8>,
}

/// What a metadata record's index says: where it is and its name.
struct MetadataAt {
    offset: u64,
    length: u64,
    name: String,
}

/// The open chunk.
#[derive(Default)]
struct OpenChunk {
    /// Its Message records, uncompressed.
    records: Vec<u8>,
    /// Per channel id: `(log_time, offset in records)` of each message.
    index: Vec<Vec<(u64, u64)>>,
    start: u64,
    end: u64,
    messages: u64,
}

/// Writes one MCAP file to `W`; see the module documentation.
pub struct ChunkedWriter<W: Read + Write + Seek> {
    /// `None` once finished.
    w: Option<W>,
    /// Bytes written so far: the position of the next record.
    at: u64,
    kept: Vec<Kept>,
    schemas: u16,
    channels: u32,
    metadata: Vec<MetadataAt>,
    chunk: OpenChunk,
    compressor: zstd::bulk::Compressor<'static>,
    /// The closed chunk being written: reused.
    out: Vec<u8>,
    chunks: u32,
    message_count: u64,
    /// Messages per channel id.
    per_channel: [u64; MAX_CHANNELS + 1],
    /// Log times of the file's first and last message; `None` before any.
    bounds: Option<(u64, u64)>,
    /// A write failed: the file is left as it is and every later call fails.
    failed: bool,
    /// The stream was moved off the end by a read back (at finish).
    displaced: bool,
    /// The CRC of the summary section so far, from its first byte (`None` before
    /// it): written in the footer, so that a recovery can trust the chunk index.
    summary_crc: Option<crc32fast::Hasher>,
}

fn put_str(b: &mut Vec<u8>, s: &str) {
    b.extend_from_slice(&(s.len() as u32).to_le_bytes());
    b.extend_from_slice(s.as_bytes());
}

fn put_record(b: &mut Vec<u8>, op: u8, body: &[u8]) {
    b.push(op);
    b.extend_from_slice(&(body.len() as u64).to_le_bytes());
    b.extend_from_slice(body);
}

fn invalid(message: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message.to_string())
}

fn corrupt(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

impl<W: Read + Write + Seek> ChunkedWriter<W> {
    /// Starts a file on `w` (positioned at its start): magic and header.
    pub fn new(mut w: W, profile: &str) -> io::Result<Self> {
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        let mut body = Vec::new();
        put_str(&mut body, profile);
        put_str(&mut body, concat!("laparo ", env!("CARGO_PKG_VERSION")));
        put_record(&mut b, op::HEADER, &body);
        w.write_all(&b)?;
        Ok(ChunkedWriter {
            w: Some(w),
            at: b.len() as u64,
            kept: Vec::new(),
            schemas: 0,
            channels: 0,
            metadata: Vec::new(),
            chunk: OpenChunk {
                index: vec![Vec::new(); MAX_CHANNELS + 1],
                ..OpenChunk::default()
            },
            compressor: zstd::bulk::Compressor::new(ZSTD_LEVEL)?,
            out: Vec::new(),
            chunks: 0,
            message_count: 0,
            per_channel: [0; MAX_CHANNELS + 1],
            bounds: None,
            failed: false,
            displaced: false,
            summary_crc: None,
        })
    }

    /// Writes `bytes` at the end of the file; a failure poisons the writer.
    fn emit(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.failed {
            return Err(io::Error::other("an earlier write to the recording failed"));
        }
        let at = self.at;
        let displaced = std::mem::take(&mut self.displaced);
        let w = self.w()?;
        let written = match displaced {
            true => w.seek(SeekFrom::Start(at)).and_then(|_| w.write_all(bytes)),
            false => w.write_all(bytes),
        };
        if let Err(e) = written {
            self.failed = true;
            return Err(e);
        }
        self.at += bytes.len() as u64;
        if let Some(crc) = &mut self.summary_crc {
            crc.update(bytes);
        }
        Ok(())
    }

    fn w(&mut self) -> io::Result<&mut W> {
        self.w
            .as_mut()
            .ok_or_else(|| io::Error::other("the recording was finished"))
    }

    /// Writes a top-level record and keeps it for the summary.
    fn keep(&mut self, op: u8, body: Vec<u8>) -> io::Result<()> {
        let mut b = Vec::with_capacity(body.len() + 9);
        put_record(&mut b, op, &body);
        self.emit(&b)?;
        self.kept.push(Kept { op, body });
        Ok(())
    }

    /// Adds a schema; its id (1, 2, …).
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        let id = self
            .schemas
            .checked_add(1)
            .ok_or_else(|| invalid("too many schemas"))?;
        let mut body = Vec::new();
        body.extend_from_slice(&id.to_le_bytes());
        put_str(&mut body, name);
        put_str(&mut body, encoding);
        body.extend_from_slice(&(data.len() as u32).to_le_bytes());
        body.extend_from_slice(data);
        self.keep(op::SCHEMA, body)?;
        self.schemas = id;
        Ok(id)
    }

    /// Adds a channel of `schema` without metadata; its id (1, 2, …, at most
    /// [`MAX_CHANNELS`]).
    pub fn add_channel(&mut self, schema: u16, topic: &str, encoding: &str) -> io::Result<u16> {
        if self.channels as usize >= MAX_CHANNELS {
            return Err(invalid("too many channels"));
        }
        let id = self.channels as u16 + 1;
        let mut body = Vec::new();
        body.extend_from_slice(&id.to_le_bytes());
        body.extend_from_slice(&schema.to_le_bytes());
        put_str(&mut body, topic);
        put_str(&mut body, encoding);
        body.extend_from_slice(&0u32.to_le_bytes());
        self.keep(op::CHANNEL, body)?;
        self.channels = u32::from(id);
        Ok(id)
    }

    /// Writes a metadata record (top level: an open chunk is closed first).
    pub fn write_metadata<'a>(
        &mut self,
        name: &str,
        pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> io::Result<()> {
        self.close_chunk()?;
        let mut map = Vec::new();
        for (k, v) in pairs {
            put_str(&mut map, k);
            put_str(&mut map, v);
        }
        let mut body = Vec::new();
        put_str(&mut body, name);
        body.extend_from_slice(&(map.len() as u32).to_le_bytes());
        body.extend_from_slice(&map);
        let mut b = Vec::with_capacity(body.len() + 9);
        put_record(&mut b, op::METADATA, &body);
        let offset = self.at;
        self.emit(&b)?;
        self.metadata.push(MetadataAt {
            offset,
            length: b.len() as u64,
            name: name.to_string(),
        });
        Ok(())
    }

    /// Adds a message to the open chunk (opening one if none is).
    pub fn write_message(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        data: &[u8],
    ) -> io::Result<()> {
        if channel == 0 || u32::from(channel) > self.channels {
            return Err(invalid("a message on a channel that was not added"));
        }
        let c = &mut self.chunk;
        let offset = c.records.len() as u64;
        c.records.push(op::MESSAGE);
        c.records
            .extend_from_slice(&((2 + 4 + 8 + 8 + data.len()) as u64).to_le_bytes());
        c.records.extend_from_slice(&channel.to_le_bytes());
        c.records.extend_from_slice(&sequence.to_le_bytes());
        c.records.extend_from_slice(&log_time.to_le_bytes());
        c.records.extend_from_slice(&publish_time.to_le_bytes());
        c.records.extend_from_slice(data);
        c.index[channel as usize].push((log_time, offset));
        if c.messages == 0 {
            (c.start, c.end) = (log_time, log_time);
        }
        c.start = c.start.min(log_time);
        c.end = c.end.max(log_time);
        c.messages += 1;
        self.per_channel[channel as usize] += 1;
        self.message_count += 1;
        self.bounds = Some(match self.bounds {
            None => (log_time, log_time),
            Some((a, b)) => (a.min(log_time), b.max(log_time)),
        });
        Ok(())
    }

    /// Bytes in the open chunk, uncompressed.
    pub fn open_bytes(&self) -> usize {
        self.chunk.records.len()
    }

    /// Compresses the open chunk and writes it, followed by its message indexes;
    /// nothing when no chunk is open.
    pub fn close_chunk(&mut self) -> io::Result<()> {
        if self.chunk.messages == 0 {
            return Ok(());
        }
        let c = &mut self.chunk;
        let crc = crc32fast::hash(&c.records);
        let out = &mut self.out;
        out.clear();
        // Chunk header: times, sizes, CRC, compression, then the records' length.
        let mut head = [0u8; 8 + 8 + 8 + 4 + 4 + 4 + 8];
        head[0..8].copy_from_slice(&c.start.to_le_bytes());
        head[8..16].copy_from_slice(&c.end.to_le_bytes());
        head[16..24].copy_from_slice(&(c.records.len() as u64).to_le_bytes());
        head[24..28].copy_from_slice(&crc.to_le_bytes());
        head[28..32].copy_from_slice(&4u32.to_le_bytes());
        head[32..36].copy_from_slice(b"zstd");
        let bound = zstd::zstd_safe::compress_bound(c.records.len());
        out.resize(9 + head.len() + bound, 0);
        let compressed = self
            .compressor
            .compress_to_buffer(&c.records, &mut out[9 + head.len()..])?;
        out.truncate(9 + head.len() + compressed);
        head[36..44].copy_from_slice(&(compressed as u64).to_le_bytes());
        out[0] = op::CHUNK;
        out[1..9].copy_from_slice(&((head.len() + compressed) as u64).to_le_bytes());
        out[9..9 + head.len()].copy_from_slice(&head);
        // One Message Index per channel with messages in the chunk, in id order.
        for (id, entries) in c.index.iter_mut().enumerate() {
            if entries.is_empty() {
                continue;
            }
            out.push(op::MESSAGE_INDEX);
            out.extend_from_slice(&((2 + 4 + 16 * entries.len()) as u64).to_le_bytes());
            out.extend_from_slice(&(id as u16).to_le_bytes());
            out.extend_from_slice(&((16 * entries.len()) as u32).to_le_bytes());
            for (time, offset) in entries.drain(..) {
                out.extend_from_slice(&time.to_le_bytes());
                out.extend_from_slice(&offset.to_le_bytes());
            }
        }
        c.records.clear();
        c.messages = 0;
        let out = std::mem::take(&mut self.out);
        let written = self.emit(&out);
        self.out = out;
        written?;
        self.chunks += 1;
        Ok(())
    }

    /// Flushes what was written to the stream (after closing the open chunk).
    pub fn flush(&mut self) -> io::Result<()> {
        self.close_chunk()?;
        self.w()?.flush()
    }

    /// Closes the open chunk, writes Data End, the summary and the footer, and
    /// hands back the stream. The chunk index is read back from the file's data
    /// section (see the module documentation), so memory stays what it was.
    pub fn finish(mut self) -> io::Result<W> {
        self.write_summary()?;
        self.w()?.flush()?;
        self.w
            .take()
            .ok_or_else(|| io::Error::other("the recording was finished"))
    }

    /// Writes the summary once: a failure part-way leaves the file without a
    /// footer (recoverable) and poisons the writer, so nothing is written twice.
    fn write_summary(&mut self) -> io::Result<()> {
        let written = self.summary();
        if written.is_err() {
            self.failed = true;
        }
        written
    }

    fn summary(&mut self) -> io::Result<()> {
        self.close_chunk()?;
        let data_end = {
            let mut b = Vec::new();
            put_record(&mut b, op::DATA_END, &0u32.to_le_bytes());
            b
        };
        self.emit(&data_end)?;
        let data_end_at = self.at - data_end.len() as u64;
        let summary_start = self.at;
        self.summary_crc = Some(crc32fast::Hasher::new());
        let mut groups: Vec<(u8, u64, u64)> = Vec::new();
        let mut b = Vec::new();
        // Schemas, then channels, as they were added.
        for wanted in [op::SCHEMA, op::CHANNEL] {
            let start = self.at + b.len() as u64;
            for k in self.kept.iter().filter(|k| k.op == wanted) {
                put_record(&mut b, k.op, &k.body);
            }
            let end = self.at + b.len() as u64;
            if end > start {
                groups.push((wanted, start, end - start));
            }
        }
        // Statistics.
        {
            let start = self.at + b.len() as u64;
            let (first, last) = self.bounds.unwrap_or((0, 0));
            let mut body = Vec::new();
            body.extend_from_slice(&self.message_count.to_le_bytes());
            body.extend_from_slice(&self.schemas.to_le_bytes());
            body.extend_from_slice(&self.channels.to_le_bytes());
            body.extend_from_slice(&0u32.to_le_bytes()); // attachments
            body.extend_from_slice(&(self.metadata.len() as u32).to_le_bytes());
            body.extend_from_slice(&self.chunks.to_le_bytes());
            body.extend_from_slice(&first.to_le_bytes());
            body.extend_from_slice(&last.to_le_bytes());
            let counted: Vec<(u16, u64)> = (1..=self.channels as u16)
                .map(|id| (id, self.per_channel[id as usize]))
                .filter(|&(_, n)| n > 0)
                .collect();
            body.extend_from_slice(&((10 * counted.len()) as u32).to_le_bytes());
            for (id, n) in counted {
                body.extend_from_slice(&id.to_le_bytes());
                body.extend_from_slice(&n.to_le_bytes());
            }
            put_record(&mut b, op::STATISTICS, &body);
            groups.push((op::STATISTICS, start, self.at + b.len() as u64 - start));
        }
        // Metadata indexes.
        if !self.metadata.is_empty() {
            let start = self.at + b.len() as u64;
            for m in &self.metadata {
                let mut body = Vec::new();
                body.extend_from_slice(&m.offset.to_le_bytes());
                body.extend_from_slice(&m.length.to_le_bytes());
                put_str(&mut body, &m.name);
                put_record(&mut b, op::METADATA_INDEX, &body);
            }
            groups.push((op::METADATA_INDEX, start, self.at + b.len() as u64 - start));
        }
        self.emit(&b)?;
        // Chunk indexes, read back from the data section a record at a time.
        if self.chunks > 0 {
            let start = self.at;
            let mut scan = MAGIC.len() as u64;
            let mut pending: Option<ChunkAt> = None;
            let mut indexes = Vec::new();
            let mut written = 0u32;
            while scan < data_end_at {
                let w = self.window_at(scan, data_end_at)?;
                let length = w.u64(1)?;
                match w.op()? {
                    op::CHUNK => {
                        if let Some(c) = pending.replace(ChunkAt::read(&w, scan, length)?) {
                            c.put_index(&mut indexes);
                            written += 1;
                        }
                    }
                    op::MESSAGE_INDEX => {
                        let Some(c) = pending.as_mut() else {
                            return Err(corrupt(format!(
                                "a message index at byte {scan} follows no chunk"
                            )));
                        };
                        c.index_offsets.push((w.u16(9)?, scan));
                        c.index_length += 9 + length;
                    }
                    _ => {
                        if let Some(c) = pending.take() {
                            c.put_index(&mut indexes);
                            written += 1;
                        }
                    }
                }
                if indexes.len() >= 1 << 16 {
                    self.emit(&indexes)?;
                    indexes.clear();
                }
                scan += 9 + length;
            }
            if let Some(c) = pending.take() {
                c.put_index(&mut indexes);
                written += 1;
            }
            self.emit(&indexes)?;
            if written != self.chunks {
                return Err(corrupt(format!(
                    "the data section holds {written} chunks, {} were written",
                    self.chunks
                )));
            }
            groups.push((op::CHUNK_INDEX, start, self.at - start));
        }
        // Summary offsets and footer.
        let offsets_start = self.at;
        let mut b = Vec::new();
        for (group, start, length) in groups {
            let mut body = Vec::with_capacity(17);
            body.push(group);
            body.extend_from_slice(&start.to_le_bytes());
            body.extend_from_slice(&length.to_le_bytes());
            put_record(&mut b, op::SUMMARY_OFFSET, &body);
        }
        // The footer: its CRC covers the summary up to and including
        // `summary_offset_start`, so it is written field by field.
        b.push(op::FOOTER);
        b.extend_from_slice(&20u64.to_le_bytes());
        b.extend_from_slice(&summary_start.to_le_bytes());
        b.extend_from_slice(&offsets_start.to_le_bytes());
        let mut crc = self
            .summary_crc
            .take()
            .expect("set where the summary starts");
        crc.update(&b);
        let crc = crc.finalize();
        b.extend_from_slice(&crc.to_le_bytes());
        b.extend_from_slice(MAGIC);
        self.emit(&b)
    }

    /// Up to [`Window::BYTES`] bytes of the data section from `at` (before
    /// `end`); the next [`Self::emit`] goes back to the end of the file.
    fn window_at(&mut self, at: u64, end: u64) -> io::Result<Window> {
        let mut w = Window {
            bytes: [0; Window::BYTES],
            len: (end - at).min(Window::BYTES as u64) as usize,
            at,
        };
        self.displaced = true;
        let stream = self.w()?;
        stream.flush()?;
        stream.seek(SeekFrom::Start(at))?;
        stream.read_exact(&mut w.bytes[..w.len])?;
        Ok(w)
    }
}

/// A writer dropped unfinished finishes its file, as the mcap crate's does, unless
/// a write already failed: a recording stays readable whatever path ends it.
impl<W: Read + Write + Seek> Drop for ChunkedWriter<W> {
    fn drop(&mut self) {
        if self.w.is_some() && !self.failed {
            let _ = self.write_summary();
            if let Some(w) = self.w.as_mut() {
                let _ = w.flush();
            }
        }
    }
}

/// The first bytes of a record of the data section: its prefix and enough of its
/// body to index it (a chunk's header, a message index's channel).
struct Window {
    bytes: [u8; Window::BYTES],
    len: usize,
    at: u64,
}

impl Window {
    /// Prefix (9), a chunk's header up to its records' length (44 with `zstd`).
    const BYTES: usize = 64;

    fn get<const N: usize>(&self, from: usize) -> io::Result<[u8; N]> {
        self.bytes[..self.len]
            .get(from..from + N)
            .map(|b| b.try_into().expect("N bytes"))
            .ok_or_else(|| corrupt(format!("a record cut short at byte {}", self.at)))
    }
    fn op(&self) -> io::Result<u8> {
        Ok(self.get::<1>(0)?[0])
    }
    fn u16(&self, from: usize) -> io::Result<u16> {
        Ok(u16::from_le_bytes(self.get(from)?))
    }
    fn u32(&self, from: usize) -> io::Result<u32> {
        Ok(u32::from_le_bytes(self.get(from)?))
    }
    fn u64(&self, from: usize) -> io::Result<u64> {
        Ok(u64::from_le_bytes(self.get(from)?))
    }
}

/// A chunk found in the data section at finish, for its index record.
struct ChunkAt {
    start: u64,
    end: u64,
    at: u64,
    /// The whole record's length, prefix included.
    length: u64,
    index_offsets: Vec<(u16, u64)>,
    /// The message-index records' total length, prefixes included.
    index_length: u64,
    compressed: u64,
    uncompressed: u64,
}

impl ChunkAt {
    /// The chunk whose record starts `w` (body `length` bytes). Only chunks this
    /// writer wrote are read back, so the compression is `zstd`.
    fn read(w: &Window, at: u64, length: u64) -> io::Result<ChunkAt> {
        if w.u32(9 + 28)? != 4 || w.get::<4>(9 + 32)? != *b"zstd" {
            return Err(corrupt(format!("the chunk at byte {at} is not zstd")));
        }
        Ok(ChunkAt {
            start: w.u64(9)?,
            end: w.u64(9 + 8)?,
            uncompressed: w.u64(9 + 16)?,
            compressed: w.u64(9 + 36)?,
            at,
            length: 9 + length,
            index_offsets: Vec::new(),
            index_length: 0,
        })
    }

    /// Appends its Chunk Index record to `b`.
    fn put_index(&self, b: &mut Vec<u8>) {
        let mut body = Vec::with_capacity(96);
        body.extend_from_slice(&self.start.to_le_bytes());
        body.extend_from_slice(&self.end.to_le_bytes());
        body.extend_from_slice(&self.at.to_le_bytes());
        body.extend_from_slice(&self.length.to_le_bytes());
        body.extend_from_slice(&((10 * self.index_offsets.len()) as u32).to_le_bytes());
        for (channel, offset) in &self.index_offsets {
            body.extend_from_slice(&channel.to_le_bytes());
            body.extend_from_slice(&offset.to_le_bytes());
        }
        body.extend_from_slice(&self.index_length.to_le_bytes());
        put_str(&mut body, "zstd");
        body.extend_from_slice(&self.compressed.to_le_bytes());
        body.extend_from_slice(&self.uncompressed.to_le_bytes());
        put_record(b, op::CHUNK_INDEX, &body);
    }
}
