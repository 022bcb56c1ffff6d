//! The server's connections: accepted by its own loop, counted, closed when idle
//! or when their peer stops reading, and severed when a shutdown runs out of time.
//!
//! - **Counted at accept.** Past [`ConnectionLimits::max`] open connections a new one
//!   is accepted and closed at once (the peer sees the connection reset or closed),
//!   so that it cannot hold a file descriptor; each refusal answers one connection
//!   attempt, so refusing cannot spin.
//! - **Counted per peer.** Past [`ConnectionLimits::per_peer`] open connections from
//!   one address, a new one from it is closed the same way, so that one peer
//!   (connections that trickle headers, or say nothing until they are idle) cannot
//!   take every slot and refuse everyone else. An IPv6 peer is counted by its /64
//!   (a host holds a whole /64 and may pick any address of it), an IPv4-mapped one
//!   as IPv4. Loopback peers are not counted per address: a proxy on the same host
//!   brings every client from loopback, and any local process may pick any address
//!   of 127.0.0.0/8, so a per-address count there would refuse honest clients and
//!   not bind anyone; the global limit still applies. Each refused peer is logged
//!   once per [`REFUSAL_LOG_INTERVAL`], at most [`REFUSAL_LOG_PEERS`] peers an
//!   interval, then one line sums the interval up ([`PeerRefusals`]).
//! - **Out of file descriptors.** `accept` failing with `EMFILE`/`ENFILE` leaves the
//!   pending connection in the kernel's backlog, so an immediate retry fails the
//!   same way: the loop sleeps [`FD_BACKOFF_MIN`], doubling to [`FD_BACKOFF_MAX`],
//!   and accepts again (serving again as soon as descriptors free up) instead of
//!   spinning a core.
//! - **Idle.** A connection with no open stream (no request in progress: no unary
//!   call, no `Join`, `Observe` or `Replay` stream) for [`ConnectionLimits::idle`]
//!   is closed: a silent TCP connection, one that sent only the HTTP/2 preface, and
//!   a channel a client keeps between calls (tonic's client reconnects on the next
//!   call). Streams are counted by [`CountStreams`], a layer that holds a count for
//!   each request until its response body is dropped.
//! - **A peer that reads nothing.** A write that waits for the peer (its socket's
//!   send buffer full) while the peer takes (acknowledges) no byte for
//!   [`ConnectionLimits::write_stall`] fails, and the connection closes with a
//!   reset, dropping what it had not sent (closed the ordinary way, its socket
//!   would stay in the kernel with those bytes while it tried to deliver them).
//!   The idle timer cannot see this: a response already handed over (pipelined
//!   HTTP/1.1 `GET`s of the console's bundle, or one large answer) holds no
//!   stream, and hyper's HTTP/1.1 connection reads nothing while its write waits;
//!   HTTP/2 keepalive does not run over HTTP/1.1. Without the limit such a
//!   connection, and the megabytes of kernel buffers it fills, stays until the
//!   peer reads or goes. The kernel holds the same limit for what the server
//!   has written (`TCP_USER_TIMEOUT`, [`conn::hand_over_within`]): an answer that
//!   fits in the send buffer needs no waiting write, and once the server has
//!   closed such a connection (a `connection: close` request) its orphaned
//!   socket, with the answer, goes when the peer has taken none of it for the
//!   limit, not after the minutes of the kernel's own zero-window probing.
//! - **Severed.** When the server's [`Severance`] is cut (a shutdown past its grace),
//!   every connection's reads and writes fail at once, whatever the peer does: an
//!   `Observe` stream whose client stopped reading, with the socket's buffers full,
//!   ends too.
//! - **Requests that never end.** A call's request must arrive whole within
//!   [`REQUEST_DEADLINE`] of its start (`Join`'s, a stream, excepted): a body sent a
//!   byte at a time no longer holds its stream, and so its connection, open.
//!
//! HTTP/2 keepalive (a PING every [`ConnectionLimits::keepalive_interval`], the
//! connection closed when its answer does not come within
//! [`ConnectionLimits::keepalive_timeout`]) is hyper's and set on tonic's builder;
//! it finds a peer that vanished while a stream is open.
//!
//! Files: this one, the limits and the accept loop ([`incoming`]); `peers`, the
//! count per peer and the refusals' log; `conn`, an accepted connection's idle
//! and write-stall timers and severance; `streams`, the layer that counts a
//! connection's streams; `deadline`, the layer that bounds a request's arrival.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::mpsc;
use tokio::time::Instant;
use tokio_stream::wrappers::ReceiverStream;
use tokio_util::sync::CancellationToken;
use tonic::transport::server::TcpConnectInfo;

mod conn;
mod deadline;
mod peers;
mod streams;

pub use conn::Conn;
pub use deadline::{REQUEST_DEADLINE, RequestDeadline, RequestDeadlineLayer};
pub use peers::{PeerCounts, REFUSAL_LOG_INTERVAL, REFUSAL_LOG_PEERS};
use peers::{PeerRefusals, log_summary, peer_key};
pub use streams::{ConnInfo, CountStreams, CountStreamsLayer, Counted, StreamGuard};

/// First sleep of the accept loop when the process is out of file descriptors.
pub const FD_BACKOFF_MIN: Duration = Duration::from_millis(50);
/// Longest sleep of the accept loop when the process is out of file descriptors:
/// at most one failed `accept` a second, and a server that waits at most this long
/// to serve again once descriptors free up.
pub const FD_BACKOFF_MAX: Duration = Duration::from_secs(1);

/// Limits on the server's connections.
#[derive(Clone, Copy, Debug)]
pub struct ConnectionLimits {
    /// Most connections open at once (`--max-connections`).
    pub max: usize,
    /// Most connections open at once from one peer address, loopback excepted
    /// (`--max-connections-per-peer`).
    pub per_peer: usize,
    /// A connection with no open stream this long is closed (`--idle-connection`).
    pub idle: Duration,
    /// A connection whose peer takes none of the bytes waiting for it this long is
    /// closed (`--write-stall`).
    pub write_stall: Duration,
    /// HTTP/2 PING interval on a connection.
    pub keepalive_interval: Duration,
    /// A connection whose PING is not answered within this is closed.
    pub keepalive_timeout: Duration,
}

/// Default of [`ConnectionLimits::idle`], s: a client between calls of a session it
/// is setting up keeps its connection; a socket that says nothing goes within a
/// minute.
pub const DEFAULT_IDLE_CONNECTION: Duration = Duration::from_secs(60);
/// Default of [`ConnectionLimits::write_stall`], s. A write waits only while the
/// socket's send buffer is full, and the connection is cut only when, all that
/// time, the peer has taken (acknowledged) none of its bytes: a working link, even
/// a slow or lossy one, takes some within seconds, so a peer that takes
/// nothing for 30 s while the server has data for it is not reading. Long enough
/// too for a laptop's network to come back after a roam.
pub const DEFAULT_WRITE_STALL: Duration = Duration::from_secs(30);
/// Default of [`ConnectionLimits::keepalive_interval`].
pub const DEFAULT_KEEPALIVE_INTERVAL: Duration = Duration::from_secs(20);
/// Default of [`ConnectionLimits::keepalive_timeout`]: a round trip of any working
/// network, with room for a loaded server.
pub const DEFAULT_KEEPALIVE_TIMEOUT: Duration = Duration::from_secs(10);

/// Cuts every connection of a server at once (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct Severance(CancellationToken);

impl Severance {
    /// Fails every connection's reads and writes from now on.
    pub fn cut(&self) {
        self.0.cancel();
    }
}

/// Counts the open connections of a server.
#[derive(Debug, Default)]
pub struct OpenCount(AtomicUsize);

impl OpenCount {
    /// Connections open now.
    pub fn get(&self) -> usize {
        self.0.load(Ordering::Acquire)
    }

    /// A slot if fewer than `max` are open.
    fn take(self: &Arc<Self>, max: usize) -> Option<Slot> {
        self.0
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n < max).then_some(n + 1)
            })
            .ok()
            .map(|_| Slot(self.clone()))
    }
}

/// One counted connection, released when dropped.
#[derive(Debug)]
struct Slot(Arc<OpenCount>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Whether an `accept` error means the process or system is out of file
/// descriptors (or the kernel out of socket memory): retrying at once fails again.
fn out_of_descriptors(e: &io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(libc::EMFILE | libc::ENFILE | libc::ENOBUFS | libc::ENOMEM)
    )
}

/// The connections `listener` accepts, counted and limited by `limits` (in all, in
/// `open`, and per peer), each severed when `severance` is cut (see the module
/// documentation). The loop runs on its own task until the stream is dropped.
pub fn incoming(
    listener: TcpListener,
    limits: ConnectionLimits,
    open: Arc<OpenCount>,
    severance: Severance,
) -> ReceiverStream<io::Result<Conn>> {
    let (tx, rx) = mpsc::channel(1);
    let local = listener.local_addr().ok();
    let peers = Arc::new(PeerCounts::default());
    let mut refusals = PeerRefusals::new(Instant::now());
    tokio::spawn(async move {
        let mut backoff = FD_BACKOFF_MIN;
        // When a refusal or a backoff was last logged: at most one line a second.
        let mut last_log: Option<Instant> = None;
        let mut quiet = move || {
            let now = Instant::now();
            let due = last_log.is_none_or(|t| now >= t + Duration::from_secs(1));
            if due {
                last_log = Some(now);
            }
            due
        };
        loop {
            let summary_due = refusals.due();
            let accepted = tokio::select! {
                _ = tx.closed() => return,
                // An interval of refusals ends even if nobody connects after it.
                _ = tokio::time::sleep_until(summary_due.unwrap_or_else(Instant::now)),
                    if summary_due.is_some() =>
                {
                    if let Some(summary) = refusals.roll(Instant::now()) {
                        log_summary(summary, limits.per_peer);
                    }
                    continue;
                }
                accepted = listener.accept() => accepted,
            };
            let (tcp, peer) = match accepted {
                Ok(a) => a,
                Err(e) if out_of_descriptors(&e) => {
                    if quiet() {
                        tracing::warn!(
                            "cannot accept a connection ({e}): out of file descriptors; \
                             waiting {} ms (raise the process's fd limit or lower \
                             --max-connections)",
                            backoff.as_millis()
                        );
                    }
                    tokio::time::sleep(backoff).await;
                    backoff = (backoff * 2).min(FD_BACKOFF_MAX);
                    continue;
                }
                // A connection reset before it was accepted, and the like: about
                // that connection only.
                Err(_) => continue,
            };
            backoff = FD_BACKOFF_MIN;
            if let Some(summary) = refusals.roll(Instant::now()) {
                log_summary(summary, limits.per_peer);
            }
            // Counted per peer first: a peer at its limit takes no global slot.
            let peer_slot = match peer_key(peer.ip()) {
                None => None,
                Some(key) => match peers.take(key, limits.per_peer) {
                    Some(slot) => Some(slot),
                    None => {
                        if refusals.refuse(key) {
                            tracing::warn!(
                                %peer,
                                "refusing connections from {key}: {} open, its limit \
                                 (--max-connections-per-peer); said once in {} s",
                                limits.per_peer,
                                REFUSAL_LOG_INTERVAL.as_secs()
                            );
                        }
                        drop(tcp);
                        continue;
                    }
                },
            };
            let Some(slot) = open.take(limits.max) else {
                if quiet() {
                    tracing::warn!(
                        %peer,
                        "refusing a connection: {} open, the limit (--max-connections)",
                        limits.max
                    );
                }
                drop(tcp);
                continue;
            };
            let _ = tcp.set_nodelay(true);
            conn::hand_over_within(&tcp, limits.write_stall);
            let conn = Conn {
                io: tcp,
                info: ConnInfo {
                    tcp: TcpConnectInfo {
                        local_addr: local,
                        remote_addr: Some(peer),
                    },
                    streams: Default::default(),
                },
                idle_for: limits.idle,
                idle: Box::pin(tokio::time::sleep(limits.idle)),
                armed_at: None,
                stall_for: limits.write_stall,
                stall: Box::pin(tokio::time::sleep(limits.write_stall)),
                stalled: None,
                severed: Box::pin(severance.0.clone().cancelled_owned()),
                _slot: slot,
                _peer: peer_slot,
            };
            if tx.send(Ok(conn)).await.is_err() {
                return;
            }
        }
    });
    ReceiverStream::new(rx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_count_never_passes_its_limit_and_frees_a_slot_when_one_drops() {
        let open = Arc::new(OpenCount::default());
        let a = open.take(2).unwrap();
        let _b = open.take(2).unwrap();
        assert!(open.take(2).is_none());
        assert_eq!(open.get(), 2);
        drop(a);
        assert_eq!(open.get(), 1);
        assert!(open.take(2).is_some());
    }

    #[test]
    fn only_descriptor_exhaustion_backs_off() {
        assert!(out_of_descriptors(&io::Error::from_raw_os_error(
            libc::EMFILE
        )));
        assert!(out_of_descriptors(&io::Error::from_raw_os_error(
            libc::ENFILE
        )));
        assert!(!out_of_descriptors(&io::Error::from_raw_os_error(
            libc::ECONNABORTED
        )));
    }
}
