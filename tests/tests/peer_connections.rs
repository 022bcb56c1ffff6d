//! One peer address cannot take every connection: past
//! `--max-connections-per-peer` its new connections are closed as they come, while
//! those it holds are served, and it is served again once one closes. Loopback is
//! not counted per address (a proxy on the same host brings every client from it).
//! A client refused at a full server is told the limit may be why.
//!
//! A peer that is not loopback needs an address of this machine that is not: the
//! server listens on the one the machine routes from, and the test connects to it
//! from the same machine (the kernel gives the connection that address as its
//! source).

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::time::Duration;

use laparo_client::connect::{ConnectConfig, connect};
use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_server::service::capacity::Capacity;
use laparo_tests::server::{TestServer, WAIT};
use tonic::transport::{Channel, Endpoint};

/// Connections the tests' servers allow one peer.
const PER_PEER: usize = 4;

fn limits() -> Capacity {
    Capacity {
        sessions: 4,
        connections: 64,
        connections_per_peer: PER_PEER,
        replays: 4,
    }
}

/// An address of this machine that is not loopback: the source of a route to a
/// documentation address (a UDP "connection" sends nothing). `None` on a machine
/// with no route off it.
fn routed_address() -> Option<IpAddr> {
    let socket = UdpSocket::bind("0.0.0.0:0").ok()?;
    socket.connect("198.51.100.1:9").ok()?;
    let ip = socket.local_addr().ok()?.ip();
    (!ip.is_loopback() && !ip.is_unspecified()).then_some(ip)
}

/// A channel with its connection made, and a call over it: `Err` if the server
/// closed the connection instead of serving it.
async fn served(addr: SocketAddr) -> Result<Channel, String> {
    let ch = Endpoint::from_shared(format!("http://{addr}"))
        .unwrap()
        .connect_timeout(WAIT)
        .timeout(WAIT)
        .connect()
        .await
        .map_err(|e| format!("connect: {e}"))?;
    list(ch.clone()).await?;
    Ok(ch)
}

async fn list(ch: Channel) -> Result<(), String> {
    v1::scenes_client::ScenesClient::new(ch)
        .list_scenes(v1::ListScenesRequest {})
        .await
        .map(|_| ())
        .map_err(|status| format!("{status:?}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_peer_past_its_limit_is_refused_and_served_again_once_one_closes() {
    let Some(ip) = routed_address() else {
        eprintln!("skipped: this machine has no address but loopback");
        return;
    };
    let server = TestServer::start_at(
        SocketAddr::new(ip, 0),
        ServeConfig {
            capacity: limits(),
            // Not loopback: allowed without TLS and tokens only when told.
            insecure: true,
            ..ServeConfig::default()
        },
    )
    .await;
    let mut held = Vec::new();
    for i in 0..PER_PEER {
        let ch = served(server.addr)
            .await
            .unwrap_or_else(|e| panic!("connection {i} of the peer's {PER_PEER}: {e}"));
        held.push(ch);
    }
    // The global limit (64) is far; the peer's is reached.
    let over = served(server.addr).await;
    assert!(
        over.is_err(),
        "a connection past the peer's limit was served"
    );
    // Those it holds still are.
    for ch in &held {
        list(ch.clone()).await.unwrap();
    }
    drop(held.pop());
    // The slot frees when the server sees the connection close.
    let deadline = tokio::time::Instant::now() + WAIT;
    loop {
        match served(server.addr).await {
            Ok(_) => break,
            Err(e) => assert!(
                tokio::time::Instant::now() < deadline,
                "never served again: {e}"
            ),
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loopback_is_not_counted_per_peer() {
    let server = TestServer::start(ServeConfig {
        capacity: limits(),
        ..ServeConfig::default()
    })
    .await;
    let mut held = Vec::new();
    for i in 0..3 * PER_PEER {
        let ch = served(server.addr)
            .await
            .unwrap_or_else(|e| panic!("loopback connection {i}: {e}"));
        held.push(ch);
    }
    for ch in &held {
        list(ch.clone()).await.unwrap();
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_refused_at_a_full_server_is_told_the_limit_may_be_why() {
    let server = TestServer::start(ServeConfig {
        capacity: Capacity {
            connections: 1,
            ..limits()
        },
        ..ServeConfig::default()
    })
    .await;
    let _only = served(server.addr).await.unwrap();
    let url = format!("http://{}", server.addr);
    let refused = connect(&ConnectConfig::new(url.clone()))
        .await
        .expect_err("the server is full");
    let said = refused.to_string();
    for words in [
        url.as_str(),
        "closed the connection",
        "connection limit",
        "--max-connections",
        "--max-connections-per-peer",
        "not a laparo server",
    ] {
        assert!(said.contains(words), "{said}");
    }
    server.shutdown().await.unwrap();
}
