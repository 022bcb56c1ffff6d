use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::{Follow, Source, SourceError};

fn temp() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("laparo-source-")
        .tempdir()
        .unwrap()
}

#[test]
fn a_file_cut_under_an_open_source_reads_short_not_past_its_end() {
    let dir = temp();
    let path = dir.path().join("r.mcap");
    std::fs::write(&path, [7u8; 1000]).unwrap();
    let source = Source::open(&path, Follow::NoLinks).unwrap();
    assert_eq!(source.read_at(990, 10, 10).unwrap(), [7; 10]);
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(100)
        .unwrap();
    assert_eq!(source.len().unwrap(), 100);
    let err = source.read_at(90, 20, 1 << 20).unwrap_err();
    assert!(
        matches!(
            err,
            SourceError::Short {
                at: 90,
                length: 20,
                size: 100
            }
        ),
        "{err}"
    );
    let mut buf = [0u8; 16];
    assert!(source.read_exact_at(u64::MAX - 4, &mut buf).is_err());
    // Only what was read is counted.
    assert_eq!(source.bytes_read(), 10);
}

#[test]
fn a_stated_length_over_the_limit_is_refused_before_it_is_allocated() {
    let source = Source::held(vec![0; 64]);
    let err = source.read_at(0, u64::MAX, 1 << 20).unwrap_err();
    assert!(matches!(err, SourceError::TooLong { .. }), "{err}");
    let err = source.read_at(60, 8, 1 << 20).unwrap_err();
    assert!(matches!(err, SourceError::Short { .. }), "{err}");
    assert_eq!(source.bytes_read(), 0);
}

#[test]
fn the_cursor_reads_and_seeks_as_a_file_does() {
    let source = Source::held((0u8..100).collect());
    let mut c = source.cursor();
    assert_eq!(c.seek(SeekFrom::End(-10)).unwrap(), 90);
    let mut rest = Vec::new();
    c.read_to_end(&mut rest).unwrap();
    assert_eq!(rest, (90u8..100).collect::<Vec<_>>());
    assert!(c.seek(SeekFrom::Current(-200)).is_err());
    assert_eq!(source.bytes_read(), 10);
}

fn refused(path: &Path, follow: Follow) -> std::io::Error {
    Source::open(path, follow).expect_err("refused")
}

#[test]
fn only_regular_files_open_and_links_only_when_asked() {
    let dir = temp();
    let d = dir.path();
    let outside = temp();
    let target = outside.path().join("secret.mcap");
    std::fs::write(&target, b"outside").unwrap();
    let link = d.join("link.mcap");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let e = refused(&link, Follow::NoLinks);
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    assert!(e.to_string().contains("symbolic link"), "{e}");
    assert!(Source::open(&link, Follow::Links).is_ok());
    // A directory, and a FIFO nobody writes to: refused at once, not waited on.
    std::fs::create_dir(d.join("dir.mcap")).unwrap();
    assert!(
        refused(&d.join("dir.mcap"), Follow::Links)
            .to_string()
            .contains("not a regular file")
    );
    let fifo = d.join("fifo.mcap");
    let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    assert!(
        refused(&fifo, Follow::Links)
            .to_string()
            .contains("not a regular file")
    );
}
