//! `Station.Attach` and `Station.SendPoses` against a real server: the handle
//! first, then what Join sends; poses through the handle drive the instrument
//! and are checked as Join's are; the handle works only for its own token; the
//! station leaves when its stream is dropped or after `leave`, and an empty call
//! keeps it from being timed out. And the console's
//! edges: cross-origin calls refused unless allowed, static assets without a
//! token.

use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::{Caller, Role, ServeConfig, StationTimeout, Tokens};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

const TEACHER: Option<&str> = Some("instructor-token");
const ALICE: Option<&str> = Some("alice-token-1");
const BOB: Option<&str> = Some("bob-token-22");

async fn server(cors: &[&str]) -> TestServer {
    TestServer::start(ServeConfig {
        cors_origins: cors.iter().map(|s| s.to_string()).collect(),
        ..config()
    })
    .await
}

/// A server's configuration with the three tokens of these tests.
fn config() -> ServeConfig {
    let mut tokens = Tokens::default();
    for (token, name, role) in [
        (TEACHER, "teacher", Role::Instructor),
        (ALICE, "alice", Role::Trainee),
        (BOB, "bob", Role::Trainee),
    ] {
        tokens.insert(
            token.unwrap(),
            Caller {
                name: name.into(),
                role,
                instruments: None,
            },
        );
    }
    ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    }
}

fn join_request(session: &str, instruments: &[&str]) -> v1::JoinRequest {
    v1::JoinRequest {
        session_id: session.into(),
        role: v1::Role::Trainee as i32,
        instruments: instruments.iter().map(|s| s.to_string()).collect(),
        surface_frame_rate_hz: None,
        client_name: "browser".into(),
    }
}

fn device_pose(tip: [f64; 3], sequence: u64) -> v1::DevicePose {
    let Some(v1::station_message::Kind::Pose(p)) =
        pose("left", tip, [0.0, 0.0, 1.0], sequence).kind
    else {
        unreachable!()
    };
    p
}

fn station(ch: &Channel) -> v1::station_client::StationClient<Channel> {
    v1::station_client::StationClient::new(ch.clone())
}

/// Attaches; returns the stream and the handle, after checking that `joined` follows.
async fn attach(
    ch: &Channel,
    token: Option<&str>,
    session: &str,
) -> Result<(tonic::Streaming<v1::AttachMessage>, String), tonic::Status> {
    let mut rx = station(ch)
        .attach(with_token(join_request(session, &["left"]), token))
        .await?
        .into_inner();
    let Some(v1::attach_message::Kind::Attached(a)) = rx.message().await?.and_then(|m| m.kind)
    else {
        panic!("the first message is not Attached");
    };
    let second = rx.message().await?.and_then(|m| m.kind);
    assert!(
        matches!(&second, Some(v1::attach_message::Kind::Message(v1::ServerMessage { kind: Some(v1::server_message::Kind::Joined(j)) })) if j.instruments == ["left"]),
        "{second:?}"
    );
    Ok((rx, a.handle))
}

async fn send(
    ch: &Channel,
    token: Option<&str>,
    handle: &str,
    poses: Vec<v1::DevicePose>,
    leave: bool,
) -> Result<u32, tonic::Status> {
    station(ch)
        .send_poses(with_token(
            v1::SendPosesRequest {
                handle: handle.into(),
                poses,
                leave,
            },
            token,
        ))
        .await
        .map(|r| r.into_inner().queued)
}

/// The next message of an attach stream that `pred` accepts, within `WAIT`.
async fn next_where(
    rx: &mut tonic::Streaming<v1::AttachMessage>,
    mut pred: impl FnMut(&v1::server_message::Kind) -> bool,
) -> Option<v1::server_message::Kind> {
    tokio::time::timeout(WAIT, async {
        while let Ok(Some(m)) = rx.message().await {
            if let Some(v1::attach_message::Kind::Message(v1::ServerMessage { kind: Some(k) })) =
                m.kind
                && pred(&k)
            {
                return Some(k);
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
}

async fn holder(ch: &Channel, session: &str) -> Option<u64> {
    v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(with_token(
            v1::GetSessionRequest {
                session_id: session.into(),
            },
            TEACHER,
        ))
        .await
        .unwrap()
        .into_inner()
        .instruments
        .iter()
        .find(|i| i.instrument == "left")
        .and_then(|i| i.station_id)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_sent_with_the_handle_drive_the_instrument() {
    let server = server(&[]).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (mut rx, handle) = attach(&ch, ALICE, &session).await.unwrap();
    assert_eq!(handle.len(), 32);
    let queued = send(
        &ch,
        ALICE,
        &handle,
        vec![
            device_pose([0.0, 0.0, 0.09], 1),
            device_pose([0.0, 0.0, 0.088], 2),
        ],
        false,
    )
    .await
    .unwrap();
    assert_eq!(queued, 2);
    let state = next_where(&mut rx, |k| {
        matches!(k, v1::server_message::Kind::InstrumentState(s) if s.instrument == "left" && s.pose_sequence == Some(2))
    })
    .await;
    let Some(v1::server_message::Kind::InstrumentState(s)) = state else {
        panic!("the instrument never took the pose");
    };
    let tip = s.pose.unwrap().tip.unwrap();
    assert!((tip.z - 0.088).abs() < 1e-12, "{tip:?}");
    // A pose out of order is refused on the stream, as on Join's.
    send(
        &ch,
        ALICE,
        &handle,
        vec![device_pose([0.0, 0.0, 0.09], 2)],
        false,
    )
    .await
    .unwrap();
    let error = next_where(&mut rx, |k| matches!(k, v1::server_message::Kind::Error(_))).await;
    assert!(
        matches!(&error, Some(v1::server_message::Kind::Error(e)) if e.code == v1::ErrorCode::OutOfOrder as i32 && e.sequence == Some(2)),
        "{error:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_handle_is_honoured_only_for_its_own_token_and_while_its_station_lasts() {
    let server = server(&[]).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (mut rx, handle) = attach(&ch, ALICE, &session).await.unwrap();
    let stolen = send(
        &ch,
        BOB,
        &handle,
        vec![device_pose([0.0, 0.0, 0.09], 1)],
        false,
    )
    .await;
    assert_eq!(stolen.unwrap_err().code(), Code::NotFound);
    let made_up = send(&ch, ALICE, &"0".repeat(32), vec![], false).await;
    assert_eq!(made_up.unwrap_err().code(), Code::NotFound);
    let no_token = send(&ch, None, &handle, vec![], false).await;
    assert_eq!(no_token.unwrap_err().code(), Code::Unauthenticated);
    // The claims are Join's: Bob cannot attach to the instrument Alice holds.
    let taken = attach(&ch, BOB, &session).await.err().unwrap();
    assert_eq!(taken.code(), Code::AlreadyExists, "{taken:?}");
    // Leaving ends the stream and releases the instrument; the handle is gone.
    assert!(holder(&ch, &session).await.is_some());
    send(&ch, ALICE, &handle, vec![], true).await.unwrap();
    let ended = final_status(&mut rx).await;
    assert!(ended.is_none(), "{ended:?}");
    let after = send(&ch, ALICE, &handle, vec![], false).await;
    assert_eq!(after.unwrap_err().code(), Code::NotFound);
    assert_eq!(holder(&ch, &session).await, None);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dropping_the_attach_stream_leaves_the_session() {
    let server = server(&[]).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (rx, handle) = attach(&ch, ALICE, &session).await.unwrap();
    assert!(holder(&ch, &session).await.is_some());
    drop(rx);
    let released = tokio::time::timeout(WAIT, async {
        while holder(&ch, &session).await.is_some() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await;
    assert!(
        released.is_ok(),
        "the instrument is still held after the stream was dropped"
    );
    let after = send(&ch, ALICE, &handle, vec![], false).await;
    assert_eq!(after.unwrap_err().code(), Code::NotFound);
}

/// A `SendPoses` with no poses and no leave is the station's heartbeat: a browser
/// station whose instruments do not move (a hidden tab draws no frames, so it
/// samples no poses) is not timed out while it calls; once it stops, it is.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_empty_send_is_a_heartbeat() {
    const TIMEOUT_S: f64 = 0.5;
    let server = TestServer::start(ServeConfig {
        station_timeout: StationTimeout::from_secs(TIMEOUT_S).unwrap(),
        ..config()
    })
    .await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (mut rx, handle) = attach(&ch, ALICE, &session).await.unwrap();
    let station = holder(&ch, &session).await.expect("left is held");
    // Three timeouts of empty calls, five a timeout.
    let beats = (3.0 * TIMEOUT_S / 0.1) as usize;
    for _ in 0..beats {
        assert_eq!(send(&ch, ALICE, &handle, vec![], false).await.unwrap(), 0);
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(holder(&ch, &session).await, Some(station));
    // Silent: timed out within WAIT, the stream ended with DEADLINE_EXCEEDED.
    let ended = final_status(&mut rx).await.map(|s| s.code());
    assert_eq!(ended, Some(Code::DeadlineExceeded));
    assert_eq!(holder(&ch, &session).await, None);
}

/// An Attach refused because the server's attached stations are at their limit
/// leaves nothing behind: the station used to be opened first (its instrument
/// claimed, its joining announced) and then refused a handle, and stayed holding
/// `left` with nobody to leave, until an instructor evicted it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_attach_refused_at_the_limit_leaves_no_station_behind() {
    let server = TestServer::start(ServeConfig {
        max_attached: Some(1),
        ..config()
    })
    .await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    // An instructor watching through Attach takes the one handle.
    let watching = station(&ch)
        .attach(with_token(join_request(&session, &[]), TEACHER))
        .await
        .unwrap();
    let refused = attach(&ch, ALICE, &session).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(refused.message().contains("MAX_ATTACHED"), "{refused:?}");
    assert_eq!(holder(&ch, &session).await, None);
    let stations = v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(with_token(
            v1::GetSessionRequest {
                session_id: session.clone(),
            },
            TEACHER,
        ))
        .await
        .unwrap()
        .into_inner()
        .stations
        .len();
    assert_eq!(stations, 1, "only the watching station");
    // With the handle given back, the same trainee attaches and holds `left`.
    drop(watching);
    let _taken = once_not(Code::ResourceExhausted, || attach(&ch, ALICE, &session))
        .await
        .expect("the handle never came back");
    assert!(holder(&ch, &session).await.is_some());
}

fn preflight(origin: &str) -> String {
    format!(
        "OPTIONS /laparo.v1.Scenes/ListScenes HTTP/1.1\r\nhost: x\r\norigin: {origin}\r\naccess-control-request-method: POST\r\naccess-control-request-headers: authorization,content-type,x-grpc-web\r\n\r\n"
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cross_origin_calls_are_refused_unless_the_origin_is_allowed() {
    let server = server(&["http://allowed.example:8080"]).await;
    let refused = http_head(&server, &preflight("http://evil.example")).await;
    assert!(
        !refused.contains("access-control-allow-origin"),
        "{refused}"
    );
    let allowed = http_head(&server, &preflight("http://allowed.example:8080")).await;
    assert!(
        allowed.contains("access-control-allow-origin: http://allowed.example:8080"),
        "{allowed}"
    );
    assert!(allowed.contains("authorization"), "{allowed}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_console_page_needs_no_token_and_the_calls_do() {
    let server = server(&[]).await;
    let page = http_head(&server, "GET / HTTP/1.1\r\nhost: x\r\n\r\n").await;
    assert!(page.starts_with("http/1.1 200"), "{page}");
    assert!(page.contains("content-type: text/html"), "{page}");
    // A gRPC-web call without a token is refused by the same interceptor.
    let call = http_head(
        &server,
        "POST /laparo.v1.Scenes/ListScenes HTTP/1.1\r\nhost: x\r\ncontent-type: application/grpc-web+proto\r\ncontent-length: 5\r\n\r\n\0\0\0\0\0",
    )
    .await;
    assert!(call.starts_with("http/1.1 200"), "{call}");
    assert!(call.contains("grpc-status: 16"), "{call}");
}
