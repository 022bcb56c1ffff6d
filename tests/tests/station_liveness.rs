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

/// A connection whose HTTP/2 windows are small, so that a stream nobody reads
/// stops the server's sending once 16 KiB wait for it.
async fn frozen_channel(server: &TestServer) -> Channel {
    Endpoint::from_shared(format!("http://{}", server.addr))
        .unwrap()
        .initial_stream_window_size(16 * 1024)
        .initial_connection_window_size(16 * 1024)
        .connect()
        .await
        .unwrap()
}

/// An observer that takes none of its messages for the station timeout is cut and
/// gives its place back: it used to count among the session's observers, and have
/// every frame copied for it, for as long as its connection lasted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_observer_is_cut_and_leaves_its_place() {
    let server = server().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let observers = || async {
        v1::sessions_client::SessionsClient::new(ch.clone())
            .get_session(v1::GetSessionRequest {
                session_id: session.clone(),
            })
            .await
            .unwrap()
            .into_inner()
            .observer_count
    };
    let frozen = v1::observe_client::ObserveClient::new(frozen_channel(&server).await)
        .observe(v1::ObserveRequest {
            session_id: session.clone(),
            frame_rate_hz: None,
        })
        .await
        .unwrap();
    assert_eq!(observers().await, 1);
    let start = Instant::now();
    while observers().await != 0 && start.elapsed() < WAIT {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(observers().await, 0, "the frozen observer kept its place");
    assert!(start.elapsed() >= Duration::from_secs_f64(TIMEOUT_S * 0.9));
    drop(frozen);
    server.shutdown().await.unwrap();
}

/// A replay nobody reads ends after the station timeout and frees its
/// `--max-replays` slot: 64 stalled replays, any token's, used to refuse every
/// other replay for as long as their connections lasted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replay_nobody_reads_frees_its_slot() {
    use laparo_server::service::capacity::Capacity;
    let dir = laparo_tests::recordings::recordings_dir("stalled-replay");
    let server = TestServer::start(ServeConfig {
        station_timeout: StationTimeout::from_secs(TIMEOUT_S).unwrap(),
        recordings: Some(dir.clone()),
        capacity: Capacity {
            replays: 1,
            ..Capacity::of_this_machine()
        },
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let rec = laparo_tests::recordings::record_press(&ch, &dir, 1.0).await;
    let file = rec.file.file_name().unwrap().to_str().unwrap().to_string();
    let replay = |ch: Channel| {
        let file = file.clone();
        async move {
            v1::recordings_client::RecordingsClient::new(ch)
                .replay(v1::ReplayRequest {
                    file,
                    speed: Some(100.0),
                    ..Default::default()
                })
                .await
        }
    };
    let stalled = replay(frozen_channel(&server).await).await.unwrap();
    let refused = replay(ch.clone()).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    let _taken = once_not(Code::ResourceExhausted, || replay(ch.clone()))
        .await
        .expect("the stalled replay kept its slot");
    drop(stalled);
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
