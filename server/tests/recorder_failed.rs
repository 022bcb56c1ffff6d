//! A recorder that fails while its session runs, as one does when the disk fills: a
//! real server whose process may write files of at most [`FILE_LIMIT`] bytes
//! (`RLIMIT_FSIZE`, with `SIGXFSZ` ignored so that the write past it fails with
//! `EFBIG` rather than killing the process). The listing must not call the file
//! "unfinished: its server stopped" while that server answers it.

use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use laparo_proto::v1;
use tonic::Code;

mod common;
use common::process::{Server, connect, create_recorded_session, free_port};

/// The largest file the server's process may write, bytes: its recording's header
/// and first chunk fit, so the file can be listed (at 256 KiB the first chunk did
/// not), and an idle default scene's frames pass it within about three seconds.
const FILE_LIMIT: u64 = 512 * 1024;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_whose_recorder_failed_is_listed_as_failed_with_why() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let mut command = Command::new(env!("CARGO_BIN_EXE_laparo-server"));
    command
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .arg("--recordings")
        .arg(dir.path())
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit());
    // SAFETY: signal and setrlimit are async-signal-safe; the child runs nothing
    // else first. An ignored signal stays ignored across exec.
    unsafe {
        command.pre_exec(|| {
            if libc::signal(libc::SIGXFSZ, libc::SIG_IGN) == libc::SIG_ERR {
                return Err(std::io::Error::last_os_error());
            }
            let limit = libc::rlimit {
                rlim_cur: FILE_LIMIT,
                rlim_max: FILE_LIMIT,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let _server = Server(command.spawn().unwrap());
    let ch = connect(port).await;
    let (id, path) = create_recorded_session(ch.clone(), "default", dir.path()).await;
    let file = path.file_name().unwrap().to_string_lossy().into_owned();

    // Its recorder fails once the file reaches the limit; the session goes on.
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let deadline = Instant::now() + Duration::from_secs(60);
    let error = loop {
        let info = sessions
            .get_session(v1::GetSessionRequest {
                session_id: id.clone(),
            })
            .await
            .expect("the session goes on without its recording")
            .into_inner();
        if let Some(e) = info.recording_error {
            break e;
        }
        assert!(
            Instant::now() < deadline,
            "the recording never reached {FILE_LIMIT} bytes"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert!(error.contains("File too large"), "{error}");

    let mut recordings = v1::recordings_client::RecordingsClient::new(ch);
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner();
    let entry = listed
        .recordings
        .iter()
        .find(|r| r.file == file)
        .unwrap_or_else(|| panic!("{file} is listed: {listed:?}"));
    assert_eq!(
        entry.state,
        v1::RecordingState::Failed as i32,
        "not unfinished: its server answers: {entry:?}"
    );
    assert!(!entry.in_progress);
    assert_eq!(
        entry.failure, error,
        "the listing says why, as the session did"
    );
    assert!(
        !entry.failure.contains(&*dir.path().to_string_lossy()),
        "named by its file alone: {}",
        entry.failure
    );

    let refused = recordings
        .replay(v1::ReplayRequest {
            file: file.clone(),
            ..Default::default()
        })
        .await
        .expect_err("a file without its summary is not replayed");
    assert_eq!(refused.code(), Code::FailedPrecondition);
    assert!(
        refused.message().contains("its recorder failed")
            && refused.message().contains("File too large")
            && refused.message().contains("recover"),
        "{}",
        refused.message()
    );
}
