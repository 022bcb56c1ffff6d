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
fn a_session_whose_recording_name_is_taken_records_beside_it() {
    // As after a restart within the second: a file of the name `s1` would take.
    let dir = temp();
    let config = SessionConfig {
        idle_timeout: None,
        recordings: Some(dir.path().to_path_buf()),
    };
    // The first server's session, its file written and closed as the server
    // stopped; then the restarted server's `s1`.
    let first = Session::start("s1".into(), Scene::default_scene(), &config).unwrap();
    let taken = first.info().recording_file.unwrap();
    wait_ticks(&first, 3);
    first.close("server stopped");
    first.join();
    let second = Session::start("s1".into(), Scene::default_scene(), &config).unwrap();
    let file = second.info().recording_file.unwrap();
    wait_ticks(&second, 3);
    second.close("test over");
    second.join();
    // Within the same second the name is the first's with `-2`; a second later,
    // a name of its own.
    assert!(
        file != taken && file.starts_with("s1-default-"),
        "{taken} then {file}"
    );
    if file.len() > taken.len() {
        assert_eq!(file, taken.replace(".mcap", "-2.mcap"));
    }
    assert!(
        second.info().recording_error.is_none(),
        "{:?}",
        second.info()
    );
    // Both recordings read back whole, each its own session's.
    for f in [&taken, &file] {
        let rec = Recording::open(&dir.path().join(f)).unwrap();
        assert!(rec.is_complete(), "{f}");
        assert_eq!(rec.meta().session_id, "s1");
    }
}

#[test]
fn a_free_recording_name_counts_up_past_the_taken_ones() {
    let dir = temp();
    let at = std::time::UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    let name = |p: PathBuf| p.file_name().unwrap().to_string_lossy().into_owned();
    let free = || free_recording_path(dir.path(), "s1", "liver 5k", at);
    assert_eq!(name(free()), "s1-liver_5k-1800000000.mcap");
    std::fs::write(free(), b"").unwrap();
    assert_eq!(name(free()), "s1-liver_5k-1800000000-2.mcap");
    std::fs::create_dir(free()).unwrap();
    assert_eq!(name(free()), "s1-liver_5k-1800000000-3.mcap");
}

#[test]
fn a_scene_with_the_longest_name_records_into_a_file_the_system_creates() {
    // A scene may be named with 256 bytes; a file name may hold 255. The scene's
    // part is cut, so the name stays creatable with the largest id, time and suffix.
    let dir = temp();
    let scene = "é".repeat(128);
    assert_eq!(scene.len(), 256);
    let id = format!("s{}", u64::MAX);
    let at = std::time::UNIX_EPOCH + Duration::from_secs(u64::MAX / 2);
    let name = recording_file_name(&id, &scene, at);
    assert!(
        name.len() + "-1000".len() <= 255,
        "{} bytes: {name}",
        name.len()
    );
    let path = free_recording_path(dir.path(), &id, &scene, at);
    std::fs::write(&path, b"").unwrap();
    let taken = path.with_file_name(name.replace(".mcap", "-1000.mcap"));
    std::fs::write(taken, b"").unwrap();
}
