//! A recording's writer holds the same memory after an hour as after a minute: a
//! counting global allocator follows the bytes the writing thread holds while a
//! session's recorder closes thousands of chunks (the recorder closes one every
//! half second, 7,200 an hour).
//!
//! The same measure on the mcap crate's own writer shows what it catches: that
//! writer keeps every chunk's index entry until it finishes.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::{Seek, SeekFrom, Write};
use std::time::SystemTime;

use laparo_proto::v1;
use laparo_server::recording::writer::{McapSink, SessionHeader};

struct Counting;

thread_local! {
    /// Bytes this thread holds: allocated minus freed (by this thread).
    static HELD: Cell<i64> = const { Cell::new(0) };
}

fn held() -> i64 {
    HELD.with(Cell::get)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        HELD.with(|c| c.set(c.get() + layout.size() as i64));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.with(|c| c.set(c.get() - layout.size() as i64));
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        HELD.with(|c| c.set(c.get() + new_size as i64 - layout.size() as i64));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Chunks written before the first reading (every buffer at its working size),
/// and after it.
const WARM_UP: u64 = 200;
const MEASURED: u64 = 5_000;

/// Poses per chunk: a station at 1 kHz fills a half-second chunk with 500; fewer
/// here keeps the test short without changing what a chunk leaves behind.
const POSES: u64 = 20;

fn pose(k: u64) -> v1::DevicePose {
    v1::DevicePose {
        instrument: "left".into(),
        sequence: k,
        ..Default::default()
    }
}

/// Bytes held after the warm-up and after the measured chunks.
fn held_over_chunks(mut chunk: impl FnMut(u64)) -> (i64, i64) {
    for c in 0..WARM_UP {
        chunk(c);
    }
    let before = held();
    for c in WARM_UP..WARM_UP + MEASURED {
        chunk(c);
    }
    (before, held())
}

#[test]
fn a_recording_holds_no_more_memory_after_thousands_of_chunks() {
    let dir = std::env::temp_dir().join(format!("laparo-recording-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("long.mcap");
    let header = SessionHeader {
        session_id: "s1".into(),
        scene_name: "default".into(),
        scene_toml: "name = \"default\"".into(),
        scene_dir: None,
        start: SystemTime::now(),
        description: v1::SceneDescription::default(),
    };
    let mut sink = McapSink::create(&path, &header).unwrap();
    let (before, after) = held_over_chunks(|c| {
        for k in 0..POSES {
            sink.write_pose(SystemTime::now(), &pose(c * POSES + k))
                .unwrap();
        }
        sink.flush().unwrap();
    });
    sink.finish().unwrap();
    // The file is whole: every chunk indexed.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    assert_eq!(summary.chunk_indexes.len() as u64, 1 + WARM_UP + MEASURED);
    std::fs::remove_dir_all(&dir).unwrap();
    eprintln!(
        "chunked writer: {} bytes more held after {MEASURED} chunks",
        after - before
    );
    // Nothing per chunk: a few bytes of slack for a buffer that grew once more.
    assert!(
        after - before <= 4096,
        "{} bytes more held after {MEASURED} chunks ({:.1} a chunk)",
        after - before,
        (after - before) as f64 / MEASURED as f64
    );
}

/// A file that keeps no bytes: only its position and length, so that what the
/// writer holds is all the measure sees.
#[derive(Default)]
struct Discard {
    at: u64,
    end: u64,
}

impl Write for Discard {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.at += buf.len() as u64;
        self.end = self.end.max(self.at);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for Discard {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.at = match to {
            SeekFrom::Start(n) => n,
            SeekFrom::Current(d) => self.at.saturating_add_signed(d),
            SeekFrom::End(d) => self.end.saturating_add_signed(d),
        };
        Ok(self.at)
    }
}

#[test]
fn the_measure_sees_a_writer_that_keeps_an_entry_per_chunk() {
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .create(Discard::default())
        .unwrap();
    let schema = w.add_schema("p", "protobuf", b"").unwrap();
    let channel = w
        .add_channel(schema, "/poses", "protobuf", &Default::default())
        .unwrap();
    let (before, after) = held_over_chunks(|c| {
        for k in 0..POSES {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: k as u32,
                log_time: c,
                publish_time: c,
            };
            w.write_to_known_channel(&header, &[0u8; 16]).unwrap();
        }
        w.flush().unwrap();
    });
    w.finish().unwrap();
    let per_chunk = (after - before) as f64 / MEASURED as f64;
    eprintln!("mcap crate writer: {per_chunk:.1} bytes more held a chunk");
    assert!(per_chunk > 64.0, "{per_chunk:.1} bytes a chunk");
}
