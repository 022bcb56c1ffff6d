//! A real `laparo-server` process, for the tests of signals and shutdown.

use std::net::TcpListener;
use std::process::Child;
use std::time::{Duration, Instant};

/// Kills the server if the test fails before it ends.
pub struct Server(pub Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A loopback port free at the time of asking.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// How long a test waits for a server it started to listen.
const LISTEN_WAIT: Duration = Duration::from_secs(30);

/// A channel to the server on loopback `port` once it listens; fails the test past
/// [`LISTEN_WAIT`].
pub async fn connect(port: u16) -> tonic::transport::Channel {
    let url = format!("http://127.0.0.1:{port}");
    let deadline = Instant::now() + LISTEN_WAIT;
    loop {
        match tonic::transport::Endpoint::from_shared(url.clone())
            .unwrap()
            .connect()
            .await
        {
            Ok(ch) => return ch,
            Err(e) if Instant::now() > deadline => panic!("server never listened: {e}"),
            Err(_) => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
}

/// Creates a recorded session of `scene` over `ch`: its id and the recording's path
/// in `recordings` (the server's `--recordings` folder).
pub async fn create_recorded_session(
    ch: tonic::transport::Channel,
    scene: &str,
    recordings: &std::path::Path,
) -> (String, std::path::PathBuf) {
    let info = laparo_proto::v1::sessions_client::SessionsClient::new(ch)
        .create_session(laparo_proto::v1::CreateSessionRequest {
            scene: scene.into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await
        .unwrap()
        .into_inner();
    let file = recordings.join(info.recording_file.expect("recorded"));
    (info.session_id, file)
}

/// A real server on `port` with `args`, its log on the test's stderr.
pub fn spawn(port: u16, args: &[&std::ffi::OsStr]) -> Server {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_laparo-server"))
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(args)
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::inherit())
        .spawn()
        .unwrap();
    Server(child)
}

/// Sends SIGTERM to `server` and waits for it to exit, at most `bound` (then the
/// test fails); its exit status and how long it took.
pub async fn terminate(
    server: &mut Server,
    bound: Duration,
) -> (std::process::ExitStatus, Duration) {
    let sent = Instant::now();
    // SAFETY: a signal to our own child process.
    let term = unsafe { libc::kill(server.0.id() as i32, libc::SIGTERM) };
    assert_eq!(term, 0, "SIGTERM could not be sent");
    loop {
        if let Some(status) = server.0.try_wait().unwrap() {
            return (status, sent.elapsed());
        }
        assert!(
            sent.elapsed() < bound,
            "the server did not exit within {bound:?} of SIGTERM"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
