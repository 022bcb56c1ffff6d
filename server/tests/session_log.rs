//! What the server's log says of its sessions: an operator reading it sees each
//! session made and closed, and why it closed (it said "session created" and
//! nothing more: an idle timeout, an eviction or a close left no trace).

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use laparo_proto::v1;

mod common;
use common::process::{Server, connect, free_port, terminate};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_closed_session_is_logged_with_its_reason_escaped() {
    let port = free_port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_laparo-server"))
        .args(["--listen", &format!("127.0.0.1:{port}"), "--no-recording"])
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let log = child.stderr.take().unwrap();
    let mut server = Server(child);
    let ch = connect(port).await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch);
    let id = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: None,
        })
        .await
        .unwrap()
        .into_inner()
        .session_id;
    // A reason is a client's text: a terminal control in it is logged escaped.
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: id.clone(),
            reason: "lesson over \u{1b}[2J".into(),
        })
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let (status, _) = terminate(&mut server, Duration::from_secs(30)).await;
    assert!(status.success(), "{status:?}");
    let lines: Vec<String> = BufReader::new(log).lines().map(Result::unwrap).collect();
    let closed = lines
        .iter()
        .find(|l| l.contains("session closed"))
        .unwrap_or_else(|| panic!("no close logged:\n{}", lines.join("\n")));
    assert!(closed.contains(&format!("session={id}")), "{closed}");
    assert!(closed.contains(r"reason=lesson over \u{1b}[2J"), "{closed}");
    assert!(!lines.iter().any(|l| l.contains('\u{1b}')), "{lines:?}");
}
