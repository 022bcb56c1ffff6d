//! The TCP connection under a channel. tonic's own connector is replaced by this one
//! so that a failure can be told in words: it remembers whether the TCP connection
//! was made at all (a peer that never accepted versus one that accepted and said
//! nothing) and the first bytes the peer sent (an HTTP/1 server answers the HTTP/2
//! preface with `HTTP/1.1 400 …`, a TLS server with an alert record).
//!
//! For an `https` URL tonic runs TLS over this connection, so the bytes remembered
//! are the raw ones: a plain HTTP server behind an `https` URL shows as such.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use hyper_util::rt::TokioIo;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tonic::codegen::Service;
use tonic::codegen::http::Uri;

/// How many of the peer's first bytes are kept: an HTTP/1 status line, a TLS record
/// header or an HTTP/2 frame header fit many times over.
pub const FIRST_BYTES: usize = 64;

/// What a connection saw of its peer, shared between the connector and whoever
/// explains a failure.
#[derive(Debug, Default)]
pub struct Seen {
    connected: AtomicBool,
    /// Set once [`FIRST_BYTES`] bytes are kept: later reads skip the lock.
    full: AtomicBool,
    first: Mutex<Vec<u8>>,
}

impl Seen {
    /// Whether a TCP connection was made.
    pub fn connected(&self) -> bool {
        self.connected.load(Ordering::Relaxed)
    }

    /// The first bytes the peer sent (at most [`FIRST_BYTES`]).
    pub fn first_bytes(&self) -> Vec<u8> {
        self.first.lock().map(|b| b.clone()).unwrap_or_default()
    }

    fn keep(&self, bytes: &[u8]) {
        if let Ok(mut first) = self.first.lock() {
            let room = FIRST_BYTES - first.len();
            first.extend_from_slice(&bytes[..bytes.len().min(room)]);
            if first.len() == FIRST_BYTES {
                self.full.store(true, Ordering::Relaxed);
            }
        }
    }
}

/// Connects to the host and port of a URI (80 or 443 by default), with
/// `TCP_NODELAY` (poses are small and must not wait for more), recording in
/// [`Seen`] what it sees.
#[derive(Clone, Debug, Default)]
pub struct Dial {
    /// What the connections made saw.
    pub seen: Arc<Seen>,
}

impl Service<Uri> for Dial {
    type Response = TokioIo<Watched>;
    type Error = io::Error;
    type Future = Pin<Box<dyn Future<Output = io::Result<TokioIo<Watched>>> + Send>>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, uri: Uri) -> Self::Future {
        let seen = Arc::clone(&self.seen);
        Box::pin(async move {
            let host = uri
                .host()
                .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the URL has no host"))?
                .trim_start_matches('[')
                .trim_end_matches(']')
                .to_owned();
            let port = uri.port_u16().unwrap_or(match uri.scheme_str() {
                Some("https") => 443,
                _ => 80,
            });
            let stream = TcpStream::connect((host.as_str(), port)).await?;
            stream.set_nodelay(true)?;
            seen.connected.store(true, Ordering::Relaxed);
            Ok(TokioIo::new(Watched { stream, seen }))
        })
    }
}

/// A TCP stream that keeps the first bytes it reads in its [`Seen`].
#[derive(Debug)]
pub struct Watched {
    stream: TcpStream,
    seen: Arc<Seen>,
}

impl AsyncRead for Watched {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        let result = Pin::new(&mut this.stream).poll_read(cx, buf);
        if !this.seen.full.load(Ordering::Relaxed) && buf.filled().len() > before {
            this.seen.keep(&buf.filled()[before..]);
        }
        result
    }
}

impl AsyncWrite for Watched {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().stream).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }
}
