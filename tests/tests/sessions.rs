//! Live sessions over real gRPC on loopback: stations and an observer sharing a
//! session, every class of bad input, a station dropping and rejoining, and a
//! session closing itself when idle.

use std::time::Duration;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::ServeConfig;
use laparo_tests::pressing::*;
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

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
    assert_eq!(ended, Code::ResourceExhausted);
    // Poses far faster than the limit for longer than its stall window:
    // rate-limited, then the stream is closed.
    let closed = flood_until_closed(&mut a, "left", away, 100, WAIT, WAIT).await;
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
    // The instrument is withdrawn: it lets the tissue go.
    assert!(
        wait_for(&mut b.rx, WAIT, |m| state_of(m, "left")
            .is_some_and(
                |s| s.held_vertex_count == 0 && s.station_id.is_none()
            ))
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
