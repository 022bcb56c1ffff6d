//! Who may replay what, a recording refused for want of room, a server that
//! records nothing, and clients told of a recorder that failed before they came.

use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::{Role, ServeConfig};
use laparo_tests::recordings::*;
use laparo_tests::server::*;
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trainees_review_recordings_and_only_instructors_watch_one_being_made() {
    let tokens = tokens(&[
        ("instructor-token", "instructor", Role::Instructor, None),
        ("trainee-token", "trainee", Role::Trainee, None),
    ]);
    let dir = recordings_dir("replay-roles");
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        tokens: Some(tokens),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let (teacher, trainee) = (Some("instructor-token"), Some("trainee-token"));
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let session = sessions
        .create_session(with_token(
            v1::CreateSessionRequest {
                scene: "default".into(),
                idle_timeout_s: None,
                record: Some(true),
            },
            teacher,
        ))
        .await
        .unwrap()
        .into_inner();
    let name = session.recording_file.clone().unwrap();
    let get = || {
        with_token(
            v1::GetSessionRequest {
                session_id: session.session_id.clone(),
            },
            teacher,
        )
    };
    tokio::time::timeout(WAIT, async {
        while sessions
            .get_session(get())
            .await
            .unwrap()
            .into_inner()
            .sim_time_s
            < 1.0
        {
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    })
    .await
    .unwrap();
    let mut recordings = v1::recordings_client::RecordingsClient::new(ch.clone());
    let lister = recordings.clone();
    let list = |token| {
        let mut r = lister.clone();
        async move {
            r.list_recordings(with_token(v1::ListRecordingsRequest {}, token))
                .await
                .map(|r| r.into_inner().recordings)
        }
    };
    assert_eq!(
        list(None).await.err().map(|s| s.code()),
        Some(Code::Unauthenticated)
    );
    // Being recorded: listed in progress with what its closed chunks hold.
    let listed = list(trainee).await.unwrap();
    assert_eq!(listed.len(), 1);
    let now = sessions.get_session(get()).await.unwrap().into_inner();
    let so_far = &listed[0];
    assert_eq!(
        (so_far.file.as_str(), so_far.session_id.as_str()),
        (name.as_str(), session.session_id.as_str())
    );
    assert!(so_far.in_progress);
    assert!(so_far.duration_s <= now.sim_time_s, "{so_far:?}");
    // Watching it is observing: an instructor's right.
    let refused = recordings
        .replay(with_token(
            replay_request(&name, Some(100.0), None),
            trainee,
        ))
        .await;
    assert_eq!(
        refused.err().map(|s| s.code()),
        Some(Code::PermissionDenied)
    );
    let (got, end) = replay_all(&ch, teacher, replay_request(&name, Some(100.0), None))
        .await
        .unwrap();
    // It ends where the file stood when the replay opened it, and says so: the
    // session goes on, and its end is not the recording's.
    let end = end.expect_err("a replay of a recording in progress ends saying so");
    assert_eq!(end.code(), Code::OutOfRange, "{end:?}");
    assert!(
        end.message().contains("still being recorded")
            && end.message().contains(&format!("`{name}` up to")),
        "{end:?}"
    );
    // The client says it as the replay's end, not as a failure.
    let mut watch = laparo_client::observe::ObserveConfig::replay(
        format!("http://{}", server.addr),
        replay_request(&name, Some(100.0), None),
    );
    watch.connect.token = teacher.map(String::from);
    let summary = laparo_client::observe::run_observe(watch, |_| {})
        .await
        .unwrap();
    assert!(summary.server_closed && summary.frames > 0, "{summary:?}");
    let note = summary.end_note.unwrap_or_default();
    assert!(note.contains("still being recorded"), "{note}");
    assert!(matches!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let ticks: Vec<u64> = got
        .iter()
        .filter_map(|(_, m)| match &m.kind {
            Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some(f.tick),
            _ => None,
        })
        .collect();
    assert!(!ticks.is_empty());
    assert!(
        ticks.iter().zip(1..).all(|(t, k)| *t == k),
        "the ticks so far, from 1: {ticks:?}"
    );
    // Finished: anyone reviews it.
    sessions
        .close_session(with_token(
            v1::CloseSessionRequest {
                session_id: session.session_id.clone(),
                reason: "test over".into(),
            },
            teacher,
        ))
        .await
        .unwrap();
    let listed = list(trainee).await.unwrap();
    assert!(!listed[0].in_progress);
    assert!(listed[0].duration_s >= so_far.duration_s);
    let (got, end) = replay_all(&ch, trainee, replay_request(&name, Some(100.0), None))
        .await
        .unwrap();
    end.unwrap();
    let frames = got.iter().filter(|(_, m)| bits(m).is_some()).count();
    assert!(frames >= ticks.len());
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_session_without_room_for_its_file_is_refused_naming_the_limit() {
    // No file system has u64::MAX bytes free: every recording lacks room.
    let dir = recordings_dir("no-room");
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        recordings_min_free: Some(u64::MAX),
        ..ServeConfig::default()
    })
    .await;
    let mut sessions = v1::sessions_client::SessionsClient::new(server.channel().await);
    let refused = sessions.create_session(create(true)).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(
        refused.message().contains("MiB free, under the")
            && refused.message().contains("MIN_FREE_BYTES"),
        "{refused:?}"
    );
    // Nothing was written, and the refusal held no session's place.
    let files = std::fs::read_dir(&dir).map(|d| d.count()).unwrap_or(0);
    assert_eq!(files, 0);
    assert!(
        sessions
            .list_sessions(v1::ListSessionsRequest {})
            .await
            .unwrap()
            .into_inner()
            .sessions
            .is_empty()
    );
    // Unrecorded, the same scene starts.
    let session = sessions.create_session(create(false)).await.unwrap();
    assert!(session.into_inner().recording_file.is_none());
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_that_records_nothing_says_so() {
    let server = TestServer::start(ServeConfig::default()).await;
    let mut recordings = v1::recordings_client::RecordingsClient::new(server.channel().await);
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await;
    let status = listed.err().unwrap();
    assert_eq!(status.code(), Code::FailedPrecondition);
    assert!(
        status.message().contains("records no sessions"),
        "{status:?}"
    );
    let replayed = recordings
        .replay(replay_request("s1-default-1.mcap", None, None))
        .await;
    assert_eq!(
        replayed.err().map(|s| s.code()),
        Some(Code::FailedPrecondition)
    );
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stations_and_observers_joining_after_the_recorder_failed_are_told() {
    // A recordings directory whose path leaves no room for a file name: it is a
    // directory with room (the session starts, recorded), and the recorder cannot
    // create its file in it (`ENAMETOOLONG`: a path of more than 4,095 bytes), as a
    // recorder fails whose disk fails it.
    let blocker = std::env::temp_dir().join(format!("laparo-blocker-{}", std::process::id()));
    let mut dir = blocker.clone();
    while dir.as_os_str().len() < 3800 {
        dir.push("d".repeat(200));
    }
    dir.push("d".repeat(4080 - dir.as_os_str().len() - 1));
    assert_eq!(dir.as_os_str().len(), 4080);
    std::fs::create_dir_all(&dir).unwrap();
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = create_recorded(&mut sessions).await;
    // Wait until the failure is known (nobody was connected to hear it live).
    let error = tokio::time::timeout(WAIT, async {
        loop {
            let info = sessions
                .get_session(v1::GetSessionRequest {
                    session_id: info.session_id.clone(),
                })
                .await
                .unwrap()
                .into_inner();
            if let Some(e) = info.recording_error {
                break (e, info.recording_file);
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("the recorder's failure shows in the session's info");
    // Named by the file alone: clients know no server paths.
    assert!(error.0.contains(".mcap"), "{}", error.0);
    assert!(!error.0.contains("laparo-blocker"), "{}", error.0);
    assert_eq!(error.1, None, "no file is named when none was created");

    let is_recorder_error = |m: &v1::ServerMessage| {
        matches!(&m.kind, Some(v1::server_message::Kind::Event(e))
            if e.kind == v1::EventKind::RecorderError as i32 && e.detail.contains(&error.0))
    };
    let (mut a, _) = join(ch.clone(), None, &info.session_id, &["left"])
        .await
        .unwrap();
    // Told right after Joined, before any frame.
    let first = a.rx.message().await.unwrap().unwrap();
    assert!(is_recorder_error(&first), "{first:?}");
    // And the session goes on: frames keep coming.
    assert!(
        wait_for(&mut a.rx, WAIT, |m| matches!(
            m.kind,
            Some(v1::server_message::Kind::SurfaceFrame(_))
        ))
        .await
        .is_some()
    );

    let mut observer = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: info.session_id.clone(),
            frame_rate_hz: None,
        })
        .await
        .unwrap()
        .into_inner();
    let scene = observer.message().await.unwrap().unwrap();
    assert!(matches!(
        scene.kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let told = observer.message().await.unwrap().unwrap();
    assert!(
        matches!(&told.kind, Some(v1::observe_message::Kind::Event(e))
            if e.kind == v1::EventKind::RecorderError as i32),
        "{told:?}"
    );
    drop((a, observer));
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&blocker);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_session_where_the_recordings_directory_is_a_file_is_refused() {
    // A `--recordings` that names a file, or a loop of links: before the check,
    // the session answered with the name of a recording its recorder failed to
    // create a tick later.
    let base = std::env::temp_dir().join(format!("laparo-not-a-dir-{}", std::process::id()));
    std::fs::create_dir_all(&base).unwrap();
    let file = base.join("file");
    std::fs::write(&file, b"not a directory").unwrap();
    let looped = base.join("loop");
    std::os::unix::fs::symlink(&looped, &looped).unwrap();
    for (dir, what) in [
        (file, "is not a directory"),
        (looped, "cannot be made or reached"),
    ] {
        let server = TestServer::start(ServeConfig {
            recordings: Some(dir),
            ..ServeConfig::default()
        })
        .await;
        let mut sessions = v1::sessions_client::SessionsClient::new(server.channel().await);
        let refused = sessions.create_session(create(true)).await.unwrap_err();
        assert_eq!(refused.code(), Code::FailedPrecondition, "{refused:?}");
        let message = refused.message();
        assert!(
            message.contains("(--recordings) ") && message.contains(what),
            "{message}"
        );
        assert!(
            !message.contains("laparo-not-a-dir"),
            "no server path: {message}"
        );
        let session = sessions.create_session(create(false)).await.unwrap();
        assert!(session.into_inner().recording_file.is_none());
        server.shutdown().await.unwrap();
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A session of the default scene, recorded or not.
fn create(record: bool) -> v1::CreateSessionRequest {
    v1::CreateSessionRequest {
        scene: "default".into(),
        idle_timeout_s: None,
        record: Some(record),
    }
}
