//! SIGTERM to a real `laparo-server` ends it within its stated bound
//! (`SHUTDOWN_BOUND`) whatever its clients do: a TCP connection that says nothing,
//! one that sent only the HTTP/2 preface, an `Observe` stream its client does not
//! read. The session's recording, finished by the shutdown, reads back whole.
//!
//! The idle-connection timeout is set far beyond the test so that it is the
//! shutdown, not the timeout, that ends these connections.

use std::ffi::OsStr;
use std::io::Write;
use std::net::TcpStream;
use std::path::PathBuf;
use std::time::Duration;

use laparo_proto::v1;
use laparo_server::recording::Recording;
use laparo_server::service::shutdown::{SHUTDOWN_BOUND, SHUTDOWN_GRACE};

mod common;
use common::process::{Server, connect, create_recorded_session, free_port, spawn, terminate};

/// The client preface every HTTP/2 connection starts with (RFC 9113 §3.4).
const PREFACE: &[u8] = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";

/// A server recording into `dir`, one recorded default session, and the session's
/// id and recording file.
async fn serving(dir: &std::path::Path) -> (Server, u16, String, PathBuf) {
    let port = free_port();
    let server = spawn(
        port,
        &[
            OsStr::new("--recordings"),
            dir.as_os_str(),
            OsStr::new("--idle-connection"),
            OsStr::new("3600"),
        ],
    );
    let (session_id, file) = create_recorded_session(connect(port).await, "default", dir).await;
    (server, port, session_id, file)
}

/// SIGTERM, then the process's exit within the bound, cleanly, and the recording
/// complete.
async fn ends_within_the_bound(mut server: Server, file: &std::path::Path) -> Duration {
    let (status, took) = terminate(&mut server, SHUTDOWN_BOUND).await;
    assert!(status.success(), "{status:?}");
    eprintln!("exited {took:?} after SIGTERM (bound {SHUTDOWN_BOUND:?})");
    let recording = Recording::open(file).unwrap();
    assert!(recording.is_complete(), "the recording was finished");
    assert!(
        recording.messages().all(|m| m.is_ok()),
        "it reads back whole"
    );
    took
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_the_server_while_a_tcp_connection_says_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (server, port, _, file) = serving(dir.path()).await;
    let silent = TcpStream::connect(("127.0.0.1", port)).unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    ends_within_the_bound(server, &file).await;
    drop(silent);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_the_server_while_a_connection_sent_only_the_preface() {
    let dir = tempfile::tempdir().unwrap();
    let (server, port, _, file) = serving(dir.path()).await;
    let mut preface_only = TcpStream::connect(("127.0.0.1", port)).unwrap();
    preface_only.write_all(PREFACE).unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    ends_within_the_bound(server, &file).await;
    drop(preface_only);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_the_server_while_an_observe_stream_is_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let (server, port, session_id, file) = serving(dir.path()).await;
    // HTTP/2's smallest windows (64 KiB): what the client does not read stops the
    // server's writes after a few frames, so the stream cannot end gracefully.
    let ch = tonic::transport::Endpoint::from_shared(format!("http://127.0.0.1:{port}"))
        .unwrap()
        .initial_stream_window_size(65_535)
        .initial_connection_window_size(65_535)
        .connect()
        .await
        .unwrap();
    let stream = v1::observe_client::ObserveClient::new(ch)
        .observe(v1::ObserveRequest {
            session_id,
            frame_rate_hz: None,
        })
        .await
        .unwrap()
        .into_inner();
    // Frames pile up unread until HTTP/2 flow control stops the server's writes.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let took = ends_within_the_bound(server, &file).await;
    // The stream's end could not be delivered: the connection was severed after
    // the grace, not closed by the client.
    assert!(took >= SHUTDOWN_GRACE, "{took:?}");
    drop(stream);
}
