//! A real `laparo-server` process, for the tests of signals and shutdown.

use std::net::TcpListener;
use std::process::Child;
use std::time::{Duration, Instant};

/// Kills the server if the test fails before it ends.
pub struct Server(pub Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A loopback port free at the time of asking.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A channel to `url` once the server listens; fails the test past `deadline`.
pub async fn connect(url: &str, deadline: Instant) -> tonic::transport::Channel {
    loop {
        match tonic::transport::Endpoint::from_shared(url.to_string())
            .unwrap()
            .connect()
            .await
        {
            Ok(ch) => return ch,
            Err(e) if Instant::now() > deadline => panic!("server never listened: {e}"),
            Err(_) => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
}
