//! A recorded session: its ticks, poses and events in the file, and a session that
//! goes on when its recording fails.

use super::*;

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
    let poses: Vec<_> = (0..5).map(|k| device_pose(&session, k)).collect();
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
    assert!(recorder.error().unwrap().contains("missing"));
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
