//! The server's connections: accepted by its own loop, counted, closed when idle,
//! and severed when a shutdown runs out of time.
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
//! - **Severed.** When the server's [`Severance`] is cut (a shutdown past its grace),
//!   every connection's reads and writes fail at once, whatever the peer does: an
//!   `Observe` stream whose client stopped reading, with the socket's buffers full,
//!   ends too.
//!
//! HTTP/2 keepalive (a PING every [`ConnectionLimits::keepalive_interval`], the
//! connection closed when its answer does not come within
//! [`ConnectionLimits::keepalive_timeout`]) is hyper's and set on tonic's builder;
//! it finds a peer that vanished while a stream is open.

use std::collections::HashMap;
use std::future::Future;
use std::io;
use std::net::{IpAddr, Ipv6Addr};
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio::time::{Instant, Sleep};
use tokio_stream::wrappers::ReceiverStream;
use tokio_util::sync::{CancellationToken, WaitForCancellationFutureOwned};
use tonic::transport::server::{Connected, TcpConnectInfo};

/// First sleep of the accept loop when the process is out of file descriptors.
pub const FD_BACKOFF_MIN: Duration = Duration::from_millis(50);
/// Longest sleep of the accept loop when the process is out of file descriptors:
/// at most one failed `accept` a second, and a server that waits at most this long
/// to serve again once descriptors free up.
pub const FD_BACKOFF_MAX: Duration = Duration::from_secs(1);

/// How long a peer refused past its limit is logged once for, and how often the
/// refusals of an interval are summed up in one line.
pub const REFUSAL_LOG_INTERVAL: Duration = Duration::from_secs(10);
/// Most peers logged by address in one [`REFUSAL_LOG_INTERVAL`]; the others are
/// only counted in the interval's summary, so that many peers cannot grow the log
/// (nor the memory of who was logged) without bound.
pub const REFUSAL_LOG_PEERS: usize = 16;

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
    /// HTTP/2 PING interval on a connection.
    pub keepalive_interval: Duration,
    /// A connection whose PING is not answered within this is closed.
    pub keepalive_timeout: Duration,
}

/// Default of [`ConnectionLimits::idle`], s: a client between calls of a session it
/// is setting up keeps its connection; a socket that says nothing goes within a
/// minute.
pub const DEFAULT_IDLE_CONNECTION: Duration = Duration::from_secs(60);
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

/// The open streams of one connection.
#[derive(Debug, Default)]
struct Streams {
    open: AtomicUsize,
    /// Streams ever begun: an idle period restarts when this changes.
    begun: AtomicU64,
    /// The connection's task, woken when its last stream ends.
    waker: Mutex<Option<Waker>>,
}

/// What a request knows of its connection (tonic's connect info): its addresses and
/// its stream count.
#[derive(Clone, Debug)]
pub struct ConnInfo {
    pub tcp: TcpConnectInfo,
    streams: Arc<Streams>,
}

/// Holds one stream of a connection open until dropped.
pub struct StreamGuard(Arc<Streams>);

impl StreamGuard {
    fn new(streams: Arc<Streams>) -> Self {
        streams.begun.fetch_add(1, Ordering::AcqRel);
        streams.open.fetch_add(1, Ordering::AcqRel);
        StreamGuard(streams)
    }
}

impl Drop for StreamGuard {
    fn drop(&mut self) {
        if self.0.open.fetch_sub(1, Ordering::AcqRel) == 1 {
            let waker = self
                .0
                .waker
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take();
            if let Some(w) = waker {
                w.wake();
            }
        }
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

/// The address a peer is counted under, `None` for loopback (not counted per
/// peer): an IPv4-mapped IPv6 address as IPv4, an IPv6 one as its /64.
fn peer_key(ip: IpAddr) -> Option<IpAddr> {
    let ip = ip.to_canonical();
    if ip.is_loopback() {
        return None;
    }
    Some(match ip {
        IpAddr::V4(_) => ip,
        IpAddr::V6(v6) => IpAddr::V6(Ipv6Addr::from(u128::from(v6) & !(u64::MAX as u128))),
    })
}

/// Counts the open connections of each peer address (only those with one open:
/// at most the server's connection limit of entries).
#[derive(Debug, Default)]
pub struct PeerCounts(Mutex<HashMap<IpAddr, usize>>);

impl PeerCounts {
    /// Connections open now from the peer counted as `key`.
    pub fn get(&self, key: IpAddr) -> usize {
        let counts = self.0.lock().unwrap_or_else(|e| e.into_inner());
        counts.get(&key).copied().unwrap_or(0)
    }

    /// A slot for peer `key` if it has fewer than `max` open.
    fn take(self: &Arc<Self>, key: IpAddr, max: usize) -> Option<PeerSlot> {
        let mut counts = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let n = counts.entry(key).or_insert(0);
        if *n >= max {
            if *n == 0 {
                counts.remove(&key);
            }
            return None;
        }
        *n += 1;
        Some(PeerSlot {
            counts: self.clone(),
            key,
        })
    }
}

/// One connection of a peer, released when dropped.
#[derive(Debug)]
struct PeerSlot {
    counts: Arc<PeerCounts>,
    key: IpAddr,
}

impl Drop for PeerSlot {
    fn drop(&mut self) {
        let mut counts = self.counts.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(n) = counts.get_mut(&self.key) {
            *n -= 1;
            if *n == 0 {
                counts.remove(&self.key);
            }
        }
    }
}

/// The refusals of peers past their limit in the current
/// [`REFUSAL_LOG_INTERVAL`]: the first of each peer is logged (up to
/// [`REFUSAL_LOG_PEERS`] peers), and at the interval's end one line sums them up.
#[derive(Debug)]
struct PeerRefusals {
    since: Instant,
    /// Peers logged this interval, and how many of their connections were refused.
    logged: HashMap<IpAddr, u64>,
    /// Connections refused this interval from peers past [`REFUSAL_LOG_PEERS`].
    unlogged: u64,
}

/// What [`PeerRefusals`] says of an interval that ended.
#[derive(Debug, PartialEq, Eq)]
struct RefusalSummary {
    connections: u64,
    /// Peers logged by address; more may have been refused unnamed.
    named_peers: usize,
    /// Connections refused from peers not named.
    unnamed: u64,
}

impl PeerRefusals {
    fn new(now: Instant) -> Self {
        PeerRefusals {
            since: now,
            logged: HashMap::new(),
            unlogged: 0,
        }
    }

    /// When the current interval ends, if it holds refusals to sum up.
    fn due(&self) -> Option<Instant> {
        (!self.logged.is_empty()).then_some(self.since + REFUSAL_LOG_INTERVAL)
    }

    /// Ends the interval if it is over: its summary, if it refused anything.
    fn roll(&mut self, now: Instant) -> Option<RefusalSummary> {
        if now < self.since + REFUSAL_LOG_INTERVAL {
            return None;
        }
        let summary = (!self.logged.is_empty()).then(|| RefusalSummary {
            connections: self.logged.values().sum::<u64>() + self.unlogged,
            named_peers: self.logged.len(),
            unnamed: self.unlogged,
        });
        *self = PeerRefusals::new(now);
        summary
    }

    /// Counts a refusal of `peer`: `true` if it is to be logged (its first this
    /// interval, and room for its address).
    fn refuse(&mut self, peer: IpAddr) -> bool {
        if let Some(n) = self.logged.get_mut(&peer) {
            *n += 1;
            return false;
        }
        if self.logged.len() >= REFUSAL_LOG_PEERS {
            self.unlogged += 1;
            return false;
        }
        self.logged.insert(peer, 1);
        true
    }
}

/// Logs the summary of an interval of refusals.
fn log_summary(summary: RefusalSummary, per_peer: usize) {
    tracing::warn!(
        "refused {} connections in the last {} s from peers at their limit of {per_peer} \
         (--max-connections-per-peer): {} peers named above{}",
        summary.connections,
        REFUSAL_LOG_INTERVAL.as_secs(),
        summary.named_peers,
        if summary.unnamed > 0 {
            format!(", {} connections from others", summary.unnamed)
        } else {
            String::new()
        }
    );
}

/// One counted connection, released when dropped.
#[derive(Debug)]
struct Slot(Arc<OpenCount>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// An accepted TCP connection (see the module documentation).
pub struct Conn {
    io: TcpStream,
    info: ConnInfo,
    idle_for: Duration,
    idle: Pin<Box<Sleep>>,
    /// The value of `begun` the idle timer was armed at; `None`: a stream is open.
    armed_at: Option<u64>,
    severed: Pin<Box<WaitForCancellationFutureOwned>>,
    _slot: Slot,
    /// Its peer's count; `None` for loopback.
    _peer: Option<PeerSlot>,
}

impl Conn {
    /// The error that ends the connection now, if any; registers the task to be
    /// woken when that may change.
    fn check(&mut self, cx: &mut Context<'_>) -> Option<io::Error> {
        if self.severed.as_mut().poll(cx).is_ready() {
            return Some(io::Error::new(
                io::ErrorKind::ConnectionAborted,
                "the server shut down",
            ));
        }
        let streams = &self.info.streams;
        if streams.open.load(Ordering::Acquire) > 0 {
            *streams.waker.lock().unwrap_or_else(|e| e.into_inner()) = Some(cx.waker().clone());
            // The last stream may have ended between the load and the store.
            if streams.open.load(Ordering::Acquire) > 0 {
                self.armed_at = None;
                return None;
            }
        }
        let begun = streams.begun.load(Ordering::Acquire);
        if self.armed_at != Some(begun) {
            self.armed_at = Some(begun);
            self.idle.as_mut().reset(Instant::now() + self.idle_for);
        }
        if self.idle.as_mut().poll(cx).is_ready() {
            return Some(io::Error::new(
                io::ErrorKind::TimedOut,
                format!("no stream for {} s", self.idle_for.as_secs_f64()),
            ));
        }
        None
    }

    fn severed(&mut self, cx: &mut Context<'_>) -> Option<io::Error> {
        self.severed
            .as_mut()
            .poll(cx)
            .is_ready()
            .then(|| io::Error::new(io::ErrorKind::ConnectionAborted, "the server shut down"))
    }
}

impl Connected for Conn {
    type ConnectInfo = ConnInfo;

    fn connect_info(&self) -> ConnInfo {
        self.info.clone()
    }
}

impl AsyncRead for Conn {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if let Some(e) = this.check(cx) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.io).poll_read(cx, buf)
    }
}

impl AsyncWrite for Conn {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.io).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.io).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.io).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.io).poll_shutdown(cx)
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

/// The layer of [`CountStreams`].
#[derive(Clone, Copy, Debug, Default)]
pub struct CountStreamsLayer;

impl<S> tower_layer::Layer<S> for CountStreamsLayer {
    type Service = CountStreams<S>;

    fn layer(&self, inner: S) -> CountStreams<S> {
        CountStreams(inner)
    }
}

/// Holds a count of its connection's open streams for each request until the
/// response body is dropped, and gives the request tonic's [`TcpConnectInfo`] (so
/// that `Request::remote_addr` answers).
#[derive(Clone, Debug)]
pub struct CountStreams<S>(S);

type BoxFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;

impl<S, ReqBody, ResBody> tower_service::Service<http::Request<ReqBody>> for CountStreams<S>
where
    S: tower_service::Service<http::Request<ReqBody>, Response = http::Response<ResBody>>,
    S::Future: Send + 'static,
{
    type Response = http::Response<Counted<ResBody>>;
    type Error = S::Error;
    type Future = BoxFuture<Result<Self::Response, S::Error>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.0.poll_ready(cx)
    }

    fn call(&mut self, mut request: http::Request<ReqBody>) -> Self::Future {
        let info = request.extensions().get::<ConnInfo>().cloned();
        let guard = info.map(|info| {
            request.extensions_mut().insert(info.tcp.clone());
            StreamGuard::new(info.streams)
        });
        let response = self.0.call(request);
        Box::pin(async move {
            let response = response.await?;
            Ok(response.map(|body| Counted {
                body: Box::pin(body),
                _guard: guard,
            }))
        })
    }
}

/// A response body that keeps its stream counted until dropped.
pub struct Counted<B> {
    body: Pin<Box<B>>,
    _guard: Option<StreamGuard>,
}

impl<B: http_body::Body> http_body::Body for Counted<B> {
    type Data = B::Data;
    type Error = B::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<B::Data>, B::Error>>> {
        self.body.as_mut().poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.body.size_hint()
    }
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
    fn a_peer_is_counted_by_address_loopback_not_at_all() {
        let ip = |s: &str| s.parse::<IpAddr>().unwrap();
        assert_eq!(peer_key(ip("127.0.0.1")), None);
        assert_eq!(peer_key(ip("127.3.2.1")), None);
        assert_eq!(peer_key(ip("::1")), None);
        // Loopback through a dual-stack listener.
        assert_eq!(peer_key(ip("::ffff:127.0.0.1")), None);
        assert_eq!(peer_key(ip("192.0.2.7")), Some(ip("192.0.2.7")));
        assert_eq!(peer_key(ip("::ffff:192.0.2.7")), Some(ip("192.0.2.7")));
        // Any address of one /64 is the same peer; another /64 is another.
        assert_eq!(
            peer_key(ip("2001:db8:1:2:aaaa::1")),
            Some(ip("2001:db8:1:2::"))
        );
        assert_eq!(
            peer_key(ip("2001:db8:1:2:ffff:ffff:ffff:ffff")),
            Some(ip("2001:db8:1:2::"))
        );
        assert_eq!(peer_key(ip("2001:db8:1:3::1")), Some(ip("2001:db8:1:3::")));
    }

    #[test]
    fn a_peers_count_never_passes_its_limit_and_others_are_counted_apart() {
        let counts = Arc::new(PeerCounts::default());
        let (a, b) = ("192.0.2.1".parse().unwrap(), "192.0.2.2".parse().unwrap());
        let first = counts.take(a, 2).unwrap();
        let _second = counts.take(a, 2).unwrap();
        assert!(counts.take(a, 2).is_none());
        assert_eq!(counts.get(a), 2);
        let other = counts.take(b, 2).unwrap();
        drop(first);
        assert_eq!(counts.get(a), 1);
        assert!(counts.take(a, 2).is_some());
        // A peer with nothing open leaves no entry behind.
        drop(other);
        assert!(!counts.0.lock().unwrap().contains_key(&b));
    }

    #[test]
    fn refusals_are_logged_once_per_peer_and_interval_and_summed_up() {
        let start = Instant::now();
        let mut refusals = PeerRefusals::new(start);
        assert_eq!(refusals.due(), None, "nothing to sum up");
        let peer = |i: u32| IpAddr::from(std::net::Ipv4Addr::from(0xc000_0200 + i));
        assert!(refusals.refuse(peer(0)));
        for _ in 0..1000 {
            assert!(!refusals.refuse(peer(0)), "said once");
        }
        for i in 1..100 {
            assert_eq!(refusals.refuse(peer(i)), i < REFUSAL_LOG_PEERS as u32);
        }
        assert_eq!(refusals.logged.len(), REFUSAL_LOG_PEERS);
        assert_eq!(refusals.due(), Some(start + REFUSAL_LOG_INTERVAL));
        assert_eq!(refusals.roll(start + REFUSAL_LOG_INTERVAL / 2), None);
        assert_eq!(
            refusals.roll(start + REFUSAL_LOG_INTERVAL),
            Some(RefusalSummary {
                connections: 1000 + 100,
                named_peers: REFUSAL_LOG_PEERS,
                unnamed: 100 - REFUSAL_LOG_PEERS as u64,
            })
        );
        // A new interval: the peer is said again, once.
        assert!(refusals.refuse(peer(0)));
        assert!(!refusals.refuse(peer(0)));
    }

    #[test]
    fn a_stream_counts_until_its_guard_drops_and_wakes_the_connection() {
        let streams = Arc::new(Streams::default());
        let g = StreamGuard::new(streams.clone());
        assert_eq!(streams.open.load(Ordering::Acquire), 1);
        assert_eq!(streams.begun.load(Ordering::Acquire), 1);
        drop(g);
        assert_eq!(streams.open.load(Ordering::Acquire), 0);
        assert_eq!(streams.begun.load(Ordering::Acquire), 1);
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
