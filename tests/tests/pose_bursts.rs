//! The pose rate limit against a real server on loopback: a burst of queued poses
//! after a network stall is admitted, sustained poses far above the limit close the
//! stream with `RESOURCE_EXHAUSTED`, leaving and joining again does not refill
//! an instrument's budget, and a whole bucket of poses at once is recorded whole.

use std::time::Duration;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::{PoseLimits, ServeConfig};
use laparo_tests::pressing::{flood_until_closed, front, state_of};
use laparo_tests::recordings::{create_recorded, recording_server};
use laparo_tests::server::*;
use tonic::Code;

const WAIT: Duration = Duration::from_secs(20);

/// What the server says of `session`.
async fn info(ch: tonic::transport::Channel, session: &str) -> v1::SessionInfo {
    v1::sessions_client::SessionsClient::new(ch)
        .get_session(v1::GetSessionRequest {
            session_id: session.into(),
        })
        .await
        .unwrap()
        .into_inner()
}

/// The `poses_rejected` and `poses_accepted` counts of `session`.
async fn counts(ch: tonic::transport::Channel, session: &str) -> (u64, u64) {
    let info = info(ch, session).await;
    (info.poses_rejected, info.poses_accepted)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_burst_after_a_stall_keeps_the_station_connected() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let f = front(&joined);
    let away = [f[0], f[1], f[2] + 0.05];
    let z = [0.0, 0.0, 1.0];
    // 0.2 s at 1 kHz, then a 0.3 s stall whose 300 poses arrive at once, then 0.2 s
    // more at 1 kHz: 700 poses, every one in order.
    let mut sequence = 0u64;
    let mut tick = tokio::time::interval(Duration::from_millis(1));
    for _ in 0..200 {
        tick.tick().await;
        sequence += 1;
        a.tx.send(pose("left", away, z, sequence)).await.unwrap();
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    for _ in 0..300 {
        sequence += 1;
        a.tx.send(pose("left", away, z, sequence)).await.unwrap();
    }
    for _ in 0..200 {
        tick.tick().await;
        sequence += 1;
        a.tx.send(pose("left", away, z, sequence)).await.unwrap();
    }
    // The newest pose is applied, and no message on the way was an error.
    let mut errors = Vec::new();
    let applied = wait_for(&mut a.rx, WAIT, |m| {
        if let Some(Kind::Error(e)) = &m.kind {
            errors.push(e.clone());
        }
        state_of(m, "left").is_some_and(|s| s.pose_sequence == Some(sequence))
    })
    .await;
    assert!(errors.is_empty(), "{errors:?}");
    assert!(applied.is_some(), "the newest pose was never applied");
    let (rejected, accepted) = counts(ch.clone(), &session).await;
    assert_eq!((rejected, accepted), (0, sequence));
    // Still connected: another pose is applied.
    sequence += 1;
    a.tx.send(pose("left", away, z, sequence)).await.unwrap();
    let applied = wait_for(&mut a.rx, WAIT, |m| {
        state_of(m, "left").is_some_and(|s| s.pose_sequence == Some(sequence))
    })
    .await;
    assert!(applied.is_some(), "the station was disconnected");
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sustained_poses_far_above_the_limit_close_the_stream() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let f = front(&joined);
    let away = [f[0], f[1], f[2] + 0.05];
    // As fast as the loopback carries them, until the server closes the stream (at
    // most 10^6 poses, each send bounded).
    let closed = flood_until_closed(&mut a, "left", away, 1, WAIT, Duration::from_secs(60)).await;
    assert!(closed.0 > 0, "no pose was rate-limited");
    assert_eq!(closed.1, Code::ResourceExhausted);
    let (rejected, _) = counts(ch.clone(), &session).await;
    assert!(rejected > 100, "{rejected}");
    server.shutdown().await.unwrap();
}

/// An instrument's pose budget stays with the instrument: a station that spent it,
/// left and joined again, is rate-limited at its first pose. Each join used to
/// start a full bucket, and a loop of joins sent 663,000 poses a second against a
/// limit of 2,000, drowning the recording.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn leaving_and_joining_again_does_not_refill_the_pose_budget() {
    // Five poses at once, then one every 100 s: nothing refills within the test.
    let server = TestServer::start(ServeConfig {
        pose_limits: PoseLimits {
            rate_hz: 0.01,
            burst: 5.0,
        },
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let rate_limited = |m: &v1::ServerMessage| matches!(&m.kind, Some(Kind::Error(e)) if e.code == v1::ErrorCode::RateLimited as i32);
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let f = front(&joined);
    let away = [f[0], f[1], f[2] + 0.05];
    let z = [0.0, 0.0, 1.0];
    for sequence in 1..=6 {
        a.tx.send(pose("left", away, z, sequence)).await.unwrap();
    }
    assert!(
        wait_for(&mut a.rx, WAIT, rate_limited).await.is_some(),
        "the sixth pose was not limited"
    );
    assert_eq!(counts(ch.clone(), &session).await, (1, 5));
    a.tx.send(v1::StationMessage {
        kind: Some(v1::station_message::Kind::Leave(v1::Leave::default())),
    })
    .await
    .unwrap();
    drop(a);
    // The instrument is free again once the first station is gone.
    let (mut b, _) = once_not(Code::AlreadyExists, || {
        join(ch.clone(), None, &session, &["left"])
    })
    .await
    .expect("left was never free again");
    b.tx.send(pose("left", away, z, 1)).await.unwrap();
    assert!(
        wait_for(&mut b.rx, WAIT, rate_limited).await.is_some(),
        "the budget was refilled"
    );
    assert_eq!(counts(ch.clone(), &session).await, (2, 5));
    server.shutdown().await.unwrap();
}

/// A whole pose budget at once (the default bucket, 10,000 poses, what a station
/// sends after a 5 s stall) is recorded whole, and so is every tick meanwhile: the
/// station's intake waits while the recorder drains instead of filling its channel.
/// Before, the burst overflowed the recorder's 4,096 items and the recording lost
/// thousands of poses and the frames of the ticks that came with them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_whole_budget_of_poses_at_once_is_recorded_whole() {
    let (server, ch, _dir) = recording_server("pose_burst").await;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    let session = create_recorded(&mut sessions).await.session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left", "right"])
        .await
        .unwrap();
    let f = front(&joined);
    let away = [f[0], f[1], f[2] + 0.05];
    let z = [0.0, 0.0, 1.0];
    let burst = PoseLimits::default().burst as u64;
    let messages: Vec<_> = (1..=burst)
        .flat_map(|s| ["left", "right"].map(|i| pose(i, away, z, s)))
        .collect();
    for m in messages {
        a.tx.send(m).await.unwrap();
    }
    let applied = wait_for(&mut a.rx, WAIT, |m| {
        state_of(m, "left").is_some_and(|s| s.pose_sequence == Some(burst))
    })
    .await;
    assert!(applied.is_some(), "the newest pose was never applied");
    let info = info(ch.clone(), &session).await;
    assert_eq!((info.poses_rejected, info.poses_accepted), (0, 2 * burst));
    assert_eq!(
        info.recorder_dropped, 0,
        "items left out of the recording (most waiting at once: {})",
        info.recorder_max_backlog
    );
    server.shutdown().await.unwrap();
}

/// A station configured faster than the server admits sends at the server's
/// limit, which `Joined` states, and so keeps its stream. At 1 kHz against a limit
/// of 40 Hz it would spend its 200-pose burst in about 0.2 s and then have
/// 960 poses a second refused, over the abuse limit: the stream would close.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_faster_than_the_limit_sends_at_the_limit_joined_states() {
    use laparo_client::station::{StationConfig, StationEnd, run_station};
    let rate_hz = 40.0;
    let server = TestServer::start(ServeConfig {
        pose_limits: PoseLimits {
            rate_hz,
            burst: laparo_server::session::input::stall_burst(rate_hz),
        },
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (_watch, joined) = join(ch.clone(), None, &session, &[]).await.unwrap();
    assert_eq!(joined.max_pose_rate_hz, rate_hz);
    drop(_watch);

    let mut config = StationConfig::new(
        format!("http://{}", server.addr),
        session.clone(),
        vec!["left".to_string()],
    );
    config.pose_rate_hz = 1000.0;
    config.duration = Some(Duration::from_millis(1500));
    let ran = run_station(config).await.unwrap();
    assert_eq!(ran.end, StationEnd::Duration, "{ran:?}");
    assert_eq!(ran.pose_rate_hz, rate_hz);
    assert!(ran.errors.is_empty(), "poses refused: {:?}", ran.errors);
    // 1.5 s at 40 Hz, less what joining took; far under what 1 kHz would send.
    assert!((20..=70).contains(&ran.poses_sent), "{}", ran.poses_sent);
    server.shutdown().await.unwrap();
}
