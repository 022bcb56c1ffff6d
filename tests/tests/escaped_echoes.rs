//! Text a client sends (names, ids, reasons, instruments) comes back in statuses
//! and events with its control characters escaped, so that no client can make the
//! server write terminal escapes onto another's screen. Against a real server on a
//! loopback port.

use std::time::Duration;

use laparo_proto::text::{needs_escape, printable};
use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_tests::server::{TestServer, create_session, join_raw, open, pose};
use tonic::Code;

const WAIT: Duration = Duration::from_secs(30);
/// Clears the screen, sets the window title, and reverses what follows.
const EVIL: &str = "\u{1b}[2J\u{1b}]0;owned\u{7}\u{202e}x";

fn clean(text: &str) -> bool {
    !text.chars().any(needs_escape)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn what_clients_send_is_echoed_escaped_in_statuses_and_events() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let shown = printable(EVIL).into_owned();
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());

    // Unknown ids and names, echoed in NOT_FOUND.
    let status = sessions
        .get_session(v1::GetSessionRequest {
            session_id: EVIL.into(),
        })
        .await
        .unwrap_err();
    assert_eq!(status.code(), Code::NotFound);
    assert!(
        clean(status.message()) && status.message().contains(&shown),
        "{status:?}"
    );
    let status = sessions
        .create_session(v1::CreateSessionRequest {
            scene: EVIL.into(),
            idle_timeout_s: None,
            record: Some(false),
        })
        .await
        .unwrap_err();
    assert_eq!(status.code(), Code::NotFound);
    assert!(
        clean(status.message()) && status.message().contains(&shown),
        "{status:?}"
    );

    // A station named with escapes, sending a pose for an instrument named with
    // them, then its session closed with a reason made of them: every event and
    // the stream's end come back escaped.
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let mut observer = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.clone(),
            frame_rate_hz: Some(1.0),
        })
        .await
        .unwrap()
        .into_inner();
    // Subscribed once the scene has come.
    observer.message().await.unwrap().expect("the scene");
    let mut first = open(&session, &["left"]);
    if let Some(v1::station_message::Kind::Open(j)) = &mut first.kind {
        j.client_name = EVIL.into();
    }
    let station = join_raw(ch.clone(), None, Some(first)).await.unwrap();
    station
        .tx
        .send(pose(EVIL, [0.0, 0.0, 0.1], [0.0, 0.0, 1.0], 1))
        .await
        .unwrap();
    let mut events = Vec::new();
    let end = tokio::time::timeout(WAIT, async {
        loop {
            match observer.message().await {
                Ok(Some(v1::ObserveMessage {
                    kind: Some(v1::observe_message::Kind::Event(e)),
                })) => {
                    if e.kind == v1::EventKind::InputRejected as i32 {
                        let info = sessions
                            .get_session(v1::GetSessionRequest {
                                session_id: session.clone(),
                            })
                            .await
                            .unwrap()
                            .into_inner();
                        for st in &info.stations {
                            assert!(clean(&st.client_name), "{st:?}");
                        }
                        sessions
                            .close_session(v1::CloseSessionRequest {
                                session_id: session.clone(),
                                reason: EVIL.into(),
                            })
                            .await
                            .unwrap();
                    }
                    events.push(e);
                }
                Ok(Some(_)) => {}
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .expect("the stream ends once the session closes");
    // The closing reason: in the closing event or the stream's end, escaped.
    let closing = events
        .iter()
        .find(|e| e.kind == v1::EventKind::SessionClosing as i32)
        .map(|e| e.detail.clone())
        .or_else(|| end.as_ref().map(|s| s.message().to_string()))
        .expect("the close is told");
    assert!(closing.contains(&shown), "{closing:?}");
    for kind in [v1::EventKind::StationJoined, v1::EventKind::InputRejected] {
        assert!(
            events
                .iter()
                .any(|e| e.kind == kind as i32 && e.detail.contains(&shown)),
            "no {kind:?} naming the escaped text in {events:?}"
        );
    }
    for e in &events {
        assert!(clean(&e.detail), "{e:?}");
        assert!(e.instrument.as_deref().is_none_or(clean), "{e:?}");
    }
    if let Some(status) = end {
        assert!(clean(status.message()), "{status:?}");
    }
    drop(station);
    server.shutdown().await.unwrap();
}
