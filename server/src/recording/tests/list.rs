//! What a recordings directory lists.

use super::*;

#[test]
fn a_directory_lists_recordings_oldest_first_and_says_what_is_wrong_with_the_rest() {
    let dir = temp();
    let d = dir.path();
    // Two recordings, the second started earlier; a copy of one cut short.
    let mut script = Script::new();
    let now = SystemTime::now();
    let mut write = |name: &str, start: SystemTime, ticks: u64| -> (PathBuf, f64) {
        let path = d.join(name);
        let mut header = script.header(start);
        header.session_id = name.trim_end_matches(".mcap").into();
        let mut sink = McapSink::create(&path, &header).unwrap();
        let mut t = 0.0;
        for k in 0..ticks {
            let frame = script.tick(k);
            t = frame.sim_time;
            sink.write_frame(&frame, SystemTime::now()).unwrap();
            sink.flush().unwrap();
        }
        drop(sink.finish().unwrap());
        (path, t)
    };
    let (late, late_t) = write("b-late.mcap", now, 6);
    let (early, early_t) = write("a-early.mcap", now - Duration::from_secs(60), 4);
    let bytes = std::fs::read(&early).unwrap();
    let cut = d.join("c-cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() - 40]).unwrap();
    std::fs::write(d.join("d-notes.mcap"), b"not a recording").unwrap();
    std::fs::write(d.join("e-notes.txt"), b"not listed").unwrap();
    std::fs::create_dir(d.join("f-dir.mcap")).unwrap();

    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    let listed = list(d, |_| false).unwrap();
    let names: Vec<&str> = listed.iter().map(|l| l.file.as_str()).collect();
    assert_eq!(
        names,
        ["a-early.mcap", "c-cut.mcap", "b-late.mcap", "d-notes.mcap"]
    );
    let entry = |k: usize| listed[k].entry.as_ref().unwrap();
    assert_eq!(entry(0).session_id, "a-early");
    assert_eq!(entry(0).state, FileState::Complete);
    assert_eq!(entry(0).duration_s.to_bits(), early_t.to_bits());
    assert_eq!(
        entry(0).start_unix_ns,
        unix_ns(now - Duration::from_secs(60))
    );
    assert_eq!(entry(0).scene, script.scene.name);
    assert_eq!(listed[0].size_bytes, size(&early));
    // The cut copy: what its complete chunks hold, and that it has no footer.
    assert_eq!(entry(1).session_id, "a-early");
    assert_eq!(entry(1).state, FileState::Unfinished);
    assert_eq!(entry(1).duration_s.to_bits(), early_t.to_bits());
    assert_eq!(listed[1].size_bytes, size(&cut));
    assert_eq!(entry(2).state, FileState::Complete);
    assert_eq!(entry(2).duration_s.to_bits(), late_t.to_bits());
    assert_eq!(listed[2].size_bytes, size(&late));
    assert!(matches!(listed[3].entry, Err(ReadError::NotMcap { .. })));
    // A file a session is writing is in progress.
    let listed = list(d, |p| p == cut).unwrap();
    assert_eq!(
        listed[1].entry.as_ref().unwrap().state,
        FileState::InProgress
    );
    // A missing directory is an error, not an empty list.
    assert!(list(&d.join("missing"), |_| false).is_err());
}

#[test]
fn a_directory_of_many_files_lists_only_the_most_recently_modified() {
    let dir = temp();
    let d = dir.path();
    let mut script = Script::new();
    let now = SystemTime::now();
    // Five recordings modified a minute apart, the last written first.
    for k in 0..5u64 {
        let path = d.join(format!("r{k}.mcap"));
        let mut header = script.header(now);
        header.session_id = format!("r{k}");
        let mut sink = McapSink::create(&path, &header).unwrap();
        sink.write_frame(&script.tick(0), SystemTime::now())
            .unwrap();
        drop(sink.finish().unwrap());
        let modified = now - Duration::from_secs(60 * (5 - k));
        std::fs::File::options()
            .write(true)
            .open(&path)
            .unwrap()
            .set_modified(modified)
            .unwrap();
    }
    let lister = Lister::new();
    let (listed, left_out) = lister.list_at_most(d, 3, |_| false).unwrap();
    let mut names: Vec<&str> = listed.iter().map(|l| l.file.as_str()).collect();
    names.sort();
    assert_eq!(names, ["r2.mcap", "r3.mcap", "r4.mcap"]);
    assert_eq!(left_out, 2);
    // Under the bound nothing is left out.
    let (listed, left_out) = lister.list_at_most(d, 5, |_| false).unwrap();
    assert_eq!((listed.len(), left_out), (5, 0));
}

#[test]
fn a_file_is_read_afresh_only_when_new_or_changed() {
    // What a listing says of a file it cannot list (a server logs it) is said once a
    // version: the console lists every 2 s.
    let dir = temp();
    let d = dir.path();
    let bad = d.join("notes.mcap");
    std::fs::write(&bad, b"not a recording").unwrap();
    let lister = Lister::new();
    let fresh = |lister: &Lister| {
        let (listed, _) = lister.list_at_most(d, 10, |_| false).unwrap();
        assert!(listed[0].entry.is_err());
        listed[0].fresh
    };
    assert!(fresh(&lister), "new");
    assert!(!fresh(&lister), "unchanged");
    std::fs::write(&bad, b"still not a recording").unwrap();
    assert!(fresh(&lister), "changed");
    assert!(!fresh(&lister), "unchanged again");
}

#[cfg(unix)]
#[test]
fn a_file_whose_name_is_not_text_is_listed_as_unreadable_once_a_version() {
    use std::os::unix::ffi::OsStrExt;
    let dir = temp();
    let d = dir.path();
    let mut script = Script::new();
    // A recording renamed to a name with a byte that is not UTF-8.
    let path = d.join(std::ffi::OsStr::from_bytes(b"caf\xe9.mcap"));
    let mut sink = McapSink::create(&path, &script.header(SystemTime::now())).unwrap();
    sink.write_frame(&script.tick(0), SystemTime::now())
        .unwrap();
    drop(sink.finish().unwrap());
    let lister = Lister::new();
    let listed = |lister: &Lister| lister.list_at_most(d, 10, |_| false).unwrap().0;
    let first = listed(&lister);
    assert_eq!(first.len(), 1);
    assert_eq!(first[0].file, "caf\u{FFFD}.mcap");
    let e = first[0].entry.as_ref().unwrap_err();
    assert!(matches!(e, ReadError::NameNotText { .. }), "{e}");
    assert!(e.to_string().contains("rename it"), "{e}");
    // Nothing of the file is read, and it is told once, as any unreadable file.
    assert_eq!((first[0].bytes_read, first[0].fresh), (0, true));
    assert!(!listed(&lister)[0].fresh);
}
