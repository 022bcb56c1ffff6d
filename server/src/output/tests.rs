//! An output is replaced whole or left as it was.

use std::io::{self, Write};
use std::path::Path;

use super::{WholeFile, write_whole};

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_written_output_replaces_the_old_one_and_leaves_no_part_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.vtu");
    std::fs::write(&out, "old").unwrap();
    write_whole(&out, |w| w.write_all(b"new contents")).unwrap();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "new contents");
    assert_eq!(names(dir.path()), ["out.vtu"]);
}

#[test]
fn a_write_that_fails_leaves_the_old_output_as_it_was() {
    // What a full disk does halfway through: the write is refused with ENOSPC.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plot.png");
    std::fs::write(&out, "the earlier plot").unwrap();
    let err = write_whole(&out, |w| {
        w.write_all(&[7u8; 100_000])?;
        Err(io::Error::from_raw_os_error(28))
    })
    .unwrap_err();
    assert_eq!(err.raw_os_error(), Some(28));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "the earlier plot");
    assert_eq!(names(dir.path()), ["plot.png"]);
    // No earlier output: none is left behind either.
    let fresh = dir.path().join("fresh.png");
    write_whole(&fresh, |_| Err(io::Error::from_raw_os_error(28))).unwrap_err();
    assert_eq!(names(dir.path()), ["plot.png"]);
}

#[test]
fn an_output_dropped_before_its_commit_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.vtu");
    let mut file = WholeFile::create(&out).unwrap();
    file.write_all(b"half").unwrap();
    assert!(file.part().exists());
    drop(file);
    assert!(names(dir.path()).is_empty());
}

#[test]
fn only_a_regular_file_is_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("a directory");
    std::fs::create_dir(&sub).unwrap();
    let err = write_whole(&sub, |w| w.write_all(b"x")).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    assert!(err.to_string().contains("it is a directory"), "{err}");
    assert!(sub.is_dir());
    #[cfg(unix)]
    {
        let target = dir.path().join("target");
        std::fs::write(&target, "kept").unwrap();
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let err = write_whole(&link, |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "kept");
        let err = write_whole(Path::new("/dev/null"), |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("character device"), "{err}");
    }
    assert_eq!(names(dir.path()).len(), if cfg!(unix) { 3 } else { 1 });
}

#[test]
fn an_output_in_a_missing_folder_is_an_error_that_creates_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("missing").join("out.vtu");
    let err = write_whole(&out, |w| w.write_all(b"x")).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::NotFound);
    assert!(names(dir.path()).is_empty());
}
