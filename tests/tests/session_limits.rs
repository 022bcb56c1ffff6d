//! How many stations and observers one session takes, and how many streams one
//! connection may open, against a real server: past each limit the request is
//! refused naming it (or, for streams, waits for the connection to free one), and
//! a place given back is taken again.

use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_server::service::limits::{
    MAX_OBSERVERS_PER_SESSION, MAX_STATIONS_PER_SESSION, MAX_STREAMS_PER_CONNECTION,
};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

async fn observe(
    ch: &Channel,
    session: &str,
) -> Result<tonic::Streaming<v1::ObserveMessage>, tonic::Status> {
    v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.into(),
            frame_rate_hz: None,
        })
        .await
        .map(|r| r.into_inner())
}

/// The session's observers, then its stations, are bounded: one more is refused
/// `RESOURCE_EXHAUSTED` naming the limit, and taken once one has gone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_takes_a_bounded_number_of_observers_and_stations() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    // Observers on connections of their own, as many to a connection as it takes.
    let mut observers = Vec::new();
    let mut own = server.channel().await;
    for k in 0..MAX_OBSERVERS_PER_SESSION {
        if k > 0 && k % MAX_STREAMS_PER_CONNECTION == 0 {
            own = server.channel().await;
        }
        observers.push(observe(&own, &session).await.unwrap());
    }
    let refused = observe(&ch, &session).await.unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(
        refused.message().contains("MAX_OBSERVERS_PER_SESSION"),
        "{refused:?}"
    );
    observers.pop();
    let again = once_not(Code::ResourceExhausted, || observe(&ch, &session))
        .await
        .expect("the observer's place never came back");
    drop((observers, again));

    // Watching stations, each on a connection of its own as stations are.
    let mut stations = Vec::new();
    for _ in 0..MAX_STATIONS_PER_SESSION {
        let own = server.channel().await;
        stations.push(join(own, None, &session, &[]).await.unwrap());
    }
    let refused = join(server.channel().await, None, &session, &["left"])
        .await
        .map(|_| ())
        .unwrap_err();
    assert_eq!(refused.code(), Code::ResourceExhausted, "{refused:?}");
    assert!(
        refused.message().contains("MAX_STATIONS_PER_SESSION"),
        "{refused:?}"
    );
    // The refused station claimed nothing: `left` is free for the next one.
    stations.pop();
    let own = server.channel().await;
    let _held = once_not(Code::ResourceExhausted, || {
        join(own.clone(), None, &session, &["left"])
    })
    .await
    .expect("the station's place never came back");
    server.shutdown().await.unwrap();
}

/// One connection has at most `MAX_STREAMS_PER_CONNECTION` streams open: the next
/// waits (HTTP/2 queues it on the client) until one ends, instead of the server
/// taking any number (a probe held 6,000 on three connections).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_connection_opens_a_bounded_number_of_streams() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let per_session = MAX_OBSERVERS_PER_SESSION as usize;
    let sessions_needed = (MAX_STREAMS_PER_CONNECTION as usize).div_ceil(per_session) + 1;
    let mut sessions = Vec::new();
    for _ in 0..sessions_needed {
        sessions.push(create_session(ch.clone(), None).await.unwrap().session_id);
    }
    let mut open = Vec::new();
    for k in 0..MAX_STREAMS_PER_CONNECTION as usize {
        open.push(observe(&ch, &sessions[k / per_session]).await.unwrap());
    }
    let last = sessions.last().unwrap().clone();
    let (ch2, last2) = (ch.clone(), last.clone());
    let mut waiting = tokio::spawn(async move { observe(&ch2, &last2).await.map(|_| ()) });
    let early = tokio::time::timeout(Duration::from_millis(500), &mut waiting).await;
    assert!(early.is_err(), "a stream past the limit opened: {early:?}");
    open.pop();
    let opened = tokio::time::timeout(Duration::from_secs(20), waiting).await;
    assert!(matches!(opened, Ok(Ok(Ok(())))), "{opened:?}");
    server.shutdown().await.unwrap();
}
