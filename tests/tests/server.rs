//! The training server over real gRPC on loopback: stations and an observer sharing a
//! session, every class of bad input, a station dropping and rejoining, roles, health
//! and reflection, and shutdown with streams open.

use std::path::{Path, PathBuf};
use std::time::Duration;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::{Caller, Role, ServeConfig, ServeError, Tokens};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

const WAIT: Duration = Duration::from_secs(20);

/// The front point of the rest surface (the default liver's free +z face), m.
fn front(joined: &v1::Joined) -> [f64; 3] {
    let f = laparo_client::demo::front(joined.scene.as_ref().unwrap());
    [f.x, f.y, f.z]
}

/// Streams poses of `instrument` pressing along −z at `x_offset` beside the front
/// point: from 1.5 cm out to 8 mm in over 0.5 s, then held, 100 poses a second.
fn press(station: &StationStream, instrument: &'static str, front: [f64; 3], x_offset: f64) {
    let tx = station.tx.clone();
    tokio::spawn(async move {
        for k in 1..=400u64 {
            let s = (k as f64 / 50.0).min(1.0);
            let z = front[2] + 0.015 - 0.023 * s;
            let tip = [front[0] + x_offset, front[1], z];
            if tx
                .send(pose(instrument, tip, [0.0, 0.0, 1.0], k))
                .await
                .is_err()
            {
                return;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    });
}

fn state_of<'a>(m: &'a v1::ServerMessage, instrument: &str) -> Option<&'a v1::InstrumentState> {
    match &m.kind {
        Some(Kind::InstrumentState(s)) if s.instrument == instrument => Some(s),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_stations_and_an_observer_see_each_other_deform_the_liver() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let (mut b, _) = join(ch.clone(), None, &session, &["right"]).await.unwrap();
    let mut observer = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.clone(),
            frame_rate_hz: Some(10.0),
        })
        .await
        .unwrap()
        .into_inner();
    let f = front(&joined);
    press(&a, "left", f, -0.02);
    // B sees A's instrument take hold of the liver, and the surface move under it.
    let seen = wait_for(&mut b.rx, WAIT, |m| {
        state_of(m, "left").is_some_and(|s| s.held_vertex_count > 0 && s.station_id.is_some())
    })
    .await;
    assert!(
        seen.is_some(),
        "station B never saw the left instrument hold tissue"
    );
    let rest = joined
        .scene
        .as_ref()
        .unwrap()
        .rest_surface
        .as_ref()
        .unwrap()
        .positions
        .clone();
    let moved = wait_for(&mut b.rx, WAIT, |m| match &m.kind {
        Some(Kind::SurfaceFrame(frame)) => frame
            .positions
            .iter()
            .zip(&rest)
            .any(|(p, r)| (p - r).abs() > 0.006),
        _ => false,
    })
    .await;
    assert!(moved.is_some(), "no surface vertex moved 6 mm");
    // Now B presses; A sees the right instrument.
    press(&b, "right", f, 0.02);
    assert!(
        wait_for(&mut a.rx, WAIT, |m| state_of(m, "right")
            .is_some_and(|s| s.held_vertex_count > 0))
        .await
        .is_some(),
        "station A never saw the right instrument hold tissue"
    );
    // The observer saw the scene, then both instruments in contact.
    let mut first = true;
    let mut in_contact = [false; 2];
    let done = tokio::time::timeout(WAIT, async {
        while let Ok(Some(m)) = observer.message().await {
            if first {
                assert!(matches!(m.kind, Some(v1::observe_message::Kind::Scene(_))));
                first = false;
            }
            if let Some(v1::observe_message::Kind::InstrumentState(s)) = &m.kind {
                let k = usize::from(s.instrument == "right");
                in_contact[k] |= s.contact != v1::ContactState::None as i32;
            }
            if in_contact == [true, true] {
                return;
            }
        }
    })
    .await;
    assert!(done.is_ok(), "the observer saw contact of {in_contact:?}");
    drop((a, b, observer));
    server.shutdown().await.unwrap();
}

/// The next error a station's stream reports.
async fn next_error(s: &mut StationStream) -> v1::StationError {
    match wait_for(&mut s.rx, WAIT, |m| matches!(m.kind, Some(Kind::Error(_)))).await {
        Some(v1::ServerMessage {
            kind: Some(Kind::Error(e)),
        }) => e,
        other => panic!("expected an error, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_input_gets_a_clear_answer_and_harms_nothing() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let (mut b, _) = join(ch.clone(), None, &session, &["right"]).await.unwrap();
    let f = front(&joined);
    let away = [f[0], f[1], f[2] + 0.05];
    let z = [0.0, 0.0, 1.0];
    // Per-message errors: the pose is dropped, the stream stays open.
    let cases: Vec<(v1::StationMessage, v1::ErrorCode)> = vec![
        (
            pose("left", [f64::NAN, 0.0, 0.0], z, 1),
            v1::ErrorCode::InvalidPose,
        ),
        (
            pose("left", away, [f64::INFINITY, 0.0, 1.0], 2),
            v1::ErrorCode::InvalidPose,
        ),
        (
            pose("left", away, [0.0, 0.0, 0.0], 3),
            v1::ErrorCode::InvalidPose,
        ),
        (
            pose("left", away, [0.0, 0.0, 1.5], 4),
            v1::ErrorCode::InvalidPose,
        ),
        (
            pose("left", [1e6, 0.0, 0.0], z, 5),
            v1::ErrorCode::OutOfWorkspace,
        ),
        (pose("middle", away, z, 6), v1::ErrorCode::UnknownInstrument),
        (pose("right", away, z, 7), v1::ErrorCode::InstrumentNotHeld),
        (pose("left", away, z, 10), v1::ErrorCode::Unspecified),
        (pose("left", away, z, 9), v1::ErrorCode::OutOfOrder),
        (open(&session, &["left"]), v1::ErrorCode::AlreadyJoined),
        (
            v1::StationMessage { kind: None },
            v1::ErrorCode::InvalidMessage,
        ),
    ];
    for (message, code) in cases {
        a.tx.send(message).await.unwrap();
        if code == v1::ErrorCode::Unspecified {
            // A good pose: applied, and seen in the instrument's state.
            let applied = wait_for(&mut a.rx, WAIT, |m| {
                state_of(m, "left").is_some_and(|s| s.pose_sequence == Some(10))
            })
            .await;
            assert!(applied.is_some(), "the good pose was not applied");
            continue;
        }
        let e = next_error(&mut a).await;
        assert_eq!(e.code, code as i32, "{e:?}");
        assert!(!e.message.is_empty());
    }
    // Join-level refusals.
    let code = |r: Result<(StationStream, v1::Joined), tonic::Status>| r.err().map(|s| s.code());
    assert_eq!(
        code(join(ch.clone(), None, "nope", &["left"]).await),
        Some(Code::NotFound)
    );
    assert_eq!(
        code(join(ch.clone(), None, &session, &["middle"]).await),
        Some(Code::NotFound)
    );
    assert_eq!(
        code(join(ch.clone(), None, &session, &["left"]).await),
        Some(Code::AlreadyExists)
    );
    assert_eq!(
        code(join(ch.clone(), None, &session, &["left", "left"]).await),
        Some(Code::InvalidArgument)
    );
    let no_open = join_raw(ch.clone(), None, Some(pose("left", away, z, 1))).await;
    assert_eq!(no_open.err().map(|s| s.code()), Some(Code::InvalidArgument));
    // A message over the size limit ends that stream with an error status.
    let (mut big, _) = join(ch.clone(), None, &session, &[]).await.unwrap();
    big.tx
        .send(pose(&"x".repeat(200_000), away, z, 1))
        .await
        .unwrap();
    let ended = tokio::time::timeout(WAIT, async {
        loop {
            match big.rx.message().await {
                Err(status) => return status.code(),
                Ok(None) => return Code::Ok,
                Ok(Some(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    assert!(
        matches!(ended, Code::OutOfRange | Code::ResourceExhausted),
        "{ended:?}"
    );
    // Poses faster than the limit: rate-limited, then the stream is closed.
    for k in 0..3000u64 {
        if a.tx.send(pose("left", away, z, 100 + k)).await.is_err() {
            break;
        }
    }
    let closed = tokio::time::timeout(WAIT, async {
        let mut limited = 0;
        loop {
            match a.rx.message().await {
                Ok(Some(v1::ServerMessage {
                    kind: Some(Kind::Error(e)),
                })) if e.code == v1::ErrorCode::RateLimited as i32 => limited += 1,
                Ok(Some(_)) => {}
                Ok(None) => return (limited, Code::Ok),
                Err(status) => return (limited, status.code()),
            }
        }
    })
    .await
    .unwrap();
    assert!(closed.0 > 0, "no pose was rate-limited");
    assert_eq!(closed.1, Code::ResourceExhausted);
    // Through all this, the session and the other station went on.
    let tick = |info: v1::SessionInfo| info.tick;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let get = v1::GetSessionRequest {
        session_id: session.clone(),
    };
    let t0 = tick(
        sessions
            .get_session(get.clone())
            .await
            .unwrap()
            .into_inner(),
    );
    assert!(
        wait_for(
            &mut b.rx,
            WAIT,
            |m| matches!(&m.kind, Some(Kind::SurfaceFrame(fr)) if fr.tick > t0 + 5)
        )
        .await
        .is_some(),
        "station B stopped receiving frames"
    );
    let info = sessions.get_session(get).await.unwrap().into_inner();
    assert!(info.poses_rejected > 100, "{info:?}");
    // The abusive station's instrument is free again.
    assert!(
        info.instruments
            .iter()
            .any(|h| h.instrument == "left" && h.station_id.is_none())
    );
    drop((b, big));
    server.shutdown().await.unwrap();
}

async fn holder(ch: &Channel, session: &str, instrument: &str) -> Option<u64> {
    let info = v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(v1::GetSessionRequest {
            session_id: session.to_string(),
        })
        .await
        .unwrap()
        .into_inner();
    info.instruments
        .iter()
        .find(|h| h.instrument == instrument)
        .and_then(|h| h.station_id)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_drops_and_rejoins() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let (mut b, _) = join(ch.clone(), None, &session, &["right"]).await.unwrap();
    press(&a, "left", front(&joined), 0.0);
    assert!(
        wait_for(&mut a.rx, WAIT, |m| state_of(m, "left")
            .is_some_and(|s| s.held_vertex_count > 0))
        .await
        .is_some()
    );
    let id = joined.station_id;
    assert_eq!(holder(&ch, &session, "left").await, Some(id));
    drop(a);
    // B hears that A left; the instrument is free; the session goes on.
    let left = wait_for(&mut b.rx, WAIT, |m| {
        matches!(&m.kind, Some(Kind::Event(e)) if e.kind == v1::EventKind::StationLeft as i32 && e.station_id == Some(id))
    })
    .await;
    assert!(left.is_some(), "no StationLeft event");
    assert_eq!(holder(&ch, &session, "left").await, None);
    // The instrument stays where it was: still holding tissue.
    assert!(
        wait_for(&mut b.rx, WAIT, |m| state_of(m, "left")
            .is_some_and(|s| s.held_vertex_count > 0))
        .await
        .is_some()
    );
    let (_a2, joined2) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    assert_ne!(joined2.station_id, id);
    assert_eq!(
        holder(&ch, &session, "left").await,
        Some(joined2.station_id)
    );
    drop(b);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn roles_decide_who_may_do_what() {
    let mut tokens = Tokens::default();
    tokens.insert(
        "instructor-token",
        Caller {
            name: "instructor".into(),
            role: Role::Instructor,
            instruments: None,
        },
    );
    tokens.insert(
        "trainee-left-token",
        Caller {
            name: "trainee".into(),
            role: Role::Trainee,
            instruments: Some(vec!["left".into()]),
        },
    );
    let server = TestServer::start(ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let (teacher, trainee) = (Some("instructor-token"), Some("trainee-left-token"));
    let code = |r: Result<v1::SessionInfo, tonic::Status>| r.err().map(|s| s.code());
    assert_eq!(
        code(create_session(ch.clone(), None).await),
        Some(Code::Unauthenticated)
    );
    assert_eq!(
        code(create_session(ch.clone(), Some("wrong-token")).await),
        Some(Code::Unauthenticated)
    );
    assert_eq!(
        code(create_session(ch.clone(), trainee).await),
        Some(Code::PermissionDenied)
    );
    let session = create_session(ch.clone(), teacher)
        .await
        .unwrap()
        .session_id;
    // The trainee may claim its own instrument, not another's, and may not observe.
    let claim = join(ch.clone(), trainee, &session, &["right"]).await;
    assert_eq!(claim.err().map(|s| s.code()), Some(Code::PermissionDenied));
    let observe = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(with_token(
            v1::ObserveRequest {
                session_id: session.clone(),
                frame_rate_hz: None,
            },
            trainee,
        ))
        .await;
    assert_eq!(
        observe.err().map(|s| s.code()),
        Some(Code::PermissionDenied)
    );
    let (_station, joined) = join(ch.clone(), trainee, &session, &["left"])
        .await
        .unwrap();
    assert_eq!(joined.instruments, vec!["left".to_string()]);
    // The instructor observes.
    let observe = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(with_token(
            v1::ObserveRequest {
                session_id: session.clone(),
                frame_rate_hz: None,
            },
            teacher,
        ))
        .await;
    assert!(observe.is_ok());
    drop(observe);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_and_reflection_answer_generic_clients() {
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::{HealthCheckRequest, health_client::HealthClient};
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    for service in ["laparo.v1.Station", "laparo.v1.Sessions"] {
        let status = HealthClient::new(ch.clone())
            .check(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner()
            .status;
        assert_eq!(status, ServingStatus::Serving as i32, "{service}");
    }
    use tonic_reflection::pb::v1::ServerReflectionRequest;
    use tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient;
    use tonic_reflection::pb::v1::server_reflection_request::MessageRequest;
    use tonic_reflection::pb::v1::server_reflection_response::MessageResponse;
    let request = ServerReflectionRequest {
        host: String::new(),
        message_request: Some(MessageRequest::ListServices(String::new())),
    };
    let mut replies = ServerReflectionClient::new(ch.clone())
        .server_reflection_info(tokio_stream::iter([request]))
        .await
        .unwrap()
        .into_inner();
    let reply = replies.message().await.unwrap().unwrap();
    let Some(MessageResponse::ListServicesResponse(list)) = reply.message_response else {
        panic!("{reply:?}");
    };
    let names: Vec<_> = list.service.iter().map(|s| s.name.as_str()).collect();
    for s in [
        "laparo.v1.Station",
        "laparo.v1.Observe",
        "laparo.v1.Sessions",
        "laparo.v1.Scenes",
    ] {
        assert!(names.contains(&s), "{names:?}");
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_ends_open_streams_with_a_status() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, _) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let mut observer = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.clone(),
            frame_rate_hz: None,
        })
        .await
        .unwrap()
        .into_inner();
    // Streams are live.
    assert!(
        wait_for(&mut a.rx, WAIT, |m| matches!(
            m.kind,
            Some(Kind::SurfaceFrame(_))
        ))
        .await
        .is_some()
    );
    let shutdown = tokio::spawn(server.shutdown());
    let status = tokio::time::timeout(WAIT, async {
        loop {
            match a.rx.message().await {
                Err(s) => return Some(s),
                Ok(None) => return None,
                Ok(Some(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    let status = status.expect("the station's stream ends with a status");
    assert_eq!(status.code(), Code::Unavailable, "{status:?}");
    assert!(status.message().contains("shutting down"), "{status:?}");
    let observed = tokio::time::timeout(WAIT, async {
        loop {
            match observer.message().await {
                Err(s) => return Some(s.code()),
                Ok(None) => return None,
                Ok(Some(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    assert_eq!(observed, Some(Code::Unavailable));
    shutdown.await.unwrap().unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_public_address_needs_tls_and_tokens_or_insecure() {
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let refused = laparo_server::service::serve(ServeConfig::default(), listener, async {}).await;
    assert!(
        matches!(refused, Err(ServeError::Insecure(_))),
        "{refused:?}"
    );
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let allowed = laparo_server::service::serve(
        ServeConfig {
            insecure: true,
            ..ServeConfig::default()
        },
        listener,
        async {},
    )
    .await;
    assert!(allowed.is_ok(), "{allowed:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_with_tokens_serves_a_public_address() {
    use tonic::transport::{Certificate, ClientTlsConfig};
    let dir = std::env::temp_dir().join(format!("laparo-tls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let (cert_pem, key_pem) = (cert.cert.pem(), cert.signing_key.serialize_pem());
    std::fs::write(dir.join("cert.pem"), &cert_pem).unwrap();
    std::fs::write(dir.join("key.pem"), &key_pem).unwrap();
    let mut tokens = Tokens::default();
    tokens.insert("instructor-token", Caller::open());
    // Not loopback, yet allowed: TLS and tokens.
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let config = ServeConfig {
        tokens: Some(tokens),
        tls: Some(laparo_server::service::TlsFiles {
            cert: dir.join("cert.pem"),
            key: dir.join("key.pem"),
        }),
        ..ServeConfig::default()
    };
    let server = tokio::spawn(laparo_server::service::serve(config, listener, async {
        let _ = stopped.await;
    }));
    let tls = ClientTlsConfig::new()
        .ca_certificate(Certificate::from_pem(&cert_pem))
        .domain_name("localhost");
    let ch = Channel::from_shared(format!("https://127.0.0.1:{port}"))
        .unwrap()
        .tls_config(tls)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let info = create_session(ch.clone(), Some("instructor-token"))
        .await
        .unwrap();
    assert!(!info.session_id.is_empty());
    // Plain text to a TLS port gets nowhere.
    let plain = Channel::from_shared(format!("http://127.0.0.1:{port}"))
        .unwrap()
        .connect()
        .await;
    if let Ok(plain) = plain {
        assert!(
            create_session(plain, Some("instructor-token"))
                .await
                .is_err()
        );
    }
    let _ = stop.send(());
    server.await.unwrap().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idle_session_closes_itself() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let id = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: Some(1.0),
            record: None,
        })
        .await
        .unwrap()
        .into_inner()
        .session_id;
    // A station keeps it alive while connected.
    let (station, _) = join(ch.clone(), None, &id, &["left"]).await.unwrap();
    tokio::time::sleep(Duration::from_millis(2500)).await;
    let get = v1::GetSessionRequest {
        session_id: id.clone(),
    };
    assert!(sessions.get_session(get.clone()).await.is_ok());
    drop(station);
    // Idle: closed within the timeout and the once-a-second check.
    let closed = tokio::time::timeout(WAIT, async {
        loop {
            if let Err(s) = sessions.get_session(get.clone()).await {
                return s.code();
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    })
    .await
    .unwrap();
    assert_eq!(closed, Code::NotFound);
    // A bad timeout is refused.
    let bad = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: Some(f64::NAN),
            record: None,
        })
        .await;
    assert_eq!(bad.err().map(|s| s.code()), Some(Code::InvalidArgument));
    let unknown = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "no-such-scene".into(),
            idle_timeout_s: None,
            record: None,
        })
        .await;
    assert_eq!(unknown.err().map(|s| s.code()), Some(Code::NotFound));
    server.shutdown().await.unwrap();
}

/// A fresh directory for a test's recordings.
fn recordings_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A server recording into a fresh directory named after `test`, a channel to
/// it, and the directory.
async fn recording_server(test: &str) -> (TestServer, Channel, PathBuf) {
    let dir = recordings_dir(test);
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    (server, ch, dir)
}

/// A session recorded through the server.
struct Recorded {
    /// The recording's path.
    file: PathBuf,
    /// The session as it closed.
    closed: v1::SessionInfo,
    joined: v1::Joined,
}

/// Records a session of the default scene in `dir`: a station presses the liver
/// with the left instrument until it holds tissue and the session has run
/// `at_least_s` of simulated time, leaves, and the session is closed (which
/// finishes the file).
async fn record_press(ch: &Channel, dir: &Path, at_least_s: f64) -> Recorded {
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await
        .unwrap()
        .into_inner();
    let file = dir.join(
        info.recording_file
            .clone()
            .expect("a recorded session names its file"),
    );
    let (mut a, joined) = join(ch.clone(), None, &info.session_id, &["left"])
        .await
        .unwrap();
    press(&a, "left", front(&joined), 0.0);
    assert!(
        wait_for(&mut a.rx, WAIT, |m| state_of(m, "left")
            .is_some_and(|s| s.held_vertex_count > 0))
        .await
        .is_some()
    );
    let get = v1::GetSessionRequest {
        session_id: info.session_id.clone(),
    };
    tokio::time::timeout(WAIT, async {
        while sessions
            .get_session(get.clone())
            .await
            .unwrap()
            .into_inner()
            .sim_time_s
            < at_least_s
        {
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    })
    .await
    .expect("the session runs");
    drop(a);
    let closed = sessions
        .close_session(v1::CloseSessionRequest {
            session_id: info.session_id.clone(),
            reason: "test over".into(),
        })
        .await
        .unwrap()
        .into_inner()
        .session
        .unwrap();
    Recorded {
        file,
        closed,
        joined,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_is_recorded_through_a_real_server() {
    use laparo_server::recording::Recording;
    let (server, ch, dir) = recording_server("rec").await;
    let Recorded {
        file,
        closed,
        joined,
    } = record_press(&ch, &dir, 0.0).await;
    // Closing waited for the mechanics thread, which finished the file.
    let recording = Recording::open(&file).unwrap();
    server.shutdown().await.unwrap();
    let surfaces = recording.surfaces().unwrap();
    let poses = recording.poses().unwrap();
    assert!(
        surfaces.len() as u64 >= closed.tick.saturating_sub(2),
        "{} vs {}",
        surfaces.len(),
        closed.tick
    );
    assert_eq!(poses.len() as u64, closed.poses_accepted);
    assert!(poses.iter().all(|p| p.message.instrument == "left"));
    // The deformed surface is in it: some vertex moved more than 6 mm from rest.
    let rest = joined.scene.unwrap().rest_surface.unwrap().positions;
    assert!(surfaces.iter().any(|s| {
        s.message
            .positions
            .iter()
            .zip(&rest)
            .any(|(p, r)| (p - r).abs() > 0.006)
    }));
    // The recorded poses through the recorded scene again: the same surfaces and
    // forces at every tick, to the bit.
    let resim = laparo_server::recording::resimulate(&recording, None, |_| {}).unwrap();
    assert_eq!(resim.ticks_compared, surfaces.len() as u64);
    assert!(resim.is_exact(), "{resim:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Simulated time of a replayed message, s (none for the scene).
fn sim_time(m: &v1::ObserveMessage) -> Option<f64> {
    use v1::observe_message::Kind as O;
    match m.kind.as_ref()? {
        O::Scene(_) => None,
        O::SurfaceFrame(f) => Some(f.sim_time_s),
        O::InstrumentState(s) => Some(s.sim_time_s),
        O::Event(e) => Some(e.sim_time_s),
    }
}

/// What a recording's file holds for a replay, in file order: its surface frames,
/// instrument states and events as observe messages, with their simulated times.
fn recorded_messages(
    recording: &laparo_server::recording::Recording,
) -> Vec<(f64, v1::ObserveMessage)> {
    use laparo_server::recording::Recorded as R;
    use v1::observe_message::Kind as O;
    recording
        .messages()
        .filter_map(|m| {
            let kind = match m.unwrap().message {
                R::Surface(f) => O::SurfaceFrame(f),
                R::Instrument(s) => O::InstrumentState(s),
                R::Event(e) => O::Event(e),
                R::Scene(_) | R::Pose(_) => return None,
            };
            let m = v1::ObserveMessage { kind: Some(kind) };
            Some((sim_time(&m).unwrap(), m))
        })
        .collect()
}

/// What a replay from `offset` sends after the scene: the newest tick at or before
/// the offset (its surface and states) and the events stamped at the offset, then
/// everything from the first message after the offset on, in file order.
fn expected_from(file: &[(f64, v1::ObserveMessage)], offset: f64) -> Vec<v1::ObserveMessage> {
    use v1::observe_message::Kind as O;
    if offset == 0.0 {
        return file.iter().map(|(_, m)| m.clone()).collect();
    }
    let after = file
        .iter()
        .position(|(t, _)| *t > offset)
        .unwrap_or(file.len());
    let tick = file[..after].iter().rev().find_map(|(_, m)| match &m.kind {
        Some(O::SurfaceFrame(f)) => Some(f.tick),
        _ => None,
    });
    let first = file[..after]
        .iter()
        .rposition(|(_, m)| matches!(&m.kind, Some(O::SurfaceFrame(_))));
    let held = file[..after]
        .iter()
        .enumerate()
        .filter(|(k, (t, m))| match &m.kind {
            Some(O::SurfaceFrame(_)) => Some(*k) == first,
            Some(O::InstrumentState(s)) => Some(s.tick) == tick && Some(*k) > first,
            Some(O::Event(_)) => *t == offset,
            _ => false,
        });
    held.map(|(_, (_, m))| m.clone())
        .chain(file[after..].iter().map(|(_, m)| m.clone()))
        .collect()
}

/// The messages of a replay, each with when it arrived after the call was made,
/// and how the stream ended; the call's own refusal as `Err`.
async fn replay_all(
    ch: &Channel,
    token: Option<&str>,
    request: v1::ReplayRequest,
) -> Result<
    (
        Vec<(Duration, v1::ObserveMessage)>,
        Result<(), tonic::Status>,
    ),
    tonic::Status,
> {
    let t0 = std::time::Instant::now();
    let mut stream = v1::recordings_client::RecordingsClient::new(ch.clone())
        .replay(with_token(request, token))
        .await?
        .into_inner();
    let mut got = Vec::new();
    let end = tokio::time::timeout(3 * WAIT, async {
        loop {
            match stream.message().await {
                Ok(Some(m)) => got.push((t0.elapsed(), m)),
                Ok(None) => return Ok(()),
                Err(status) => return Err(status),
            }
        }
    })
    .await
    .expect("the replay ends");
    Ok((got, end))
}

fn replay_request(file: &str, speed: Option<f64>, offset: Option<f64>) -> v1::ReplayRequest {
    v1::ReplayRequest {
        file: file.to_string(),
        speed,
        start_offset_s: offset,
        mode: v1::ReplayMode::Recorded as i32,
    }
}

/// Surface positions as bits, to compare frames bit for bit.
fn bits(m: &v1::ObserveMessage) -> Option<(u64, Vec<u32>)> {
    match &m.kind {
        Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some((
            f.sim_time_s.to_bits(),
            f.positions.iter().map(|x| x.to_bits()).collect(),
        )),
        _ => None,
    }
}

/// Each message arrives no earlier than its simulated time after the offset,
/// divided by the speed (less a millisecond for rounding).
fn assert_paced(got: &[(Duration, v1::ObserveMessage)], offset: f64, speed: f64) {
    for (arrived, m) in got {
        if let Some(t) = sim_time(m) {
            let due = (t - offset).max(0.0) / speed;
            assert!(
                arrived.as_secs_f64() >= due - 1e-3,
                "a message of t = {t} s arrived after {arrived:?}, before {due} s"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_is_listed_and_replayed_as_recorded() {
    use laparo_server::recording::Recording;
    let (server, ch, dir) = recording_server("replay").await;
    let rec = record_press(&ch, &dir, 2.0).await;
    let name = rec.file.file_name().unwrap().to_str().unwrap().to_string();
    let recording = Recording::open(&rec.file).unwrap();
    let file = recorded_messages(&recording);
    let surfaces = recording.surfaces().unwrap();
    let last = surfaces.last().unwrap().message.clone();
    let scene = recording.scene().unwrap();
    let rate = scene.summary.as_ref().unwrap().mechanics_rate_hz;

    // The list: the session, its scene, start, duration and the file's size.
    let mut recordings = v1::recordings_client::RecordingsClient::new(ch.clone());
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner()
        .recordings;
    assert_eq!(listed.len(), 1, "{listed:?}");
    let info = &listed[0];
    assert_eq!(info.file, name);
    assert_eq!(info.session_id, rec.closed.session_id);
    assert_eq!(info.scene, rec.closed.scene);
    assert_eq!(info.start, rec.closed.created_at);
    assert!(!info.in_progress);
    assert_eq!(info.size_bytes, std::fs::metadata(&rec.file).unwrap().len());
    assert_eq!(info.duration_s.to_bits(), last.sim_time_s.to_bits());
    assert!(
        (info.duration_s - last.tick as f64 / rate).abs() < 1e-9,
        "{} s for {} ticks at {rate} Hz",
        info.duration_s,
        last.tick
    );
    assert!(last.tick <= rec.closed.tick && info.duration_s >= 2.0);

    // At 20×: the scene, then every frame, state and event of the file in its
    // order, frames bit for bit, each no earlier than its time allows.
    let (got, end) = replay_all(&ch, None, replay_request(&name, Some(20.0), None))
        .await
        .unwrap();
    end.unwrap();
    assert_eq!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(scene.clone()))
    );
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    let all: Vec<v1::ObserveMessage> = file.iter().map(|(_, m)| m.clone()).collect();
    assert_eq!(sent.len(), all.len());
    assert!(sent == all, "the replay differs from the file");
    let frame_bits = |ms: &[v1::ObserveMessage]| ms.iter().filter_map(bits).collect::<Vec<_>>();
    assert_eq!(frame_bits(&sent), frame_bits(&all));
    assert_eq!(frame_bits(&sent).len(), surfaces.len());
    let ticks: Vec<u64> = sent
        .iter()
        .filter_map(|m| match &m.kind {
            Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some(f.tick),
            _ => None,
        })
        .collect();
    assert!(ticks.windows(2).all(|w| w[0] < w[1]), "ticks out of order");
    assert!(
        sent.iter()
            .any(|m| matches!(m.kind, Some(v1::observe_message::Kind::Event(_))))
    );
    assert_paced(&got, 0.0, 20.0);

    // Re-simulated at 50×: the recorded poses through the scene again give the
    // same frames and instrument states, to the bit and in the same order, and the
    // same events (their order among the session's other events may differ).
    let (got, end) = replay_all(
        &ch,
        None,
        v1::ReplayRequest {
            mode: v1::ReplayMode::Resimulate as i32,
            ..replay_request(&name, Some(50.0), None)
        },
    )
    .await
    .unwrap();
    end.unwrap();
    assert_eq!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(scene.clone()))
    );
    let again: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    let split = |ms: &[v1::ObserveMessage]| {
        let (mut ticks, mut events) = (Vec::new(), Vec::new());
        for m in ms {
            match &m.kind {
                Some(v1::observe_message::Kind::Event(e)) => {
                    events.push((e.tick, e.kind, e.instrument.clone(), e.detail.clone()))
                }
                _ => ticks.push(m.clone()),
            }
        }
        events.sort();
        (ticks, events)
    };
    let (again_ticks, again_events) = split(&again);
    let (recorded_ticks, recorded_events) = split(&all);
    assert_eq!(again_ticks.len(), recorded_ticks.len());
    assert!(again_ticks == recorded_ticks, "the re-simulation differs");
    assert_eq!(again_events, recorded_events);
    assert!(
        again_events
            .iter()
            .any(|e| e.1 == v1::EventKind::ContactBegan as i32),
        "the press made contact, and the re-simulation found it again"
    );
    assert_paced(&got, 0.0, 50.0);

    // From an offset, at 2×: the state at the offset first, then nothing earlier,
    // paced by the time after the offset.
    let offset = 1.0;
    let (got, end) = replay_all(&ch, None, replay_request(&name, Some(2.0), Some(offset)))
        .await
        .unwrap();
    end.unwrap();
    assert!(matches!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    assert!(sent == expected_from(&file, offset));
    let frame_times: Vec<f64> = sent
        .iter()
        .filter(|m| bits(m).is_some())
        .map(|m| sim_time(m).unwrap())
        .collect();
    let newest_before = surfaces
        .iter()
        .map(|s| s.message.sim_time_s)
        .filter(|t| *t <= offset)
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(frame_times[0].to_bits(), newest_before.to_bits());
    assert!(frame_times[1..].iter().all(|t| *t > offset));
    assert_paced(&got, offset, 2.0);
    let span = (last.sim_time_s - offset) / 2.0;
    let wall = got.last().unwrap().0.as_secs_f64();
    assert!(
        wall >= span - 1e-3 && wall < span + 15.0,
        "{wall} s for {span} s of replay"
    );
    // From the very end: the last tick alone.
    let (got, end) = replay_all(
        &ch,
        None,
        replay_request(&name, Some(50.0), Some(info.duration_s)),
    )
    .await
    .unwrap();
    end.unwrap();
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    assert!(sent == expected_from(&file, info.duration_s));
    assert_eq!(sent.iter().filter_map(bits).count(), 1);

    // Every bad request gets its code.
    let code = |r: Result<_, tonic::Status>| r.err().map(|s: tonic::Status| s.code());
    let bad =
        |file: &str, speed: Option<f64>, offset: Option<f64>| replay_request(file, speed, offset);
    let cases = [
        (bad("../escape.mcap", None, None), Code::InvalidArgument),
        (
            bad(&format!("../{name}"), None, None),
            Code::InvalidArgument,
        ),
        (
            bad(&format!("{}/{name}", dir.display()), None, None),
            Code::InvalidArgument,
        ),
        (bad("sub/x.mcap", None, None), Code::InvalidArgument),
        (bad("..", None, None), Code::InvalidArgument),
        (bad("", None, None), Code::InvalidArgument),
        (bad("a\\b.mcap", None, None), Code::InvalidArgument),
        (bad("notes.txt", None, None), Code::InvalidArgument),
        (bad("nope.mcap", None, None), Code::NotFound),
        (bad(&name, Some(0.0), None), Code::InvalidArgument),
        (bad(&name, Some(-2.0), None), Code::InvalidArgument),
        (bad(&name, Some(f64::NAN), None), Code::InvalidArgument),
        (bad(&name, Some(f64::INFINITY), None), Code::InvalidArgument),
        (bad(&name, Some(1000.0), None), Code::InvalidArgument),
        (bad(&name, None, Some(-0.5)), Code::InvalidArgument),
        (bad(&name, None, Some(f64::NAN)), Code::InvalidArgument),
        (
            bad(&name, None, Some(info.duration_s + 0.5)),
            Code::OutOfRange,
        ),
        (
            v1::ReplayRequest {
                mode: 99,
                ..bad(&name, None, None)
            },
            Code::InvalidArgument,
        ),
    ];
    for (request, expected) in cases {
        let what = format!("{request:?}");
        let got = recordings.replay(request).await;
        assert_eq!(code(got), Some(expected), "{what}");
    }

    // Files that are not recordings, or cannot be replayed, in the directory.
    let bytes = std::fs::read(&rec.file).unwrap();
    std::fs::write(dir.join("notes.mcap"), b"not a recording").unwrap();
    std::fs::write(dir.join("cut.mcap"), &bytes[..bytes.len() * 3 / 4]).unwrap();
    let chunks = &recording.mcap_summary().chunk_indexes;
    assert!(chunks.len() >= 2, "{} chunks", chunks.len());
    let chunk = &chunks[1];
    let mut damaged = bytes.clone();
    let middle = (chunk.chunk_start_offset + chunk.chunk_length / 2) as usize;
    for b in &mut damaged[middle..middle + 16] {
        *b ^= 0xA5;
    }
    std::fs::write(dir.join("damaged.mcap"), &damaged).unwrap();
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner()
        .recordings;
    assert!(listed.contains(info));
    assert!(listed.iter().all(|r| r.file != "notes.mcap"), "{listed:?}");
    // Cut short by a stopped server: listed as unfinished, replayed once recovered.
    let cut = listed.iter().find(|r| r.file == "cut.mcap").unwrap();
    assert_eq!(cut.state, v1::RecordingState::Unfinished as i32);
    assert!(!cut.in_progress);
    for file in ["notes.mcap", "cut.mcap"] {
        let status = recordings.replay(bad(file, None, None)).await.unwrap_err();
        assert_eq!(status.code(), Code::FailedPrecondition, "{file}");
        // Named by its name: the server's directory is none of the client's business.
        let message = status.message();
        assert!(
            message.contains(file) && !message.contains(&*dir.to_string_lossy()),
            "{message}"
        );
    }
    let damaged = match replay_all(&ch, None, bad("damaged.mcap", Some(100.0), None)).await {
        Err(status) => status,
        Ok((_, end)) => end.expect_err("the damaged chunk ends the replay"),
    };
    assert_eq!(damaged.code(), Code::DataLoss, "{damaged:?}");

    // Shutting down ends a replay as it ends live streams.
    let mut slow = recordings
        .replay(bad(&name, Some(0.01), None))
        .await
        .unwrap()
        .into_inner();
    assert!(matches!(
        slow.message().await.unwrap().unwrap().kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let shutdown = tokio::spawn(server.shutdown());
    let status = tokio::time::timeout(WAIT, async {
        loop {
            match slow.message().await {
                Ok(Some(_)) => {}
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .unwrap()
    .expect("the replay ends with a status");
    assert_eq!(status.code(), Code::Unavailable, "{status:?}");
    assert!(status.message().contains("shutting down"), "{status:?}");
    shutdown.await.unwrap().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trainees_review_recordings_and_only_instructors_watch_one_being_made() {
    let mut tokens = Tokens::default();
    tokens.insert(
        "instructor-token",
        Caller {
            name: "instructor".into(),
            role: Role::Instructor,
            instruments: None,
        },
    );
    tokens.insert(
        "trainee-token",
        Caller {
            name: "trainee".into(),
            role: Role::Trainee,
            instruments: None,
        },
    );
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
    end.unwrap();
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
    // The recordings "directory" is a file: the recorder cannot create its file.
    let blocker = std::env::temp_dir().join(format!("laparo-blocker-{}", std::process::id()));
    std::fs::write(&blocker, b"not a directory").unwrap();
    let server = TestServer::start(ServeConfig {
        recordings: Some(blocker.join("recordings")),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let info = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await
        .unwrap()
        .into_inner();
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
    let _ = std::fs::remove_file(&blocker);
}
