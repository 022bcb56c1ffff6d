//! A shutdown that ends within [`SHUTDOWN_BOUND`] whatever the clients do.
//!
//! In order:
//! 1. the server stops accepting connections;
//! 2. every session closes ([`Registry::close_all`]): open streams get
//!    `UNAVAILABLE` and the reason, mechanics threads stop and recordings are
//!    finished (summary and footer written), waiting at most
//!    [`MECHANICS_JOIN_TIMEOUT`] for all of them together;
//! 3. connections get [`SHUTDOWN_GRACE`] to deliver those endings and go (HTTP/2
//!    GOAWAY; tonic waits for every connection);
//! 4. then every connection still open is severed ([`Severance`]): a silent TCP
//!    connection, one that sent only the HTTP/2 preface, an `Observe` stream its
//!    client does not read (socket buffers full, so that its last frame never
//!    leaves);
//! 5. the runtime gets [`RUNTIME_GRACE`] for what is left (a replay's read burst).
//!
//! Recordings are finished in step 2, before any client can delay anything, so a
//! recording a shutdown closes reads back whole.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use super::Registry;
use super::connections::Severance;
use crate::session::MECHANICS_JOIN_TIMEOUT;

/// Time connections get to deliver the endings of their streams and close, once
/// every session is closed: a round trip and a few frames on any working network.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(1);

/// Time the async runtime gets, after the server has returned, for tasks still
/// running (`laparo-server` drops it with this timeout).
pub const RUNTIME_GRACE: Duration = Duration::from_millis(500);

/// Longest time from the shutdown signal to the end of the process: the sum of
/// the waits above (5 s + 1 s + 0.5 s) and a second for the rest (joining the accept
/// loop, logging, a loaded machine). A shutdown whose sessions all stop at once
/// (every tick of a default scene) takes about [`SHUTDOWN_GRACE`].
pub const SHUTDOWN_BOUND: Duration = Duration::from_millis(
    MECHANICS_JOIN_TIMEOUT.as_millis() as u64
        + SHUTDOWN_GRACE.as_millis() as u64
        + RUNTIME_GRACE.as_millis() as u64
        + 1000,
);

/// Resolves once `signal` has, every session is closed (step 2), and the timer of
/// step 4 is running; what tonic's `serve_with_incoming_shutdown` awaits before its
/// graceful shutdown of the connections.
pub async fn on_signal(
    signal: impl Future<Output = ()>,
    registry: Arc<Registry>,
    severance: Severance,
) {
    signal.await;
    tracing::info!("shutting down: closing every session");
    tokio::task::block_in_place(|| registry.close_all("server shutting down"));
    tokio::spawn(async move {
        tokio::time::sleep(SHUTDOWN_GRACE).await;
        tracing::info!("shutting down: closing the connections still open");
        severance.cut();
    });
}
