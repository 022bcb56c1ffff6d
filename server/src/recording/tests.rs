//! Recordings written and read back: a scripted simulation through the recorder, a
//! recorded session, files cut short and recovered, and files that are not
//! recordings.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use laparo_proto::force::wire::to_pose;
use laparo_proto::v1;
use nalgebra::{Point3, Unit};
use prost::Message;

use super::writer::McapSink;
use super::*;
use crate::engine::contact::pose::InstrumentPose;
use crate::engine::scene::{Scene, Simulation};
use crate::session::describe::{description, instrument_state, surface_positions};
use crate::session::{Frame, Session, SessionConfig};

/// The default scene's left instrument pushing straight down into the top of the
/// liver, 1 mm a tick from 1 cm above it.
struct Script {
    sim: Simulation,
    scene: Scene,
    top: Point3<f64>,
    trocar: Point3<f64>,
}

impl Script {
    fn new() -> Self {
        let scene = Scene::default_scene();
        let sim = scene.build().unwrap();
        let (lo, hi) = sim.mesh.bounding_box();
        let top = Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z + 0.01);
        let trocar = sim.instruments[0].trocar;
        Script {
            sim,
            scene,
            top,
            trocar,
        }
    }

    fn pose(&self, k: u64) -> InstrumentPose {
        let tip = self.top - nalgebra::Vector3::z() * (1e-3 * k as f64);
        InstrumentPose::new(tip, Unit::new_normalize(self.trocar - tip))
    }

    /// The device pose of tick `k`, as a station would send it.
    fn device_pose(&self, k: u64) -> v1::DevicePose {
        let p = self.pose(k);
        v1::DevicePose {
            instrument: self.sim.instruments[0].name.clone(),
            pose: Some(to_pose(&p.tip, &p.axis)),
            device_time_s: k as f64 * 1e-3,
            sequence: k + 1,
        }
    }

    /// Sets tick `k`'s pose, ticks, and returns the frame.
    fn tick(&mut self, k: u64) -> Frame {
        self.sim.set_pose(0, Some(self.pose(k)));
        self.sim.tick();
        let n = self.sim.instruments.len();
        Frame {
            tick: self.sim.tick,
            sim_time: self.sim.time,
            surface: surface_positions(&self.sim),
            instruments: (0..n)
                .map(|i| instrument_state(&self.sim, i, Some(1), Some(k + 1)))
                .collect(),
        }
    }

    fn header(&self, start: SystemTime) -> SessionHeader {
        SessionHeader {
            session_id: "s7".into(),
            scene_name: self.scene.name.clone(),
            scene_dir: None,
            scene_toml: self.scene.text.clone(),
            start,
            description: description(&self.scene, &self.sim),
        }
    }
}

mod scene_updates;

fn temp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Runs `ticks` ticks of the script through a recorder, with the pose of each tick
/// recorded before it; returns the frames and poses handed over.
fn record_script(path: &Path, ticks: u64) -> (Vec<Arc<Frame>>, Vec<v1::DevicePose>, SessionHeader) {
    let mut script = Script::new();
    let header = script.header(SystemTime::now());
    let recorder = Recorder::start(path.to_path_buf(), header.clone()).unwrap();
    let (mut frames, mut poses) = (Vec::new(), Vec::new());
    for k in 0..ticks {
        let pose = script.device_pose(k);
        assert_eq!(
            recorder.offer(Item::Pose {
                received: SystemTime::now(),
                pose: pose.clone()
            }),
            None
        );
        poses.push(pose);
        let frame = Arc::new(script.tick(k));
        assert_eq!(
            recorder.offer(Item::Frame {
                frame: frame.clone(),
                wall: SystemTime::now()
            }),
            None
        );
        frames.push(frame);
    }
    recorder.finish().unwrap();
    assert_eq!(
        recorder
            .stats()
            .dropped
            .load(std::sync::atomic::Ordering::Relaxed),
        0
    );
    (frames, poses, header)
}

#[test]
fn a_scripted_run_reads_back_bit_for_bit() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (frames, poses, header) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();

    let meta = rec.meta();
    assert_eq!(meta.format_version, FORMAT_VERSION);
    assert_eq!(meta.session_id, "s7");
    assert_eq!(meta.scene, header.scene_name);
    assert_eq!(meta.scene_toml, header.scene_toml);
    assert!(!meta.scene_toml.is_empty());
    assert_eq!(meta.start_unix_ns, unix_ns(header.start));
    assert_eq!(rec.scene().unwrap(), header.description);

    let surfaces = rec.surfaces().unwrap();
    assert_eq!(surfaces.len(), frames.len());
    for (s, f) in surfaces.iter().zip(&frames) {
        assert_eq!(s.message.tick, f.tick);
        assert_eq!(s.message.sim_time_s.to_bits(), f.sim_time.to_bits());
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&s.message.positions), bits(&f.surface));
        assert_eq!(s.log_time, sim_log_time(meta.start_unix_ns, f.sim_time));
    }
    let states = rec.instrument_states().unwrap();
    let expected: Vec<_> = frames.iter().flat_map(|f| f.instruments.clone()).collect();
    assert_eq!(
        states.into_iter().map(|s| s.message).collect::<Vec<_>>(),
        expected
    );
    assert_eq!(
        rec.poses()
            .unwrap()
            .into_iter()
            .map(|p| p.message)
            .collect::<Vec<_>>(),
        poses
    );
    // Log times of ticks never go back.
    let times: Vec<u64> = rec.surfaces().unwrap().iter().map(|s| s.log_time).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]));
    let counts = rec.message_counts();
    assert_eq!(counts[TOPIC_SURFACE], 40);
    assert_eq!(counts[TOPIC_POSES], 40);
    assert_eq!(counts[TOPIC_SCENE], 1);
    // Scene updates for Foxglove at most 20 a second: ticks 1, 4, … at 60 Hz.
    let stride = foxglove_scene::stride(60.0);
    assert_eq!(stride, 3);
    assert_eq!(counts[TOPIC_FOXGLOVE_SCENE], 40u64.div_ceil(stride));
    // The contract's messages alone, decoded; the viewers' channel is left alone.
    let decoded = rec.messages().map(Result::unwrap).count() as u64;
    assert_eq!(
        decoded,
        counts.values().sum::<u64>() - counts[TOPIC_FOXGLOVE_SCENE]
    );
}

#[test]
fn every_schema_is_the_contract_named_by_its_message() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    record_script(&path, 3);
    let rec = Recording::open(&path).unwrap();
    let summary = rec.mcap_summary();
    assert_eq!(summary.channels.len(), 6);
    for channel in summary.channels.values() {
        assert_eq!(channel.message_encoding, "protobuf");
        let schema = channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        if channel.topic == TOPIC_FOXGLOVE_SCENE {
            // Foxglove's own schema (tests/scene_updates.rs).
            continue;
        }
        assert_eq!(&schema.data[..], laparo_proto::FILE_DESCRIPTOR_SET);
        let set = prost_types::FileDescriptorSet::decode(&*schema.data).unwrap();
        let (package, message) = schema.name.rsplit_once('.').unwrap();
        assert!(
            set.file
                .iter()
                .any(|f| f.package() == package
                    && f.message_type.iter().any(|m| m.name() == message)),
            "{} is not in its schema's descriptors",
            schema.name
        );
    }
    let topics: std::collections::BTreeSet<_> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    assert_eq!(
        topics,
        [
            TOPIC_SCENE,
            TOPIC_POSES,
            TOPIC_SURFACE,
            TOPIC_INSTRUMENTS,
            TOPIC_EVENTS,
            TOPIC_FOXGLOVE_SCENE
        ]
        .into_iter()
        .collect()
    );
}

#[test]
fn the_summary_measures_the_scripted_push() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (frames, _, header) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();
    let s = summarize(&rec).unwrap();
    assert_eq!(s.ticks, 40);
    assert_eq!(s.poses, 40);
    assert_eq!(
        s.duration_s.to_bits(),
        frames.last().unwrap().sim_time.to_bits()
    );
    let left = &s.instruments["left"];
    assert_eq!(left.ticks_with_pose, 40);
    // 39 steps of 1 mm.
    assert!(
        (left.path_length_m - 0.039).abs() < 1e-9,
        "{}",
        left.path_length_m
    );
    let forces: Vec<f64> = frames
        .iter()
        .map(|f| {
            let v = f.instruments[0]
                .force
                .as_ref()
                .and_then(|f| f.force)
                .unwrap_or_default();
            (v.x * v.x + v.y * v.y + v.z * v.z).sqrt()
        })
        .collect();
    let max = forces.iter().cloned().fold(0.0, f64::max);
    assert!(max > 0.0, "the push never touched the liver");
    assert_eq!(left.max_force_n, max);
    assert!((left.mean_force_n - forces.iter().sum::<f64>() / 40.0).abs() < 1e-12);
    let contact = frames
        .iter()
        .filter(|f| f.instruments[0].contact != v1::ContactState::None as i32)
        .count() as u64;
    assert_eq!(left.contact_ticks, contact);
    let rate = header.description.summary.unwrap().mechanics_rate_hz;
    assert!((left.time_in_contact_s - contact as f64 / rate).abs() < 1e-12);
    assert!(left.max_force_jump_n > 0.0 && left.max_force_jump_n <= max + 1e-12);
    // The other instrument never had a pose.
    let right = &s.instruments["right"];
    assert_eq!((right.ticks_with_pose, right.path_length_m), (0, 0.0));
}

/// Writes a recording, closing a chunk every `per_chunk` ticks; returns the file
/// size and message count after each chunk, and the finished file's bytes.
fn chunked(path: &Path, ticks: u64, per_chunk: u64) -> (Vec<(u64, u64)>, Vec<u8>) {
    let mut script = Script::new();
    let header = script.header(SystemTime::now());
    let mut sink = McapSink::create(path, &header).unwrap();
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    let mut boundaries = vec![(size(path), sink.messages)];
    for k in 0..ticks {
        sink.write_pose(SystemTime::now(), &script.device_pose(k))
            .unwrap();
        let frame = script.tick(k);
        sink.write_frame(&frame, SystemTime::now()).unwrap();
        if (k + 1) % per_chunk == 0 {
            sink.flush().unwrap();
            boundaries.push((size(path), sink.messages));
        }
    }
    drop(sink.finish().unwrap());
    (boundaries, std::fs::read(path).unwrap())
}

/// Every message of a recording, raw, in file order.
fn raw_messages(path: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), m.log_time, m.data.into_owned())
        })
        .collect()
}

#[test]
fn a_file_cut_short_recovers_every_complete_chunk() {
    let dir = temp();
    let full = dir.path().join("full.mcap");
    let (boundaries, bytes) = chunked(&full, 24, 4);
    let all = raw_messages(&full);
    assert_eq!(all.len() as u64, boundaries.last().unwrap().1);
    let mut cuts: Vec<(u64, u64, u64)> = Vec::new(); // (offset, at least, at most)
    for w in boundaries.windows(2) {
        let ((a, na), (b, nb)) = (w[0], w[1]);
        cuts.push((a, na, na)); // right after a chunk and its indexes
        cuts.push((a + 1, na, na)); // one byte into the next chunk
        cuts.push(((a + b) / 2, na, nb)); // mid-chunk
        cuts.push((b - 1, na, nb));
    }
    let n = all.len() as u64;
    cuts.push((bytes.len() as u64 - 1, n, n)); // only the end magic missing
    cuts.push((boundaries.last().unwrap().0 + 3, n, n)); // inside the summary
    for (cut, at_least, at_most) in cuts {
        let cut_path = dir.path().join(format!("cut-{cut}.mcap"));
        std::fs::write(&cut_path, &bytes[..cut as usize]).unwrap();
        assert!(matches!(
            Recording::open(&cut_path),
            Err(ReadError::Truncated { .. })
        ));
        let fixed = dir.path().join(format!("fixed-{cut}.mcap"));
        let report = recover(&cut_path, &fixed).unwrap();
        let got = raw_messages(&fixed);
        assert!(
            (at_least..=at_most).contains(&(got.len() as u64)),
            "cut at {cut}: {} messages, expected {at_least}..={at_most}",
            got.len()
        );
        assert_eq!(report.messages, got.len() as u64);
        assert_eq!(got[..], all[..got.len()], "cut at {cut}");
        assert!(report.bytes_kept <= cut);
        // The recovered file is complete: indexed and readable as any recording.
        let rec = Recording::open(&fixed).unwrap();
        assert!(!rec.mcap_summary().chunk_indexes.is_empty());
        assert_eq!(rec.meta().session_id, "s7");
        assert_eq!(rec.message_counts().values().sum::<u64>(), got.len() as u64);
        assert!(summarize(&rec).is_ok());
    }
    // A complete file recovers to the same messages, in place.
    let copy = dir.path().join("copy.mcap");
    std::fs::copy(&full, &copy).unwrap();
    let report = recover(&copy, &copy).unwrap();
    assert!(report.was_complete);
    assert_eq!(raw_messages(&copy), all);
}

#[test]
fn a_recording_of_another_version_is_refused_by_name() {
    let dir = temp();
    let path = dir.path().join("v2.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("protobuf")
        .create(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: METADATA_NAME.into(),
        metadata: [("format_version".to_string(), "2".to_string())].into(),
    })
    .unwrap();
    w.finish().unwrap();
    drop(w);
    let err = Recording::open(&path).unwrap_err();
    assert!(
        matches!(&err, ReadError::UnsupportedVersion { found, .. } if found == "2"),
        "{err}"
    );
    assert!(err.to_string().contains("version `2`"), "{err}");
}

#[test]
fn files_that_are_not_recordings_give_clear_errors() {
    let dir = temp();
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let text = write("notes.mcap", b"this is not a recording at all");
    assert!(matches!(
        Recording::open(&text),
        Err(ReadError::NotMcap { .. })
    ));
    assert!(matches!(
        recover(&text, &dir.path().join("x.mcap")),
        Err(RecoverError::NotMcap { .. })
    ));
    let empty = write("empty.mcap", b"");
    assert!(matches!(
        Recording::open(&empty),
        Err(ReadError::NotMcap { .. })
    ));
    let mut framed = mcap::MAGIC.to_vec();
    framed.extend_from_slice(&[0xAB; 100]);
    framed.extend_from_slice(mcap::MAGIC);
    let garbage = write("garbage.mcap", &framed);
    let err = Recording::open(&garbage).unwrap_err();
    assert!(matches!(err, ReadError::Corrupt { .. }), "{err}");
    assert!(matches!(
        Recording::open(&dir.path().join("missing.mcap")),
        Err(ReadError::Io { .. })
    ));

    // An MCAP file without our metadata.
    let plain = dir.path().join("plain.mcap");
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(&plain).unwrap(),
    ))
    .unwrap();
    w.finish().unwrap();
    drop(w);
    assert!(matches!(
        Recording::open(&plain),
        Err(ReadError::NotARecording { .. })
    ));

    // Damage anywhere in a real recording: an error or a partial read, never a panic.
    let good = dir.path().join("good.mcap");
    record_script(&good, 10);
    let bytes = std::fs::read(&good).unwrap();
    for at in (8..bytes.len()).step_by(bytes.len() / 400 + 1) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x5A;
        if let Ok(rec) = Recording::from_bytes(format!("bad-{at}"), bad.clone()) {
            let _ = rec.messages().count();
            let _ = summarize(&rec);
        }
        let _ = super::recover::recover_bytes("bad", &bad, std::io::Cursor::new(Vec::new()));
    }
}

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
    let Err(e) = McapSink::new(std::io::BufWriter::new(full), &header) else {
        panic!("writing to /dev/full succeeded");
    };
    let reported = recorder::with_causes(&e);
    assert!(reported.contains("No space left on device"), "{reported}");
}

/// Waits until the session has ticked `n` times.
fn wait_ticks(session: &Session, n: u64) {
    while session
        .stats
        .tick
        .load(std::sync::atomic::Ordering::Relaxed)
        < n
    {
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_recorded_session_writes_its_ticks_poses_and_events() {
    let dir = temp();
    let config = SessionConfig {
        idle_timeout: None,
        recordings: Some(dir.path().to_path_buf()),
    };
    let session = Session::start("s3".into(), Scene::default_scene(), &config).unwrap();
    let file = session.info().recording_file.unwrap();
    assert!(
        file.starts_with("s3-default-") && file.ends_with(".mcap"),
        "{file}"
    );
    wait_ticks(&session, 5);
    let script = Script::new();
    let poses: Vec<_> = (0..5).map(|k| script.device_pose(k)).collect();
    for p in &poses {
        session.record_pose(p);
    }
    session.publish(
        v1::EventKind::StationJoined,
        Some(1),
        None,
        "test station".into(),
    );
    wait_ticks(&session, 10);
    // While the session runs its file has no footer, and reads as far as it goes.
    assert!(session.recorder().unwrap().is_writing());
    let path = dir.path().join(&file);
    let (so_far, state) = list::open(&path, |p| p == path).unwrap();
    assert_eq!(state, FileState::InProgress);
    assert_eq!(so_far.meta().session_id, "s3");
    session.close("test over");
    session.join();
    assert!(!session.recorder().unwrap().is_writing());
    let last_tick = session
        .stats
        .tick
        .load(std::sync::atomic::Ordering::Relaxed);
    let rec = Recording::open(&dir.path().join(&file)).unwrap();
    assert_eq!(rec.meta().session_id, "s3");
    assert_eq!(rec.meta().scene_toml, Scene::default_scene().text);
    assert_eq!(rec.scene().unwrap(), session.description);
    let surfaces = rec.surfaces().unwrap();
    assert_eq!(surfaces.len() as u64, last_tick);
    assert!(
        surfaces
            .iter()
            .enumerate()
            .all(|(i, s)| s.message.tick == i as u64 + 1)
    );
    assert_eq!(
        rec.instrument_states().unwrap().len(),
        surfaces.len() * session.scene.instruments.len()
    );
    assert_eq!(
        rec.poses()
            .unwrap()
            .into_iter()
            .map(|p| p.message)
            .collect::<Vec<_>>(),
        poses
    );
    let kinds: Vec<i32> = rec
        .events()
        .unwrap()
        .iter()
        .map(|e| e.message.kind)
        .collect();
    assert!(kinds.contains(&(v1::EventKind::StationJoined as i32)));
    assert_eq!(kinds.last(), Some(&(v1::EventKind::SessionClosing as i32)));
    let r = session.recorder().unwrap();
    assert_eq!(
        r.stats().dropped.load(std::sync::atomic::Ordering::Relaxed),
        0
    );
    assert_eq!(r.error(), None);
}

#[test]
fn a_session_whose_recording_fails_goes_on_without_it() {
    let dir = temp();
    let config = SessionConfig {
        idle_timeout: None,
        recordings: Some(dir.path().join("missing")),
    };
    let session = Session::start("s4".into(), Scene::default_scene(), &config).unwrap();
    // The recorder thread fails at once; the RECORDER_ERROR event it causes may
    // come before anyone could subscribe (the recorder test checks the report),
    // so this checks what stays: the error, the count, no file named.
    let recorder = session.recorder().unwrap();
    while recorder.error().is_none() {
        std::thread::sleep(Duration::from_millis(2));
    }
    let error = recorder.error().unwrap();
    assert!(
        error.contains("s4-") && !error.contains("missing"),
        "{error}"
    );
    let tick = session
        .stats
        .tick
        .load(std::sync::atomic::Ordering::Relaxed);
    wait_ticks(&session, tick + 3);
    assert_eq!(session.info().recording_file, None);
    assert_eq!(
        session
            .recorder()
            .unwrap()
            .stats()
            .errors
            .load(std::sync::atomic::Ordering::Relaxed),
        1
    );
    session.close("test over");
    session.join();
}

#[test]
fn a_scripted_run_resimulates_with_zero_deviation_and_another_material_does_not() {
    let dir = temp();
    let path = dir.path().join("resim.mcap");
    let (frames, _, _) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();
    // The script pushed into the liver: there is something to reproduce.
    assert!(
        frames
            .iter()
            .any(|f| f.instruments[0].held_vertex_count > 0)
    );
    let mut seen = Vec::new();
    let same = resimulate(&rec, None, |t| seen.push(t)).unwrap();
    assert_eq!(seen, (1..=40).collect::<Vec<u64>>());
    assert_eq!(same.ticks_compared, 40);
    assert_eq!(same.steps, 40);
    assert!(same.is_exact(), "{same:?}");
    assert_eq!(same.worst_surface_tick, None);

    // A stiffer liver under the same hands deforms otherwise: the comparison sees
    // it (and the check above is not blind).
    let mut stiffer = rec.meta().clone();
    assert!(stiffer.scene_toml.contains("young_modulus = 4500.0"));
    stiffer.scene_toml = stiffer
        .scene_toml
        .replace("young_modulus = 4500.0", "young_modulus = 9000.0");
    let other = resimulate_as(&rec, &stiffer, None, |_| {}).unwrap();
    assert_eq!(other.ticks_compared, 40);
    assert!(other.max_surface_deviation_m > 1e-4, "{other:?}");
    assert!(other.max_force_deviation_n > 0.0, "{other:?}");
    assert!(!other.is_exact());
}

#[test]
fn resimulating_on_another_mesh_is_refused() {
    let dir = temp();
    let path = dir.path().join("mesh.mcap");
    record_script(&path, 3);
    let rec = Recording::open(&path).unwrap();
    let mut meta = rec.meta().clone();
    // The SOFA liver scene is a different mesh altogether.
    meta.scene_toml = include_str!("../../scenes/sofa-liver.toml").into();
    meta.scene_dir = Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"));
    let err = resimulate_as(&rec, &meta, None, |_| {}).unwrap_err();
    assert!(
        matches!(
            err,
            ResimError::MeshSize { .. } | ResimError::MeshMoved { .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("not the recorded one"), "{err}");
}

#[test]
fn the_duration_is_the_last_frames_time_from_the_index_or_every_frame() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (boundaries, bytes) = chunked(&path, 24, 5);
    let rec = Recording::open(&path).unwrap();
    assert!(rec.is_complete());
    let surfaces = rec.surfaces().unwrap();
    let last = surfaces.last().unwrap().message.sim_time_s;
    assert_eq!(rec.duration_s().unwrap().to_bits(), last.to_bits());
    assert_eq!(
        rec.duration_s().unwrap().to_bits(),
        summarize(&rec).unwrap().duration_s.to_bits()
    );
    // Cut after each closed chunk: read as far as it goes, the duration is that of
    // the last tick of the complete chunks, and nothing else is lost.
    for (k, &(cut, messages)) in boundaries.iter().enumerate().skip(1) {
        let cut_bytes = bytes[..cut as usize + 1].to_vec();
        assert!(matches!(
            Recording::from_bytes("cut".into(), cut_bytes.clone()),
            Err(ReadError::Truncated { .. })
        ));
        let partial = Recording::from_unfinished_bytes("cut".into(), cut_bytes).unwrap();
        assert!(!partial.is_complete());
        assert_eq!(partial.meta(), rec.meta());
        assert_eq!(partial.scene().unwrap(), rec.scene().unwrap());
        let ticks = (5 * k).min(24);
        assert_eq!(
            partial.duration_s().unwrap().to_bits(),
            surfaces[ticks - 1].message.sim_time_s.to_bits(),
            "cut after chunk {k}"
        );
        // messages() leaves out the Foxglove channel: a scene update every third
        // tick at 60 Hz.
        let drawn = (ticks as u64).div_ceil(foxglove_scene::stride(60.0));
        assert_eq!(partial.messages().count() as u64 + drawn, messages);
        assert_eq!(partial.surfaces().unwrap()[..], surfaces[..ticks]);
    }
    // Complete bytes read unfinished are just the recording.
    let whole = Recording::from_unfinished_bytes("whole".into(), bytes).unwrap();
    assert!(whole.is_complete());
    assert_eq!(whole.surfaces().unwrap(), surfaces);
}

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
fn a_recording_decodes_with_nothing_but_the_schemas_in_it() {
    use prost_reflect::{DescriptorPool, DynamicMessage, Value};
    let dir = temp();
    let path = dir.path().join("generic.mcap");
    let (frames, poses, _) = record_script(&path, 12);
    // A generic reader: the mcap crate's message stream, and for each message the
    // descriptors its channel's schema carries; nothing of the contract's types.
    let bytes = std::fs::read(&path).unwrap();
    let mut by_topic: std::collections::BTreeMap<String, Vec<DynamicMessage>> = Default::default();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        let pool = DescriptorPool::decode(&*schema.data).unwrap();
        let descriptor = pool
            .get_message_by_name(&schema.name)
            .unwrap_or_else(|| panic!("{} is not in its own schema", schema.name));
        let message = DynamicMessage::decode(descriptor, &*m.data).unwrap();
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push(message);
    }
    let field = |m: &DynamicMessage, name: &str| m.get_field_by_name(name).unwrap().into_owned();
    // Every tick's surface, field by field.
    let surfaces = &by_topic[TOPIC_SURFACE];
    assert_eq!(surfaces.len(), frames.len());
    for (m, f) in surfaces.iter().zip(&frames) {
        assert_eq!(field(m, "tick"), Value::U64(f.tick));
        assert_eq!(field(m, "sim_time_s"), Value::F64(f.sim_time));
        let Value::List(positions) = field(m, "positions") else {
            panic!("positions is not a list");
        };
        let positions: Vec<u32> = positions
            .iter()
            .map(|v| v.as_f32().unwrap().to_bits())
            .collect();
        assert_eq!(
            positions,
            f.surface.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
    // Every pose, with its nested tip.
    let recorded = &by_topic[TOPIC_POSES];
    assert_eq!(recorded.len(), poses.len());
    for (m, p) in recorded.iter().zip(&poses) {
        assert_eq!(field(m, "sequence"), Value::U64(p.sequence));
        let Value::Message(pose) = field(m, "pose") else {
            panic!("pose is not a message");
        };
        let Value::Message(tip) = field(&pose, "tip") else {
            panic!("tip is not a message");
        };
        assert_eq!(field(&tip, "z"), Value::F64(p.pose.unwrap().tip.unwrap().z));
    }
    // The instruments' states: the force, as the contract names it.
    let states = &by_topic[TOPIC_INSTRUMENTS];
    let expected: Vec<_> = frames.iter().flat_map(|f| f.instruments.clone()).collect();
    assert_eq!(states.len(), expected.len());
    let mut pushed = false;
    for (m, s) in states.iter().zip(&expected) {
        assert_eq!(field(m, "instrument"), Value::String(s.instrument.clone()));
        assert_eq!(
            field(m, "held_vertex_count"),
            Value::U32(s.held_vertex_count)
        );
        // The force's magnitude is a field of its own, for plotting.
        let Value::Message(force) = field(m, "force") else {
            panic!("force is not a message");
        };
        let f = s.force.unwrap().force.unwrap();
        let norm = (f.x * f.x + f.y * f.y + f.z * f.z).sqrt();
        let Value::F64(magnitude) = field(&force, "magnitude_n") else {
            panic!("magnitude_n is not a double");
        };
        assert!(
            (magnitude - norm).abs() <= 1e-12 * norm.max(1.0),
            "{magnitude} vs {norm}"
        );
        pushed |= magnitude > 0.0;
    }
    assert!(pushed, "the script never pushed");
    // Foxglove's scene updates decode with their own schema: the liver and every
    // instrument with its force arrow.
    let updates = &by_topic[TOPIC_FOXGLOVE_SCENE];
    assert!(!updates.is_empty());
    for u in updates {
        let Value::List(entities) = field(u, "entities") else {
            panic!("entities is not a list");
        };
        assert_eq!(entities.len(), 1 + 2 * frames[0].instruments.len());
    }
    assert_eq!(by_topic[TOPIC_SCENE].len(), 1);
}
