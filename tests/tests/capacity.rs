//! What a server takes on at once: sessions and replays past their limits are
//! refused with `RESOURCE_EXHAUSTED` naming the limit and its flag, and accepted
//! again once one ends; slow replays, more than the blocking pool has threads,
//! starve neither listing nor another replay.

use laparo_proto::v1;
use laparo_proto::v1::recordings_client::RecordingsClient;
use laparo_proto::v1::sessions_client::SessionsClient;
use laparo_server::recording::Recording;
use laparo_server::service::ServeConfig;
use laparo_server::service::capacity::Capacity;
use laparo_tests::recordings::{
    record_press, recorded_messages, recordings_dir, replay_all, replay_request,
};
use laparo_tests::server::{TestServer, WAIT, once_not};
use tonic::Code;

fn limits(sessions: usize, replays: usize) -> Capacity {
    Capacity {
        sessions,
        connections: 64,
        connections_per_peer: 64,
        replays,
    }
}

fn create() -> v1::CreateSessionRequest {
    v1::CreateSessionRequest {
        scene: "default".into(),
        idle_timeout_s: None,
        record: Some(false),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_past_the_limit_is_refused_naming_the_flag_until_one_closes() {
    let server = TestServer::start(ServeConfig {
        capacity: limits(2, 4),
        ..ServeConfig::default()
    })
    .await;
    let mut sessions = SessionsClient::new(server.channel().await);
    let first = sessions
        .create_session(create())
        .await
        .unwrap()
        .into_inner();
    sessions.create_session(create()).await.unwrap();
    let refused = sessions.create_session(create()).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(refused.message().contains("2 sessions"), "{refused:?}");
    assert!(refused.message().contains("--max-sessions"), "{refused:?}");
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: first.session_id,
            reason: "room for another".into(),
        })
        .await
        .unwrap();
    sessions.create_session(create()).await.unwrap();
    server.shutdown().await.unwrap();
}

/// A scene larger than a session's share of memory counts as several sessions:
/// SOFA's liver refined twice (38,144 tetrahedra) as two. Sessions of a scene of
/// any size could otherwise fill the limit, sized for 64 MiB a session, with
/// gigabytes (a coarse liver refined three times holds 400 MB).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_large_scene_counts_as_several_sessions_and_its_refusal_says_so() {
    let dir = recordings_dir("large-scene");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let default = include_str!("../../server/scenes/default.toml");
    let large = default
        .replacen("name = \"default\"", "name = \"large\"", 1)
        .replacen("[mesh]", "[mesh]\nrefine = 2", 1);
    std::fs::write(scenes.join("large.toml"), large).unwrap();
    let server = TestServer::start(ServeConfig {
        scene_dir: Some(scenes.clone()),
        recordings: Some(dir.clone()),
        capacity: limits(3, 4),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let mut sessions = SessionsClient::new(ch.clone());
    let of = |scene: &str| v1::CreateSessionRequest {
        scene: scene.into(),
        ..create()
    };
    let recorded = sessions
        .create_session(v1::CreateSessionRequest {
            record: Some(true),
            ..of("large")
        })
        .await
        .unwrap()
        .into_inner();
    // Re-simulating its recording would build the scene again, 7 replays' worth of
    // memory where the server streams 4; as recorded it is one replay.
    sessions
        .close_session(v1::CloseSessionRequest {
            session_id: recorded.session_id,
            reason: "recorded".into(),
        })
        .await
        .unwrap();
    let file = recorded.recording_file.unwrap();
    let mut resimulated = replay_request(&file, None, None);
    resimulated.mode = v1::ReplayMode::Resimulate as i32;
    let refused = RecordingsClient::new(ch.clone())
        .replay(resimulated)
        .await
        .unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    for words in [
        "38144 tetrahedra",
        "counts as 7 of the 4 replays",
        "--max-replays",
    ] {
        assert!(refused.message().contains(words), "{refused:?}");
    }
    RecordingsClient::new(ch.clone())
        .replay(replay_request(&file, None, None))
        .await
        .unwrap();
    sessions.create_session(of("large")).await.unwrap();
    let refused = sessions.create_session(of("large")).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    for words in [
        "`large`",
        "38144 tetrahedra",
        "counts as 2 of the 3",
        "--max-sessions",
    ] {
        assert!(refused.message().contains(words), "{refused:?}");
    }
    // The one left is a default session's.
    sessions.create_session(of("default")).await.unwrap();
    let refused = sessions.create_session(of("default")).await.unwrap_err();
    assert!(refused.message().contains("3 sessions"), "{refused:?}");
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// A replay at the slowest speed, open until dropped, once its scene has come.
async fn slow_replay(
    ch: &tonic::transport::Channel,
    name: &str,
) -> Result<tonic::Streaming<v1::ObserveMessage>, tonic::Status> {
    let mut stream = RecordingsClient::new(ch.clone())
        .replay(replay_request(name, Some(0.01), None))
        .await?
        .into_inner();
    let first = tokio::time::timeout(WAIT, stream.message())
        .await
        .expect("the scene comes")
        .unwrap()
        .unwrap();
    assert!(matches!(
        first.kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    Ok(stream)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replay_past_the_limit_is_refused_naming_the_flag_until_one_ends() {
    let dir = recordings_dir("replay-limit");
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        capacity: limits(4, 2),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let rec = record_press(&ch, &dir, 0.5).await;
    let name = rec.file.file_name().unwrap().to_str().unwrap().to_string();
    let a = slow_replay(&ch, &name).await.unwrap();
    let _b = slow_replay(&ch, &name).await.unwrap();
    let refused = slow_replay(&ch, &name).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(refused.message().contains("2 replays"), "{refused:?}");
    assert!(refused.message().contains("--max-replays"), "{refused:?}");
    // Once a client goes, its slot is free (when the server has seen it go).
    drop(a);
    once_not(Code::ResourceExhausted, || slow_replay(&ch, &name))
        .await
        .expect("a slot frees up");
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// More paced replays than the blocking pool has threads: had each held a thread
/// while it waits for its client, listing (which reads on the pool) would wait
/// for ever behind them.
#[test]
fn slow_replays_beyond_the_blocking_pool_starve_neither_listing_nor_another_replay() {
    const BLOCKING_THREADS: usize = 2;
    const SLOW: usize = 4 * BLOCKING_THREADS;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .max_blocking_threads(BLOCKING_THREADS)
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let dir = recordings_dir("slow-replays");
        let server = TestServer::start(ServeConfig {
            recordings: Some(dir.clone()),
            capacity: limits(4, 64),
            ..ServeConfig::default()
        })
        .await;
        let ch = server.channel().await;
        let rec = record_press(&ch, &dir, 0.5).await;
        let name = rec.file.file_name().unwrap().to_str().unwrap().to_string();
        let mut slow = Vec::new();
        for _ in 0..SLOW {
            slow.push(slow_replay(&ch, &name).await.unwrap());
        }
        // Listing answers (the bound only turns a starved pool into a failure).
        let listed = tokio::time::timeout(
            WAIT,
            RecordingsClient::new(ch.clone()).list_recordings(v1::ListRecordingsRequest {}),
        )
        .await
        .expect("listing is not starved by slow replays")
        .unwrap()
        .into_inner()
        .recordings;
        assert_eq!(listed.len(), 1);
        // Another replay, at the fastest speed, sends the whole file and ends.
        let (got, end) = replay_all(&ch, None, replay_request(&name, Some(100.0), None))
            .await
            .unwrap();
        end.unwrap();
        let file = recorded_messages(&Recording::open(&rec.file).unwrap());
        assert_eq!(got.len(), 1 + file.len(), "the scene and every message");
        drop(slow);
        server.shutdown().await.unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    });
}

/// Before a replay's start offset nothing is sent, yet a re-simulated burst still
/// ends after `BURST_TICKS` ticks: the reading goes back to `feed`, which looks
/// whether the stream is still wanted, between every few ticks. A first burst used
/// to re-simulate everything up to the offset at once: a large scene's replay,
/// cancelled at once, worked on for 40 s past the `--max-replays` slot it had freed.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_resimulated_burst_before_the_start_offset_stops_after_a_few_ticks() {
    use laparo_server::service::replay::{BURST_TICKS, ReadResimulated, Reader};
    let dir = recordings_dir("burst-before-offset");
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        ..ServeConfig::default()
    })
    .await;
    let rec = record_press(&server.channel().await, &dir, 1.0).await;
    server.shutdown().await.unwrap();
    let name = rec.file.file_name().unwrap().to_str().unwrap().to_string();
    let recording = Recording::open(&rec.file).unwrap();
    let ticks = recorded_messages(&recording)
        .iter()
        .filter(|(_, m)| matches!(m.kind, Some(v1::observe_message::Kind::SurfaceFrame(_))))
        .count();
    assert!(ticks > 3 * BURST_TICKS, "{ticks} ticks recorded");
    // An offset past the recording's end: every burst but the last sends nothing.
    let mut reader = ReadResimulated::new(std::sync::Arc::new(recording), name, 1e3, None);
    let mut bursts = 0;
    loop {
        let mut out = Vec::new();
        let more = reader.read(&mut out);
        bursts += 1;
        if !more {
            break;
        }
        assert!(out.is_empty(), "burst {bursts} sent before the offset");
    }
    assert!(
        bursts >= ticks / BURST_TICKS,
        "{ticks} ticks re-simulated in {bursts} bursts"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
