//! An accepted connection: closed when it has had no open stream for the idle
//! limit, or when its peer has taken none of the server's bytes for the write-stall
//! limit; failed when the server's severance is cut (see [`connections`](super)).

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::Ordering;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::time::{Instant, Sleep};
use tokio_util::sync::WaitForCancellationFutureOwned;
use tonic::transport::server::Connected;

use super::Slot;
use super::peers::PeerSlot;
use super::streams::ConnInfo;

/// How many times within the write-stall limit a waiting write looks whether the
/// peer has taken bytes: a peer that stops reading is cut between the limit and
/// 1¼ of it after the last byte it took, and a stalled connection costs the
/// server four system calls a limit.
pub(super) const STALL_CHECKS: u32 = 4;

/// A write waiting for the peer ([`Conn::stalled`]).
#[derive(Debug)]
pub(super) struct Stall {
    /// The bytes the peer had not acknowledged at the last check, if the system
    /// tells ([`unacknowledged`]).
    unacknowledged: Option<usize>,
    /// When the peer was last seen taking bytes, or the write began to wait.
    since: Instant,
}

/// An accepted TCP connection (see the module documentation).
pub struct Conn {
    pub(super) io: TcpStream,
    pub(super) info: ConnInfo,
    pub(super) idle_for: Duration,
    pub(super) idle: Pin<Box<Sleep>>,
    /// The value of `begun` the idle timer was armed at; `None`: a stream is open.
    pub(super) armed_at: Option<u64>,
    pub(super) severed: Pin<Box<WaitForCancellationFutureOwned>>,
    /// The write-stall limit ([`ConnectionLimits::write_stall`](super::ConnectionLimits::write_stall)).
    pub(super) stall_for: Duration,
    /// While a write waits for the peer, fires at each of its
    /// [`STALL_CHECKS`]; allocated once, reset each time.
    pub(super) stall: Pin<Box<Sleep>>,
    /// Since when the peer has taken nothing; `None`: no write is waiting (none
    /// has had to, or one has gone through since).
    pub(super) stalled: Option<Stall>,
    pub(super) _slot: Slot,
    /// Its peer's count; `None` for loopback.
    pub(super) _peer: Option<PeerSlot>,
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

    /// What a write that had to wait for the peer (`Pending`) answers: still
    /// `Pending`, the stall timer armed if it was not and registered to wake the
    /// task; or, once the peer has taken nothing for [`Self::stall_for`], the error
    /// that ends the connection.
    ///
    /// The peer's reading shows twice: a write goes through (and ends the stall)
    /// once the peer has taken a third of the socket's send buffer, and the bytes
    /// it has not acknowledged fall as soon as it takes any, which the timer's
    /// [`STALL_CHECKS`] look at: a peer that reads, but takes a third of the
    /// buffer more slowly than the limit (a send buffer grows to megabytes on
    /// loopback), is not cut.
    fn wait_for_peer<T>(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<T>> {
        let check_every = self.stall_for / STALL_CHECKS;
        let stall = match &mut self.stalled {
            Some(stall) => stall,
            None => {
                let now = Instant::now();
                self.stall.as_mut().reset(now + check_every);
                self.stalled.insert(Stall {
                    unacknowledged: unacknowledged(&self.io),
                    since: now,
                })
            }
        };
        while self.stall.as_mut().poll(cx).is_ready() {
            let now = Instant::now();
            let unacked = unacknowledged(&self.io);
            if let (Some(before), Some(after)) = (stall.unacknowledged, unacked)
                && after < before
            {
                stall.since = now;
            }
            stall.unacknowledged = unacked;
            let cut_at = stall.since + self.stall_for;
            if now >= cut_at {
                // Closed with a reset, its unsent bytes dropped: closed the
                // ordinary way, the socket would stay in the kernel, holding
                // those bytes, while it tried to hand them to a peer that takes
                // none.
                let _ = self.io.set_zero_linger();
                return Poll::Ready(Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!(
                        "the peer read nothing for {} s (the write-stall limit)",
                        self.stall_for.as_secs_f64()
                    ),
                )));
            }
            self.stall.as_mut().reset((now + check_every).min(cut_at));
        }
        Poll::Pending
    }

    /// `written`, a write's answer, with the stall timer armed, kept or disarmed
    /// by it: bytes taken, or a flush or shutdown done, is progress.
    fn after_write<T>(
        &mut self,
        cx: &mut Context<'_>,
        written: Poll<io::Result<T>>,
        progress: impl FnOnce(&T) -> bool,
    ) -> Poll<io::Result<T>> {
        match written {
            Poll::Pending => self.wait_for_peer(cx),
            Poll::Ready(Ok(v)) => {
                if progress(&v) {
                    self.stalled = None;
                }
                Poll::Ready(Ok(v))
            }
            Poll::Ready(Err(e)) => Poll::Ready(Err(e)),
        }
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
        let written = Pin::new(&mut this.io).poll_write(cx, buf);
        this.after_write(cx, written, |&n| n > 0)
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
        let written = Pin::new(&mut this.io).poll_write_vectored(cx, bufs);
        this.after_write(cx, written, |&n| n > 0)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        let written = Pin::new(&mut this.io).poll_flush(cx);
        this.after_write(cx, written, |_| true)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if let Some(e) = this.severed(cx) {
            return Poll::Ready(Err(e));
        }
        let written = Pin::new(&mut this.io).poll_shutdown(cx);
        this.after_write(cx, written, |_| true)
    }
}

/// Has the kernel give up on `tcp` once bytes written to it have waited `limit`
/// for the peer (`TCP_USER_TIMEOUT`, ms): unacknowledged, or unsent behind a
/// window the peer keeps shut (Linux counts that from its first zero-window probe
/// and starts again when the window opens, so a slow reader is kept). It holds
/// after the server closes the socket, where the write-stall timer of [`Conn`]
/// cannot: an orphan with an answer its peer never reads goes at the limit. A
/// link that delivers nothing for the limit is cut as well; it stays at least the
/// 30 s default (`--write-stall`), and a station that hears nothing for its own
/// 5 s has lost its instruments by then. Rounded up to whole ms and capped at
/// what the option holds; a system that refuses the option leaves the kernel's
/// own bound, minutes.
#[cfg(target_os = "linux")]
pub(super) fn hand_over_within(tcp: &TcpStream, limit: Duration) {
    use std::os::fd::AsRawFd;
    let ms = limit.as_nanos().div_ceil(1_000_000);
    let ms = libc::c_uint::try_from(ms).unwrap_or(libc::c_uint::MAX);
    // SAFETY: `TCP_USER_TIMEOUT` reads one unsigned int, from `ms`, for the
    // connection's own open descriptor.
    let _ = unsafe {
        libc::setsockopt(
            tcp.as_raw_fd(),
            libc::IPPROTO_TCP,
            libc::TCP_USER_TIMEOUT,
            (&ms as *const libc::c_uint).cast(),
            std::mem::size_of::<libc::c_uint>() as libc::socklen_t,
        )
    };
}

/// Has the kernel give up on `tcp` after `limit`: not offered here, so the
/// kernel's own bound holds once the server has closed the socket.
#[cfg(not(target_os = "linux"))]
pub(super) fn hand_over_within(_tcp: &TcpStream, _limit: Duration) {}

/// Bytes written to `tcp` that its peer has not acknowledged yet (`SIOCOUTQ`);
/// `None` where the system does not tell.
#[cfg(target_os = "linux")]
fn unacknowledged(tcp: &TcpStream) -> Option<usize> {
    use std::os::fd::AsRawFd;
    let mut bytes: libc::c_int = 0;
    // SAFETY: `SIOCOUTQ` (`TIOCOUTQ` by its other name) writes one int, to
    // `bytes`, about the connection's own open descriptor.
    let done = unsafe { libc::ioctl(tcp.as_raw_fd(), libc::TIOCOUTQ, &mut bytes) };
    (done == 0).then(|| usize::try_from(bytes).ok()).flatten()
}

/// Bytes written to `tcp` that its peer has not acknowledged yet: not told here,
/// so a write that waits the whole limit fails.
#[cfg(not(target_os = "linux"))]
fn unacknowledged(_tcp: &TcpStream) -> Option<usize> {
    None
}
