//! The recordings directory cannot hurt the server: files cut short or rewritten
//! while they are replayed, large unfinished files listed concurrently, links out
//! of the directory, names that are terminal escapes, files that never got their
//! header, and files with nothing to recover. Each against a real server on a
//! loopback port where the server is what is tested.

use std::path::{Path, PathBuf};
use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_tests::recordings::{create_recorded, recording_server, recordings_dir, run_until};
use laparo_tests::server::TestServer;
use tonic::Code;
use tonic::transport::Channel;

/// Longest any step here may take before the test fails rather than hangs.
const WAIT: Duration = Duration::from_secs(60);

/// Records a session of the default scene through the server until it has run
/// `at_least_s` of simulated time, closes it (which finishes the file), and
/// returns the file's path.
async fn record(ch: &Channel, dir: &Path, at_least_s: f64) -> PathBuf {
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = create_recorded(&mut sessions).await;
    let file = dir.join(
        info.recording_file
            .expect("a recorded session names its file"),
    );
    run_until(&mut sessions, &info.session_id, at_least_s).await;
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: info.session_id,
            reason: "recorded".into(),
        })
        .await
        .unwrap();
    file
}

fn recordings(ch: &Channel) -> v1::recordings_client::RecordingsClient<Channel> {
    v1::recordings_client::RecordingsClient::new(ch.clone())
}

/// Replays `file` at `speed` and reads until the first surface frame.
async fn replay_to_first_frame(
    ch: &Channel,
    file: &str,
    speed: f64,
) -> tonic::Streaming<v1::ObserveMessage> {
    let mut stream = recordings(ch)
        .replay(v1::ReplayRequest {
            file: file.into(),
            speed: Some(speed),
            start_offset_s: None,
            mode: v1::ReplayMode::Recorded as i32,
        })
        .await
        .unwrap()
        .into_inner();
    tokio::time::timeout(WAIT, async {
        loop {
            let m = stream.message().await.unwrap().expect("a frame comes");
            if matches!(m.kind, Some(v1::observe_message::Kind::SurfaceFrame(_))) {
                return;
            }
        }
    })
    .await
    .expect("the replay starts");
    stream
}

/// Reads `stream` to its end: the status it ends with (`None`: OK).
async fn end_of(mut stream: tonic::Streaming<v1::ObserveMessage>) -> Option<tonic::Status> {
    tokio::time::timeout(WAIT, async {
        loop {
            match stream.message().await {
                Ok(Some(_)) => {}
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .expect("the replay ends")
}

/// The top-level records of an MCAP file's bytes: opcode, start, end.
fn records(bytes: &[u8]) -> Vec<(u8, usize, usize)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        let end = at + 9 + len;
        if end > bytes.len() {
            break;
        }
        out.push((bytes[at], at, end));
        if bytes[at] == 0x0F {
            break;
        }
        at = end;
    }
    out
}

/// A file as a server stopped mid-session would leave it, but of at least `size`
/// bytes: the finished recording `bytes` up to its metadata, then its chunks of
/// ticks (with their message indexes) over and over, without data end, summary or
/// footer. Its newest frame is the recording's last.
fn unfinished_of_size(bytes: &[u8], size: usize) -> Vec<u8> {
    let records = records(bytes);
    let metadata = records
        .iter()
        .position(|r| r.0 == 0x0C)
        .expect("a metadata record");
    let head_end = records[metadata].2;
    let data_end = records.iter().find(|r| r.0 == 0x0F).expect("a data end").1;
    let ticks = &bytes[head_end..data_end];
    assert!(!ticks.is_empty());
    let mut out = bytes[..head_end].to_vec();
    while out.len() < size {
        out.extend_from_slice(ticks);
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_cut_or_rewritten_while_replayed_ends_its_replay_with_data_loss_only() {
    let (server, ch, dir) = recording_server("cut").await;
    let path = record(&ch, &dir, 3.0).await;
    let name = path.file_name().unwrap().to_str().unwrap().to_string();
    let bytes = std::fs::read(&path).unwrap();
    let dir_text = dir.display().to_string();

    // Cut to a third in place while it plays: the reading that reaches the cut
    // ends the stream with DATA_LOSS naming the file, relative to the directory.
    let stream = replay_to_first_frame(&ch, &name, 2.0).await;
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(bytes.len() as u64 / 3)
        .unwrap();
    let status = end_of(stream).await.expect("the replay ends with an error");
    assert_eq!(status.code(), Code::DataLoss, "{status:?}");
    assert!(status.message().contains(&name), "{}", status.message());
    assert!(
        !status.message().contains(&dir_text),
        "{}",
        status.message()
    );

    // Rewritten in place with other bytes of the same length while it plays.
    std::fs::write(&path, &bytes).unwrap();
    let stream = replay_to_first_frame(&ch, &name, 2.0).await;
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .and_then(|f| std::os::unix::fs::FileExt::write_all_at(&f, &vec![0xAB; bytes.len() - 8], 8))
        .unwrap();
    let status = end_of(stream).await.expect("the replay ends with an error");
    assert_eq!(status.code(), Code::DataLoss, "{status:?}");
    assert!(status.message().contains(&name), "{}", status.message());

    // The server is still up, and says what the file is now.
    let listed = recordings(&ch)
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert!(listed.recordings.iter().all(|r| r.file != name));
    std::fs::write(&path, &bytes).unwrap();
    let listed = recordings(&ch)
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(listed.recordings.len(), 1);
    assert_eq!(listed.recordings[0].file, name);
    assert!(
        end_of(replay_to_first_frame(&ch, &name, 100.0).await)
            .await
            .is_none()
    );
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_large_unfinished_file_lists_from_its_first_and_last_chunks_once_however_many_ask() {
    use laparo_server::recording::{FileState, Lister, Recording};
    /// What one listing of the large file may read: its first chunk (schemas,
    /// scene), metadata, the 9-byte prefixes of its records and its newest chunk.
    const CAP: u64 = 4 << 20;
    /// The large file: sixteen times the cap.
    const SIZE: usize = 64 << 20;

    let (server, ch, dir) = recording_server("large").await;
    let path = record(&ch, &dir, 1.5).await;
    let finished = Recording::open(&path).unwrap();
    let duration = finished.duration_s().unwrap();
    assert!(duration >= 1.5);
    let bytes = std::fs::read(&path).unwrap();
    let big = dir.join("big.mcap");
    std::fs::write(&big, unfinished_of_size(&bytes, SIZE)).unwrap();
    drop(bytes);
    let size = std::fs::metadata(&big).unwrap().len();

    // Four listings at once through one lister: one reads the file, within the
    // cap, and the others find its answer cached.
    let lister = Lister::new();
    let read: Vec<(u64, f64, FileState)> = std::thread::scope(|s| {
        let listings: Vec<_> = (0..4)
            .map(|_| {
                s.spawn(|| {
                    let listed = lister.list(&dir, |_| false).unwrap();
                    let l = listed.iter().find(|l| l.file == "big.mcap").unwrap();
                    assert_eq!(l.size_bytes, size);
                    let e = l.entry.as_ref().unwrap();
                    (l.bytes_read, e.duration_s, e.state)
                })
            })
            .collect();
        listings.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let total: u64 = read.iter().map(|r| r.0).sum();
    assert!(total > 0 && total < CAP, "{total} bytes read of {size}");
    assert_eq!(read.iter().filter(|r| r.0 > 0).count(), 1, "{read:?}");
    for (_, d, state) in read {
        assert_eq!(d.to_bits(), duration.to_bits());
        assert_eq!(state, FileState::Unfinished);
    }
    // Through the server: six listings at once, each with the finished recording
    // and the large unfinished file, with its state and real duration.
    let calls: Vec<_> = (0..6)
        .map(|_| {
            let mut client = recordings(&ch);
            tokio::spawn(async move {
                client
                    .list_recordings(v1::ListRecordingsRequest {})
                    .await
                    .map(|r| r.into_inner().recordings)
            })
        })
        .collect();
    let finished_name = path.file_name().unwrap().to_str().unwrap();
    for call in calls {
        let listed = tokio::time::timeout(WAIT, call)
            .await
            .expect("listing ends")
            .unwrap()
            .unwrap();
        assert_eq!(listed.len(), 2, "{listed:?}");
        let big = listed.iter().find(|r| r.file == "big.mcap").unwrap();
        assert_eq!(big.state, v1::RecordingState::Unfinished as i32);
        assert!(!big.in_progress);
        assert_eq!(big.size_bytes, size);
        assert_eq!(big.duration_s.to_bits(), duration.to_bits());
        let done = listed.iter().find(|r| r.file == finished_name).unwrap();
        assert_eq!(done.state, v1::RecordingState::Complete as i32);
        assert_eq!(done.duration_s.to_bits(), duration.to_bits());
    }
    // An unfinished file is listed but not replayed until recovered.
    let status = recordings(&ch)
        .replay(v1::ReplayRequest {
            file: "big.mcap".into(),
            speed: None,
            start_offset_s: None,
            mode: 0,
        })
        .await
        .unwrap_err();
    assert_eq!(status.code(), Code::FailedPrecondition);
    assert!(status.message().contains("recover"), "{status:?}");

    // A change to the file is read again.
    std::fs::OpenOptions::new()
        .append(true)
        .open(&big)
        .and_then(|mut f| std::io::Write::write_all(&mut f, &[0; 5]))
        .unwrap();
    let listed = lister.list(&dir, |_| false).unwrap();
    let l = listed.iter().find(|l| l.file == "big.mcap").unwrap();
    assert!(l.bytes_read > 0 && l.bytes_read < CAP);
    assert_eq!(l.size_bytes, size + 5);
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Whether `text` holds a character a terminal would act on.
fn has_control(text: &str) -> bool {
    text.chars().any(laparo_proto::text::needs_escape)
}

/// A server recording to a new directory `label` and offering the scenes of the
/// directory `scenes`, and the file of a session of scene `scene` it recorded and
/// closed.
async fn record_scene_of(
    label: &str,
    scenes: &Path,
    scene: &str,
) -> (TestServer, Channel, PathBuf, String) {
    let dir = recordings_dir(label);
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        scene_dir: Some(scenes.to_path_buf()),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = sessions
        .create_session(v1::CreateSessionRequest {
            scene: scene.into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await
        .unwrap()
        .into_inner();
    let recorded = info.recording_file.clone().unwrap();
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: info.session_id.clone(),
            reason: "recorded".into(),
        })
        .await
        .unwrap();
    (server, ch, dir, recorded)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_regular_files_of_the_directory_are_served_and_nothing_echoes_escapes() {
    // A scene whose name is terminal escapes: it reaches the recording's metadata.
    let scenes = recordings_dir("escape-scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let evil = "evil\u{1b}]0;owned\u{7}\u{1b}[2J";
    let toml = include_str!("../../server/scenes/default.toml").replace(
        "name = \"default\"",
        "name = \"evil\\u001b]0;owned\\u0007\\u001b[2J\"",
    );
    std::fs::write(scenes.join("evil.toml"), toml).unwrap();
    let (server, ch, dir, recorded) = record_scene_of("escape", &scenes, evil).await;
    assert!(!has_control(&recorded));

    // Beside it: a link to a recording outside the directory, links to a device
    // and to a FIFO, a FIFO, a directory, and a file named with escapes.
    let outside = recordings_dir("escape-outside");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::copy(dir.join(&recorded), outside.join("secret.mcap")).unwrap();
    let link = |to: &Path, name: &str| std::os::unix::fs::symlink(to, dir.join(name)).unwrap();
    link(&outside.join("secret.mcap"), "link.mcap");
    link(Path::new("/dev/zero"), "zero.mcap");
    let fifo = dir.join("fifo.mcap");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    link(&fifo, "to-fifo.mcap");
    std::fs::create_dir(dir.join("dir.mcap")).unwrap();
    let escaped_name = "\u{1b}[2J.mcap";
    std::fs::copy(dir.join(&recorded), dir.join(escaped_name)).unwrap();

    let listed = tokio::time::timeout(
        WAIT,
        recordings(&ch).list_recordings(v1::ListRecordingsRequest {}),
    )
    .await
    .expect("listing does not hang on a FIFO or a device")
    .unwrap()
    .into_inner();
    let files: Vec<&str> = listed.recordings.iter().map(|r| r.file.as_str()).collect();
    assert_eq!(files, [recorded.as_str()]);
    let r = &listed.recordings[0];
    assert_eq!(r.scene, laparo_proto::text::printable(evil));
    assert!(!has_control(&r.scene) && !has_control(&r.session_id));

    // Replays: a link or a device is no recording of this directory; an escaped
    // name is refused, and echoed escaped.
    let replay = |file: &str| {
        let mut client = recordings(&ch);
        let request = v1::ReplayRequest {
            file: file.into(),
            speed: Some(100.0),
            start_offset_s: None,
            mode: v1::ReplayMode::Recorded as i32,
        };
        async move {
            tokio::time::timeout(WAIT, client.replay(request))
                .await
                .unwrap()
        }
    };
    for file in [
        "link.mcap",
        "zero.mcap",
        "fifo.mcap",
        "to-fifo.mcap",
        "dir.mcap",
    ] {
        let status = replay(file).await.expect_err(file);
        assert_eq!(status.code(), Code::NotFound, "{file}: {status:?}");
    }
    let status = replay(escaped_name).await.unwrap_err();
    assert_eq!(status.code(), Code::InvalidArgument);
    assert!(!has_control(status.message()), "{:?}", status.message());
    assert!(
        status.message().contains("\\u{1b}[2J.mcap"),
        "{:?}",
        status.message()
    );
    assert!(replay(&recorded).await.is_ok());
    server.shutdown().await.unwrap();
    for d in [&dir, &scenes, &outside] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recordings_directory_removed_is_made_again_and_one_replaced_is_refused_by_name() {
    let (server, ch, dir) = recording_server("gone").await;
    // An answered call means the server runs, so it has made its recordings
    // directory (serving starts after that); then the directory goes away.
    let _ = recordings(&ch)
        .list_recordings(v1::ListRecordingsRequest {})
        .await;
    std::fs::remove_dir_all(&dir).unwrap();
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let create = v1::CreateSessionRequest {
        scene: "default".into(),
        idle_timeout_s: None,
        record: Some(true),
    };
    // Removed, it is made again, and the session is recorded there.
    let info = sessions
        .create_session(create.clone())
        .await
        .unwrap()
        .into_inner();
    let file = info.recording_file.expect("recorded");
    assert!(
        dir.join(&file).is_file(),
        "{file} in the directory made again"
    );
    // Replaced by a file, it cannot be: the session is refused, naming the
    // flag and not the server's path.
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::write(&dir, b"not a directory").unwrap();
    let status = sessions.create_session(create).await.unwrap_err();
    assert_eq!(status.code(), Code::FailedPrecondition);
    assert!(status.message().contains("--recordings"), "{status:?}");
    assert!(!status.message().contains("/tmp"), "{status:?}");
    // Listing a directory that is not one says so, without its path.
    let status = recordings(&ch)
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap_err();
    assert_eq!(status.code(), Code::FailedPrecondition);
    assert!(
        !status.message().contains(&dir.display().to_string()),
        "{status:?}"
    );
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_file(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_whose_mesh_is_gone_cannot_be_resimulated_and_says_so_without_server_paths() {
    // A scene of a scene directory, reading its mesh from a file there.
    let scenes = recordings_dir("resim-scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let toml = include_str!("../../server/scenes/default.toml")
        .replace("name = \"default\"", "name = \"from-file\"")
        .replace("builtin:liver.msh", "liver.msh");
    std::fs::write(scenes.join("from-file.toml"), toml).unwrap();
    std::fs::write(
        scenes.join("liver.msh"),
        include_bytes!("../../server/meshes/liver.msh"),
    )
    .unwrap();
    let (server, ch, dir, recorded) = record_scene_of("resim-gone", &scenes, "from-file").await;
    std::fs::remove_file(scenes.join("liver.msh")).unwrap();
    let request = v1::ReplayRequest {
        file: recorded.clone(),
        speed: Some(100.0),
        start_offset_s: None,
        mode: v1::ReplayMode::Resimulate as i32,
    };
    let status = match tokio::time::timeout(WAIT, recordings(&ch).replay(request))
        .await
        .unwrap()
    {
        Err(status) => status,
        Ok(stream) => end_of(stream.into_inner())
            .await
            .expect("the replay ends with an error"),
    };
    assert_eq!(status.code(), Code::FailedPrecondition, "{status:?}");
    let message = status.message();
    assert!(message.contains(&recorded), "{message}");
    assert!(message.contains("liver.msh"), "{message}");
    assert!(
        !message.contains(&*scenes.to_string_lossy()) && !message.contains("/tmp"),
        "{message}"
    );
    server.shutdown().await.unwrap();
    for d in [&dir, &scenes] {
        let _ = std::fs::remove_dir_all(d);
    }
}
