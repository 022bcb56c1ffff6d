//! Standard output and standard error that cannot be written: a reader that closed
//! its pipe (`laparo-server run … | head -3`, a log piped to a killed `tee`) or a
//! full disk under a redirection. The run and the server go on as if the lines had
//! been written; nothing panics (status 101), no file is left unwritten.

use std::fs::File;
use std::process::{Command, Stdio};
use std::time::Duration;

use laparo_proto::v1;
use laparo_server::recording::Recording;

mod common;
use common::process::{Server, connect, create_recorded_session, free_port, terminate};

/// A run of 1 s that writes a series of a frame every 0.1 s (the start and ten
/// more) as `s.pvd` and the final state as `end.vtu` in a fresh folder: the folder
/// and the command.
fn run_with_files() -> (tempfile::TempDir, Command) {
    let dir = tempfile::tempdir().unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_laparo-server"));
    command
        .args(["run", "--seconds", "1", "--export-every", "0.1"])
        .arg(dir.path().join("s.pvd"))
        .arg("--export")
        .arg(dir.path().join("end.vtu"));
    (dir, command)
}

/// The frames `s.pvd` lists, and whether `end.vtu` was written.
fn written(dir: &tempfile::TempDir) -> (usize, bool) {
    let pvd = std::fs::read_to_string(dir.path().join("s.pvd")).expect("the series is written");
    let frames = pvd.matches("<DataSet").count();
    (frames, dir.path().join("end.vtu").is_file())
}

/// A pipe whose reader is already gone, as the writing end for a child: its first
/// write fails with `BrokenPipe` (Rust ignores `SIGPIPE`), as every write after a
/// `| head -1` has read its line does, without a race on when the reader leaves.
fn closed_pipe() -> Stdio {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    Stdio::from(writer)
}

#[test]
fn a_run_whose_reader_left_writes_every_file_and_exits_0() {
    let (dir, mut command) = run_with_files();
    let out = command.stdout(closed_pipe()).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
    assert_eq!(written(&dir), (11, true));
}

#[test]
fn a_run_whose_output_is_a_full_disk_writes_every_file_and_says_why_it_failed() {
    let (dir, mut command) = run_with_files();
    let out = command
        .stdout(File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cannot write to standard output: No space left on device")
            && stderr.contains("went to its end"),
        "{stderr}"
    );
    assert_eq!(written(&dir), (11, true), "{stderr}");
}

/// A server whose log goes to a pipe nobody reads any more logs every request and
/// its shutdown into it: each such line fails to be written. It used to panic on the
/// first (the session's creation: its caller saw "stream no longer needed" and the
/// session stayed, taking a slot), and on the shutdown's (status 101, the recording
/// left without its summary).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_whose_log_cannot_be_written_serves_and_finishes_its_recording() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let child = Command::new(env!("CARGO_BIN_EXE_laparo-server"))
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .arg("--recordings")
        .arg(dir.path())
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(closed_pipe())
        .spawn()
        .unwrap();
    let mut server = Server(child);
    let ch = connect(port).await;
    let (id, path) = create_recorded_session(ch.clone(), "default", dir.path()).await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch);
    let info = sessions
        .get_session(v1::GetSessionRequest {
            session_id: id.clone(),
        })
        .await
        .expect("the session runs")
        .into_inner();
    assert_eq!(info.session_id, id);
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (status, _) = terminate(&mut server, Duration::from_secs(30)).await;
    assert!(status.success(), "{status:?}");
    let recording = Recording::open(&path).expect("the recording is finished");
    assert!(recording.is_complete());
}
