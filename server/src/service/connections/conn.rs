//! An accepted connection: closed when it has had no open stream for the idle
//! limit, failed when the server's severance is cut (see [`connections`](super)).

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

/// An accepted TCP connection (see the module documentation).
pub struct Conn {
    pub(super) io: TcpStream,
    pub(super) info: ConnInfo,
    pub(super) idle_for: Duration,
    pub(super) idle: Pin<Box<Sleep>>,
    /// The value of `begun` the idle timer was armed at; `None`: a stream is open.
    pub(super) armed_at: Option<u64>,
    pub(super) severed: Pin<Box<WaitForCancellationFutureOwned>>,
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
