//! `Sessions.EvictStation`: an instructor ends a station's stream and frees its
//! instruments; a trainee may not; the session's streams are told who and why.

use laparo_proto::v1;
use laparo_server::service::{Caller, Role, ServeConfig, Tokens};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

const TEACHER: Option<&str> = Some("instructor-token");
const TRAINEE: Option<&str> = Some("trainee-token");

async fn server_with_tokens() -> TestServer {
    let mut tokens = Tokens::default();
    for (token, name, role) in [
        (TEACHER, "Dr Ayache", Role::Instructor),
        (TRAINEE, "trainee", Role::Trainee),
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
    TestServer::start(ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    })
    .await
}

async fn evict(
    ch: &Channel,
    token: Option<&str>,
    session: &str,
    station: u64,
    reason: &str,
) -> Result<v1::EvictStationResponse, tonic::Status> {
    v1::sessions_client::SessionsClient::new(ch.clone())
        .evict_station(with_token(
            v1::EvictStationRequest {
                session_id: session.into(),
                station_id: station,
                reason: reason.into(),
            },
            token,
        ))
        .await
        .map(|r| r.into_inner())
}

async fn holder(ch: &Channel, session: &str, instrument: &str) -> Option<u64> {
    v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(with_token(
            v1::GetSessionRequest {
                session_id: session.to_string(),
            },
            TEACHER,
        ))
        .await
        .unwrap()
        .into_inner()
        .instruments
        .into_iter()
        .find(|h| h.instrument == instrument)
        .and_then(|h| h.station_id)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_instructor_evicts_a_station_and_a_trainee_may_not() {
    let server = server_with_tokens().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (mut watcher, _) = join(ch.clone(), TEACHER, &session, &[]).await.unwrap();
    let (mut trainee, joined) = join(ch.clone(), TRAINEE, &session, &["left"])
        .await
        .unwrap();
    let id = joined.station_id;

    let refused = evict(&ch, TRAINEE, &session, id, "mine now")
        .await
        .unwrap_err();
    assert_eq!(refused.code(), Code::PermissionDenied, "{refused:?}");
    assert_eq!(holder(&ch, &session, "left").await, Some(id));

    let evicted = evict(&ch, TEACHER, &session, id, "hands off the liver")
        .await
        .unwrap()
        .station
        .unwrap();
    assert_eq!(evicted.station_id, id);
    assert_eq!(evicted.instruments, ["left"]);
    // Free when the call returns: another station claims it at once.
    assert_eq!(holder(&ch, &session, "left").await, None);
    let (_next, _) = join(ch.clone(), TRAINEE, &session, &["left"])
        .await
        .unwrap();

    // The evicted station's stream ends saying who and why.
    let status = final_status(&mut trainee.rx)
        .await
        .expect("an error status");
    assert_eq!(status.code(), Code::Aborted, "{status:?}");
    for words in ["evicted", "Dr Ayache", "hands off the liver"] {
        assert!(status.message().contains(words), "{status:?}");
    }
    // The session's streams are told, then the station leaves.
    let mut kinds = Vec::new();
    let _ = wait_for(&mut watcher.rx, WAIT, |m| match &m.kind {
        Some(v1::server_message::Kind::Event(e)) if e.station_id == Some(id) => {
            if e.kind == v1::EventKind::StationEvicted as i32 {
                assert!(e.detail.contains("Dr Ayache"), "{e:?}");
                assert!(e.detail.contains("hands off the liver"), "{e:?}");
            }
            kinds.push(e.kind);
            e.kind == v1::EventKind::StationLeft as i32
        }
        _ => false,
    })
    .await;
    assert_eq!(
        kinds,
        [
            v1::EventKind::StationJoined as i32,
            v1::EventKind::StationEvicted as i32,
            v1::EventKind::StationLeft as i32
        ]
    );
    drop((watcher, trainee));
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn evicting_what_is_not_there_or_with_too_long_a_reason_is_refused() {
    let server = server_with_tokens().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    let (_station, joined) = join(ch.clone(), TRAINEE, &session, &["left"])
        .await
        .unwrap();
    let unknown = evict(&ch, TEACHER, &session, joined.station_id + 1, "")
        .await
        .unwrap_err();
    assert_eq!(unknown.code(), Code::NotFound, "{unknown:?}");
    let no_session = evict(&ch, TEACHER, "s999", joined.station_id, "")
        .await
        .unwrap_err();
    assert_eq!(no_session.code(), Code::NotFound, "{no_session:?}");
    let long = evict(&ch, TEACHER, &session, joined.station_id, &"x".repeat(1025))
        .await
        .unwrap_err();
    assert_eq!(long.code(), Code::InvalidArgument, "{long:?}");
    assert!(long.message().contains("reason"), "{long:?}");
    // None of them touched the station.
    assert_eq!(holder(&ch, &session, "left").await, Some(joined.station_id));
    server.shutdown().await.unwrap();
}
