//! The recorder thread: a full channel, an unwritable directory and a full disk are
//! counted and reported, never silent, and nothing waits.

use super::*;

#[test]
fn a_full_channel_is_counted_and_reported_never_silent() {
    let dir = temp();
    let path = dir.path().join("lag.mcap");
    let mut script = Script::new();
    let recorder =
        Recorder::with_capacity(path.clone(), script.header(SystemTime::now()), 1).unwrap();
    let frame = Arc::new(script.tick(0));
    let mut reports = Vec::new();
    let mut offered = 0u64;
    let stats = recorder.stats();
    while stats.dropped.load(std::sync::atomic::Ordering::Relaxed) == 0 && offered < 1_000_000 {
        offered += 1;
        reports.extend(recorder.offer(Item::Frame {
            frame: frame.clone(),
            wall: SystemTime::now(),
        }));
    }
    let dropped = stats.dropped.load(std::sync::atomic::Ordering::Relaxed);
    assert!(dropped > 0, "a channel of one never filled");
    let dropped_first = dropped;
    assert_eq!(reports.len(), 1);
    assert_eq!(reports[0].kind(), v1::EventKind::RecorderLagging);
    // A later item makes it through: the file notes the gap before it.
    let sent_before = stats.sent.load(std::sync::atomic::Ordering::Relaxed);
    while stats.sent.load(std::sync::atomic::Ordering::Relaxed) == sent_before {
        let report = recorder.offer(Item::Event {
            event: v1::Event {
                tick: 1,
                kind: v1::EventKind::SessionClosing as i32,
                ..Default::default()
            },
            wall: SystemTime::now(),
        });
        assert!(report.is_none_or(|r| r.kind() == v1::EventKind::RecorderLagging));
        std::thread::sleep(Duration::from_millis(1));
    }
    recorder.finish().unwrap();
    let sent = stats.sent.load(std::sync::atomic::Ordering::Relaxed);
    let dropped = stats.dropped.load(std::sync::atomic::Ordering::Relaxed);
    assert_eq!(
        sent + dropped,
        offered + (sent - sent_before) + (dropped - dropped_first)
    );
    // Every item handed over was written; at most the channel's one item plus the
    // one being written ever waited.
    assert_eq!(
        stats.processed.load(std::sync::atomic::Ordering::Relaxed),
        sent
    );
    let backlog = stats.max_backlog.load(std::sync::atomic::Ordering::Relaxed);
    assert!((1..=2).contains(&backlog), "{backlog}");
    // A client arriving now is told items were left out, with the total.
    assert_eq!(
        recorder.standing_reports(),
        vec![Report::Lagging {
            dropped_total: dropped,
            detail: "earlier items were".into()
        }]
    );
    let rec = Recording::open(&path).unwrap();
    let events = rec.events().unwrap();
    let surfaces = rec.surfaces().unwrap().len() as u64;
    let closing = events
        .iter()
        .filter(|e| e.message.kind == v1::EventKind::SessionClosing as i32)
        .count() as u64;
    assert_eq!(surfaces + closing, sent);
    assert!(
        events
            .iter()
            .any(|e| e.message.kind == v1::EventKind::RecorderLagging as i32),
        "{dropped} dropped and no lagging event in the file"
    );
}

#[test]
fn an_unwritable_directory_is_reported_once_and_nothing_waits() {
    let dir = temp();
    let path = dir.path().join("no-such-dir").join("x.mcap");
    let script = Script::new();
    let recorder = Recorder::start(path, script.header(SystemTime::now())).unwrap();
    let event = || Item::Event {
        event: v1::Event::default(),
        wall: SystemTime::now(),
    };
    // Until the thread has failed, offers queue up (and may fill the channel, which
    // is reported as lagging); the failure is then reported once.
    let failed = loop {
        match recorder.offer(event()) {
            Some(r @ Report::Failed { .. }) => break r,
            Some(r) => assert_eq!(r.kind(), v1::EventKind::RecorderLagging),
            None => std::thread::yield_now(),
        }
    };
    assert!(
        matches!(&failed, Report::Failed { error } if error.contains("x.mcap") && !error.contains("no-such-dir"))
    );
    assert_eq!(failed.kind(), v1::EventKind::RecorderError);
    for _ in 0..10 {
        assert_eq!(recorder.offer(event()), None);
    }
    assert_eq!(
        recorder
            .stats()
            .errors
            .load(std::sync::atomic::Ordering::Relaxed),
        1
    );
    assert!(!recorder.created_file());
    assert!(recorder.finish().is_err());
}

/// A full disk: `/dev/full` answers every write with ENOSPC. (The recorder opens
/// its file with `create_new` and so never writes over a device; the writer is
/// given it here.) The error the recorder reports names the cause, not only that
/// writing failed.
#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_is_reported_with_its_cause() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("no /dev/full here: nothing to test");
        return;
    };
    let script = Script::new();
    let header = script.header(SystemTime::now());
    // The header and scene are written and flushed at once: the disk is full there.
    let Err(e) = McapSink::new(full, &header) else {
        panic!("writing to /dev/full succeeded");
    };
    let reported = crate::recording::recorder::with_causes(&e);
    assert!(
        reported.starts_with("No space left on device"),
        "{reported}"
    );
}
