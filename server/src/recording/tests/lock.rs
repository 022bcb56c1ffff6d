//! A recording being written is locked: recovery refuses it, and a listing shows it
//! in progress, until its writer lets it go.

use super::*;
use crate::recording::lock::path_being_written;

#[test]
fn a_recording_being_written_is_not_recovered_and_is_listed_in_progress() {
    let dir = temp();
    let path = dir.path().join("live.mcap");
    let mut script = Script::new();
    let mut sink = McapSink::create(&path, &script.header(SystemTime::now())).unwrap();
    for k in 0..6 {
        sink.write_pose(SystemTime::now(), &script.device_pose(k))
            .unwrap();
        sink.write_frame(&script.tick(k), SystemTime::now())
            .unwrap();
    }
    sink.flush().unwrap();
    let before = std::fs::read(&path).unwrap();
    assert!(path_being_written(&path));

    // Recovering it in place, or to another file, or writing another recovery over
    // it: each refused by name, the file left as it is.
    let copy = dir.path().join("copy.mcap");
    std::fs::write(&copy, &before).unwrap();
    assert!(!path_being_written(&copy));
    for (input, output) in [(&path, &path), (&path, &copy), (&copy, &path)] {
        let err = recover(input, output, Existing::Refuse).unwrap_err();
        assert!(
            matches!(&err, RecoverError::BeingRecorded { file } if file == &path.display().to_string()),
            "{input:?} → {output:?}: {err}"
        );
    }
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read(&copy).unwrap(), before);
    let listed = list(dir.path(), path_being_written).unwrap();
    let state = |name: &str| {
        listed
            .iter()
            .find(|l| l.file == name)
            .and_then(|l| l.entry.as_ref().ok())
            .map(|e| e.state)
    };
    assert_eq!(state("live.mcap"), Some(FileState::InProgress));
    assert_eq!(state("copy.mcap"), Some(FileState::Unfinished));

    // Dropped unfinished, as by a server that dies: the lock goes with the file,
    // and the recording is recovered like any file cut short.
    drop(sink);
    assert!(!path_being_written(&path));
    let report = recover(&path, &path, Existing::Refuse).unwrap();
    assert!(report.messages > 0);
    assert!(Recording::open(&path).unwrap().is_complete());
}
