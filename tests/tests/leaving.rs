//! A station leaving, as the contract states it: the instruments it held are
//! released and withdrawn from the body, so that the tissue is let go.

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::ServeConfig;
use laparo_tests::pressing::*;
use laparo_tests::server::*;

/// |F| of a state, N; 0 when absent.
fn force_n(s: &v1::InstrumentState) -> f64 {
    s.force
        .as_ref()
        .and_then(|f| f.force.as_ref())
        .map_or(0.0, |v| (v.x * v.x + v.y * v.y + v.z * v.z).sqrt())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_released_instrument_is_withdrawn_from_the_body() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let (mut watcher, _) = join(ch.clone(), None, &session, &[]).await.unwrap();
    press(&a, "left", front(&joined), 0.0);
    let pressing = wait_for(&mut a.rx, WAIT, |m| {
        state_of(m, "left").is_some_and(|s| s.held_vertex_count > 0 && force_n(s) > 0.1)
    })
    .await;
    assert!(pressing.is_some(), "the station never pressed the liver");
    a.tx.send(v1::StationMessage {
        kind: Some(v1::station_message::Kind::Leave(v1::Leave {
            reason: "done".into(),
        })),
    })
    .await
    .unwrap();
    let left = wait_for(&mut watcher.rx, WAIT, |m| {
        matches!(&m.kind, Some(Kind::Event(e))
            if e.kind == v1::EventKind::StationLeft as i32 && e.station_id == Some(joined.station_id))
    })
    .await;
    let Some(Kind::Event(event)) = left.and_then(|m| m.kind) else {
        panic!("no StationLeft event");
    };
    // The withdrawal is in the pose slot before the event is published: the tick
    // in progress may still use the old pose, the one after it cannot.
    let after = event.tick + 2;
    let state = wait_for(&mut watcher.rx, WAIT, |m| {
        state_of(m, "left").is_some_and(|s| s.tick >= after)
    })
    .await;
    let Some(Kind::InstrumentState(s)) = state.and_then(|m| m.kind) else {
        panic!("no state of the left instrument after tick {after}");
    };
    assert_eq!(s.station_id, None, "{s:?}");
    assert_eq!(s.held_vertex_count, 0, "{s:?}");
    assert_eq!(force_n(&s), 0.0, "{s:?}");
    assert!(s.pose.is_none() && s.pose_sequence.is_none(), "{s:?}");
    assert_eq!(s.contact, v1::ContactState::None as i32, "{s:?}");
    drop((a, watcher));
    server.shutdown().await.unwrap();
}
