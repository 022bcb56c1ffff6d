//! A station that is gone loses its instruments: one that sends nothing, or that
//! stops taking the server's messages, for the station timeout is timed out with
//! an event, its stream ends with DEADLINE_EXCEEDED, another station may claim
//! what it held, and the session's idle timeout counts from then. A station that
//! only sends heartbeats is there and keeps its claim.

use std::time::{Duration, Instant};

use laparo_proto::v1;
use laparo_server::service::{ServeConfig, StationTimeout};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::{Channel, Endpoint};

/// The station timeout of these tests, s: the shortest the server accepts is 0.5 s;
/// a second keeps the tests short and a loaded machine from taking a live test
/// station for gone.
const TIMEOUT_S: f64 = 1.0;

async fn server() -> TestServer {
    TestServer::start(ServeConfig {
        station_timeout: StationTimeout::from_secs(TIMEOUT_S).unwrap(),
        ..ServeConfig::default()
    })
    .await
}

fn heartbeat() -> v1::StationMessage {
    v1::StationMessage {
        kind: Some(v1::station_message::Kind::Heartbeat(v1::Heartbeat {})),
    }
}

/// An observer of `session`'s events.
async fn observe(ch: &Channel, session: &str) -> tonic::Streaming<v1::ObserveMessage> {
    v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.to_string(),
            frame_rate_hz: Some(1.0),
        })
        .await
        .unwrap()
        .into_inner()
}

/// The kinds and details of the events of `station` the observer sees, until a
/// STATION_LEFT of it (or `WAIT`).
async fn events_until_left(
    observer: &mut tonic::Streaming<v1::ObserveMessage>,
    station: u64,
) -> Vec<(i32, String)> {
    let mut seen = Vec::new();
    let _ = tokio::time::timeout(WAIT, async {
        while let Ok(Some(m)) = observer.message().await {
            if let Some(v1::observe_message::Kind::Event(e)) = m.kind
                && e.station_id == Some(station)
            {
                seen.push((e.kind, e.detail));
                if e.kind == v1::EventKind::StationLeft as i32 {
                    return;
                }
            }
        }
    })
    .await;
    seen
}

async fn holder(ch: &Channel, session: &str, instrument: &str) -> Option<u64> {
    v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(v1::GetSessionRequest {
            session_id: session.to_string(),
        })
        .await
        .unwrap()
        .into_inner()
        .instruments
        .into_iter()
        .find(|h| h.instrument == instrument)
        .and_then(|h| h.station_id)
}

/// The status a station's stream ends with, reading (and dropping) what comes
/// before it.
async fn final_status(rx: &mut tonic::Streaming<v1::ServerMessage>) -> Option<tonic::Status> {
    tokio::time::timeout(WAIT, async {
        loop {
            match rx.message().await {
                Ok(Some(_)) => continue,
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .expect("the stream ends")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_silent_station_loses_its_claim_with_an_event_and_another_may_claim_it() {
    let server = server().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let mut observer = observe(&ch, &session).await;
    let (mut silent, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let last_word = Instant::now();
    assert_eq!(holder(&ch, &session, "left").await, Some(joined.station_id));
    // It sends nothing more, and keeps its stream open.
    let events = events_until_left(&mut observer, joined.station_id).await;
    let released_after = last_word.elapsed();
    let kinds: Vec<i32> = events.iter().map(|e| e.0).collect();
    assert_eq!(
        kinds,
        [
            v1::EventKind::StationJoined as i32,
            v1::EventKind::StationTimedOut as i32,
            v1::EventKind::StationLeft as i32
        ],
        "{events:?}"
    );
    assert!(events[1].1.contains("sent nothing"), "{events:?}");
    // Not before the timeout.
    assert!(
        released_after >= Duration::from_secs_f64(TIMEOUT_S),
        "released after {released_after:?}"
    );
    assert_eq!(holder(&ch, &session, "left").await, None);
    let status = final_status(&mut silent.rx).await.expect("an error status");
    assert_eq!(status.code(), Code::DeadlineExceeded, "{status:?}");
    assert!(status.message().contains("sent nothing"), "{status:?}");
    // The instrument is free for another station.
    let (_other, rejoined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    assert_eq!(
        holder(&ch, &session, "left").await,
        Some(rejoined.station_id)
    );
    drop(silent);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_station_that_sends_but_never_reads_loses_its_claim() {
    let server = server().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let mut observer = observe(&ch, &session).await;
    // Its own connection, with small HTTP/2 windows: a client that does not read
    // stops the server's sending once 16 KiB wait for it.
    let frozen_ch = Endpoint::from_shared(format!("http://{}", server.addr))
        .unwrap()
        .initial_stream_window_size(16 * 1024)
        .initial_connection_window_size(16 * 1024)
        .connect()
        .await
        .unwrap();
    let (frozen, joined) = join(frozen_ch, None, &session, &["left"]).await.unwrap();
    // It keeps saying it is there, ten times a timeout, and reads nothing.
    let tx = frozen.tx.clone();
    let beating = tokio::spawn(async move {
        for _ in 0..(TIMEOUT_S * 10.0 * 20.0) as usize {
            if tx.send(heartbeat()).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    });
    let events = events_until_left(&mut observer, joined.station_id).await;
    let timed_out = events
        .iter()
        .find(|e| e.0 == v1::EventKind::StationTimedOut as i32);
    assert!(
        timed_out.is_some_and(|e| e.1.contains("took none")),
        "{events:?}"
    );
    assert_eq!(
        events.last().map(|e| e.0),
        Some(v1::EventKind::StationLeft as i32)
    );
    assert_eq!(holder(&ch, &session, "left").await, None);
    let (_other, _) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    beating.abort();
    drop(frozen);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_that_only_beats_keeps_its_claim() {
    let server = server().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut station, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    // Three timeouts of heartbeats, a beat every quarter timeout, reading all.
    let beats = 12;
    for _ in 0..beats {
        station.tx.send(heartbeat()).await.unwrap();
        let quarter = Duration::from_secs_f64(TIMEOUT_S / 4.0);
        let _ = tokio::time::timeout(quarter, async {
            while let Ok(Some(_)) = station.rx.message().await {}
        })
        .await;
    }
    assert_eq!(holder(&ch, &session, "left").await, Some(joined.station_id));
    drop(station);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_idle_timeout_counts_from_the_release_of_a_silent_station() {
    let server = server().await;
    let ch = server.channel().await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let session = sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: Some(1.0),
            record: None,
        })
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let (mut silent, _) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    // The station's stream stays open on this side; the server times it out, then
    // finds the session idle and closes it.
    let status = final_status(&mut silent.rx).await.expect("an error status");
    assert_eq!(status.code(), Code::DeadlineExceeded, "{status:?}");
    let get = v1::GetSessionRequest {
        session_id: session.clone(),
    };
    let closed = tokio::time::timeout(WAIT, async {
        loop {
            match sessions.get_session(get.clone()).await {
                Err(s) if s.code() == Code::NotFound => return,
                _ => tokio::time::sleep(Duration::from_millis(100)).await,
            }
        }
    })
    .await;
    assert!(closed.is_ok(), "the session never idled out");
    drop(silent);
    server.shutdown().await.unwrap();
}
