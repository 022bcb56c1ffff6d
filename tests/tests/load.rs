//! `laparo load` against a real server on loopback: one posing station per free
//! instrument, the others only receiving, every station counted, the pose-to-state
//! latency measured, and the session created for the run closed at its end.

use std::time::Duration;

use laparo_client::connect::ConnectConfig;
use laparo_client::load::{LoadConfig, run_load};
use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_tests::server::TestServer;
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_load_run_poses_from_one_station_per_free_instrument_and_closes_its_session() {
    let server = TestServer::start(ServeConfig::default()).await;
    let config = LoadConfig {
        connect: ConnectConfig::new(format!("http://{}", server.addr)),
        session: None,
        stations: 3,
        pose_rate_hz: 100.0,
        duration: Duration::from_secs(2),
        surface_frame_rate_hz: None,
        scene: None,
        record: Some(false),
    };
    let summary = run_load(config, |_| {}).await.unwrap();
    assert!(summary.failures.is_empty(), "{:?}", summary.failures);
    assert!(summary.created_session && !summary.recorded);
    // The default scene has two instruments: two stations pose, the third receives.
    assert_eq!((summary.stations, summary.posing_stations), (3, 2));
    assert_eq!(summary.frames_per_station.len(), 3);
    assert!(
        summary.frames_per_station.iter().all(|&f| f > 0),
        "{:?}",
        summary.frames_per_station
    );
    assert!(summary.states > 0);
    assert!(summary.errors.is_empty(), "{:?}", summary.errors);
    // Every pose the session accepted was sent by a station of the run, and each
    // latency measured is that of one pose sent.
    assert!(summary.poses_sent > 0);
    assert!(
        (1..=summary.poses_sent).contains(&summary.poses_accepted),
        "{} accepted of {} sent",
        summary.poses_accepted,
        summary.poses_sent
    );
    assert!(
        (1..=summary.poses_sent).contains(&summary.latency.count),
        "{:?}",
        summary.latency
    );
    let mut sessions = v1::sessions_client::SessionsClient::new(server.channel().await);
    let gone = sessions
        .get_session(v1::GetSessionRequest {
            session_id: summary.session_id.clone(),
        })
        .await
        .unwrap_err();
    assert_eq!(gone.code(), Code::NotFound);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_closed_under_a_load_run_is_said_by_its_stations() {
    let server = TestServer::start(ServeConfig::default()).await;
    let mut sessions = v1::sessions_client::SessionsClient::new(server.channel().await);
    let session = sessions
        .create_session(v1::CreateSessionRequest::default())
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let config = LoadConfig {
        connect: ConnectConfig::new(format!("http://{}", server.addr)),
        session: Some(session.clone()),
        stations: 2,
        pose_rate_hz: 100.0,
        duration: Duration::from_secs(20),
        surface_frame_rate_hz: None,
        scene: None,
        record: Some(false),
    };
    let run = tokio::spawn(run_load(config, |_| {}));
    tokio::time::sleep(Duration::from_millis(1500)).await;
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: session,
            reason: "end of exercise".into(),
        })
        .await
        .unwrap();
    // The run ends saying why its stations stopped, not with the session it can
    // no longer find.
    let summary = run.await.unwrap().unwrap();
    assert_eq!(summary.failures.len(), 2, "{:?}", summary.failures);
    assert!(
        summary
            .failures
            .iter()
            .all(|f| f.why.contains("end of exercise")),
        "{:?}",
        summary.failures
    );
    let gone = summary.session_gone.as_deref().unwrap_or_default();
    assert!(gone.contains("no session"), "{gone}");
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_larger_than_a_session_takes_is_refused_and_leaves_no_session() {
    let server = TestServer::start(ServeConfig::default()).await;
    let mut sessions = v1::sessions_client::SessionsClient::new(server.channel().await);
    let max = laparo_server::service::limits::MAX_STATIONS_PER_SESSION;
    let config = LoadConfig {
        connect: ConnectConfig::new(format!("http://{}", server.addr)),
        session: None,
        stations: max + 1,
        pose_rate_hz: 100.0,
        duration: Duration::from_secs(2),
        surface_frame_rate_hz: None,
        scene: None,
        record: Some(false),
    };
    let e = run_load(config, |_| {}).await.unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("it takes at most {max} at once and has 0")),
        "{e}"
    );
    // The session it created to find the limit is closed again.
    let left = sessions
        .list_sessions(v1::ListSessionsRequest::default())
        .await
        .unwrap()
        .into_inner()
        .sessions;
    assert!(left.is_empty(), "{left:?}");
    // The limit is the one the server states, and the one its joins enforce.
    let session = sessions
        .create_session(v1::CreateSessionRequest::default())
        .await
        .unwrap()
        .into_inner();
    assert_eq!(session.max_stations as usize, max);
    server.shutdown().await.unwrap();
}

/// Posing stations asked to send faster than the server admits send at its rate
/// (`Joined.max_pose_rate_hz`), as `laparo station` does: above it they emptied
/// their burst allowance, had poses refused and lost their streams.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_load_run_faster_than_the_server_admits_poses_at_its_rate() {
    let admitted = 40.0;
    let server = TestServer::start(ServeConfig {
        pose_limits: laparo_server::service::PoseLimits {
            rate_hz: admitted,
            burst: 5.0,
        },
        ..ServeConfig::default()
    })
    .await;
    let config = LoadConfig {
        connect: ConnectConfig::new(format!("http://{}", server.addr)),
        session: None,
        stations: 1,
        pose_rate_hz: 1000.0,
        duration: Duration::from_secs(3),
        surface_frame_rate_hz: None,
        scene: None,
        record: Some(false),
    };
    let summary = run_load(config, |_| {}).await.unwrap();
    assert!(summary.failures.is_empty(), "{:?}", summary.failures);
    assert!(summary.errors.is_empty(), "{:?}", summary.errors);
    assert_eq!(summary.posing_stations, 1);
    assert_eq!(summary.pose_rate_hz, admitted);
    assert_eq!(summary.poses_rejected, 0);
    // At most 3 s at 40 Hz and the first at once (a busy machine sends fewer).
    assert!(
        (1..=121).contains(&summary.poses_sent),
        "{} poses sent",
        summary.poses_sent
    );
}
