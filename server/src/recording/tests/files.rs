//! Files the recorder and recovery leave behind: none from a start that failed,
//! a recovery up to the last complete chunk before a junk tail, and no file at
//! all when nothing is recoverable.

use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::time::SystemTime;

use laparo_proto::v1;

use crate::recording::Existing;
use crate::recording::writer::{McapSink, SessionHeader, created};
use crate::recording::{ReadError, Recording, RecoverError, recover};

fn temp() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("laparo-files-")
        .tempdir()
        .unwrap()
}

fn header() -> SessionHeader {
    SessionHeader {
        session_id: "s9".into(),
        scene_name: "default".into(),
        scene_toml: "name = \"default\"".into(),
        scene_dir: None,
        start: SystemTime::now(),
        description: v1::SceneDescription::default(),
    }
}

/// A writer that takes `room` bytes, then answers every write as a full disk does.
struct FillsUp {
    file: File,
    room: usize,
}

impl Write for FillsUp {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.room == 0 {
            return Err(std::io::Error::from_raw_os_error(28)); // ENOSPC
        }
        let n = buf.len().min(self.room);
        self.room -= n;
        self.file.write(&buf[..n])
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl std::io::Read for FillsUp {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.file.read(buf)
    }
}

impl std::io::Seek for FillsUp {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.file.seek(to)
    }
}

#[test]
fn a_recording_whose_start_fails_leaves_no_file() {
    let dir = temp();
    for room in [0, 9, 500, 4000] {
        let path = dir.path().join(format!("full-{room}.mcap"));
        let started = created(&path, |file| {
            McapSink::new(FillsUp { file, room }, &header())
        });
        assert!(started.is_err(), "{room} bytes were enough");
        assert!(!path.exists(), "{room}: a file was left");
    }
    // A start that succeeds keeps its file, and an existing file is never replaced.
    let path = dir.path().join("ok.mcap");
    drop(McapSink::create(&path, &header()).unwrap());
    if let Err(e) = Recording::open(&path) {
        panic!("a started recording does not open: {e}");
    }
    assert!(McapSink::create(&path, &header()).is_err());
    if let Err(e) = Recording::open(&path) {
        panic!("a started recording does not open: {e}");
    }
}

/// A file as a stopped server leaves it: the header chunk and metadata, `events`
/// events in a closed chunk, then `tail`.
fn cut_with_tail(path: &Path, events: u64, tail: &[u8]) {
    let mut sink = McapSink::create(path, &header()).unwrap();
    for k in 0..events {
        let event = v1::Event {
            tick: k,
            sim_time_s: k as f64 / 60.0,
            kind: v1::EventKind::ContactBegan as i32,
            ..v1::Event::default()
        };
        sink.write_event(&event, SystemTime::now()).unwrap();
    }
    sink.flush().unwrap();
    let size = std::fs::metadata(path).unwrap().len();
    drop(sink.finish().unwrap());
    let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
    f.set_len(size).unwrap();
    std::os::unix::fs::FileExt::write_all_at(&f, tail, size).unwrap();
}

#[test]
fn a_junk_tail_is_left_out_and_every_complete_chunk_before_it_kept() {
    let dir = temp();
    let junk: Vec<u8> = (0..3000u32).map(|k| (k * 7919 % 251) as u8).collect();
    for (tail, name) in [
        (&junk[..], "junk"),
        (&[0xFF; 40][..], "ff"),
        (&[][..], "none"),
    ] {
        let path = dir.path().join(format!("{name}.mcap"));
        cut_with_tail(&path, 25, tail);
        assert!(matches!(
            Recording::open(&path),
            Err(ReadError::Truncated { .. })
        ));
        let out = dir.path().join(format!("{name}-fixed.mcap"));
        let r = recover(&path, &out, Existing::Refuse).unwrap();
        assert_eq!(r.messages, 1 + 25, "{name}: the scene and every event");
        assert_eq!(r.bytes_dropped, tail.len() as u64, "{name}");
        let fixed = Recording::open(&out).unwrap();
        assert_eq!(fixed.meta().session_id, "s9");
        assert_eq!(fixed.events().unwrap().len(), 25);
    }
}

#[test]
fn a_file_with_nothing_recoverable_is_an_error_and_writes_nothing() {
    let dir = temp();
    let whole = dir.path().join("whole.mcap");
    cut_with_tail(&whole, 3, &[]);
    let bytes = std::fs::read(&whole).unwrap();
    let mut junk_after_magic = mcap::MAGIC.to_vec();
    junk_after_magic.extend((0..2000u32).map(|k| (k * 31 % 256) as u8));
    let cases = [
        ("magic-then-junk", junk_after_magic),
        ("cut-in-first-chunk", bytes[..bytes.len() / 4].to_vec()),
        ("magic-only", mcap::MAGIC.to_vec()),
    ];
    for (name, content) in cases {
        let path = dir.path().join(format!("{name}.mcap"));
        std::fs::write(&path, &content).unwrap();
        let out = dir.path().join(format!("{name}-fixed.mcap"));
        let err = recover(&path, &out, Existing::Refuse).unwrap_err();
        assert!(
            matches!(err, RecoverError::NothingToRecover { .. }),
            "{name}: {err}"
        );
        assert!(err.to_string().contains("nothing recoverable"), "{err}");
        assert!(!out.exists(), "{name}: an output was written");
        // Recovering in place leaves the file as it was.
        assert!(recover(&path, &path, Existing::Refuse).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), content, "{name}");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.ends_with(".part"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}
