//! Every client string is bounded at the edge, and one caller's joins are bounded
//! in rate, so that no client can flood observers and recordings with events.

use std::time::Instant;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::ServeConfig;
use laparo_server::service::join_rate::{JOIN_BURST, JOINS_PER_SECOND};
use laparo_server::service::limits::{MAX_NAME_BYTES, MAX_REASON_BYTES};
use laparo_tests::server::*;
use tonic::Code;

fn long(n: usize) -> String {
    "x".repeat(n + 1)
}

fn refused(r: Result<impl std::fmt::Debug, tonic::Status>, field: &str, limit: usize) {
    let e = r.expect_err("an over-long string is refused");
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains(field), "{field} not named: {e:?}");
    assert!(
        e.message().contains(&limit.to_string()),
        "limit not named: {e:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_long_strings_in_each_request_are_refused_naming_the_field() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let id = create_session(ch.clone(), None).await.unwrap().session_id;
    let mut sessions = v1::sessions_client::SessionsClient::new(ch.clone());
    refused(
        sessions
            .create_session(v1::CreateSessionRequest {
                scene: long(MAX_NAME_BYTES),
                ..Default::default()
            })
            .await,
        "scene",
        MAX_NAME_BYTES,
    );
    refused(
        sessions
            .get_session(v1::GetSessionRequest {
                session_id: long(MAX_NAME_BYTES),
            })
            .await,
        "session_id",
        MAX_NAME_BYTES,
    );
    refused(
        sessions
            .close_session(v1::CloseSessionRequest {
                session_id: id.clone(),
                reason: long(MAX_REASON_BYTES),
            })
            .await,
        "reason",
        MAX_REASON_BYTES,
    );
    refused(
        v1::scenes_client::ScenesClient::new(ch.clone())
            .get_scene(v1::GetSceneRequest {
                name: long(MAX_NAME_BYTES),
            })
            .await,
        "name",
        MAX_NAME_BYTES,
    );
    refused(
        v1::observe_client::ObserveClient::new(ch.clone())
            .observe(v1::ObserveRequest {
                session_id: long(MAX_NAME_BYTES),
                ..Default::default()
            })
            .await
            .map(|_| ()),
        "session_id",
        MAX_NAME_BYTES,
    );
    refused(
        v1::recordings_client::RecordingsClient::new(ch.clone())
            .replay(v1::ReplayRequest {
                file: long(MAX_NAME_BYTES),
                ..Default::default()
            })
            .await
            .map(|_| ()),
        "file",
        MAX_NAME_BYTES,
    );
    let opening = |f: &dyn Fn(&mut v1::JoinRequest)| {
        let mut m = open(&id, &["left"]);
        if let Some(v1::station_message::Kind::Open(o)) = &mut m.kind {
            f(o);
        }
        m
    };
    for (field, m) in [
        (
            "client_name",
            opening(&|o| o.client_name = long(MAX_NAME_BYTES)),
        ),
        (
            "session_id",
            opening(&|o| o.session_id = long(MAX_NAME_BYTES)),
        ),
        (
            "instruments",
            opening(&|o| o.instruments = vec![long(MAX_NAME_BYTES)]),
        ),
    ] {
        refused(
            join_raw(ch.clone(), None, Some(m)).await.map(|_| ()),
            field,
            MAX_NAME_BYTES,
        );
    }
    // At the limit is accepted.
    let mut m = open(&id, &["left"]);
    if let Some(v1::station_message::Kind::Open(o)) = &mut m.kind {
        o.client_name = "x".repeat(MAX_NAME_BYTES);
    }
    let mut s = join_raw(ch.clone(), None, Some(m)).await.unwrap();
    assert!(matches!(
        s.rx.message().await.unwrap().and_then(|m| m.kind),
        Some(Kind::Joined(_))
    ));
    drop(s);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn join_leave_churn_is_cut_off_and_observers_see_a_bounded_number_of_events() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let id = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut watcher, _) = join(ch.clone(), None, &id, &[]).await.unwrap();
    let started = Instant::now();
    let mut admitted = 1usize; // the watcher
    let mut cut_off = None;
    for _ in 0..10 * JOIN_BURST as usize {
        // Watching stations: no instrument to wait for, each join an event.
        let mut m = open(&id, &[]);
        if let Some(v1::station_message::Kind::Open(o)) = &mut m.kind {
            o.client_name = "x".repeat(MAX_NAME_BYTES);
        }
        match join_raw(ch.clone(), None, Some(m)).await {
            Ok(mut s) => {
                admitted += 1;
                let _ = s.rx.message().await;
                drop(s); // leaves
            }
            Err(e) => {
                cut_off = Some(e);
                break;
            }
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    let e = cut_off.expect("the churn is cut off");
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("a second"), "{e:?}");
    let bound = JOIN_BURST + JOINS_PER_SECOND * elapsed + 1.0;
    assert!(admitted as f64 <= bound, "{admitted} joins > {bound}");

    v1::sessions_client::SessionsClient::new(ch.clone())
        .close_session(v1::CloseSessionRequest {
            session_id: id.clone(),
            reason: "done".into(),
        })
        .await
        .unwrap();
    let mut station_events = 0usize;
    while let Ok(Some(m)) = watcher.rx.message().await {
        if let Some(Kind::Event(e)) = &m.kind
            && (e.kind == v1::EventKind::StationJoined as i32
                || e.kind == v1::EventKind::StationLeft as i32)
        {
            station_events += 1;
        }
    }
    assert!(
        station_events <= 2 * admitted,
        "{station_events} join/leave events for {admitted} joins"
    );
    server.shutdown().await.unwrap();
}
