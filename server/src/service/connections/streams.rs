//! The open streams of a connection: a tower layer counts each request from its
//! start until its response body is dropped, and wakes the connection when its
//! last stream ends (see [`connections`](super), "Idle").

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};

use tonic::transport::server::TcpConnectInfo;

/// The open streams of one connection.
#[derive(Debug, Default)]
pub(super) struct Streams {
    pub(super) open: AtomicUsize,
    /// Streams ever begun: an idle period restarts when this changes.
    pub(super) begun: AtomicU64,
    /// The connection's task, woken when its last stream ends.
    pub(super) waker: Mutex<Option<Waker>>,
}

/// What a request knows of its connection (tonic's connect info): its addresses and
/// its stream count.
#[derive(Clone, Debug)]
pub struct ConnInfo {
    pub tcp: TcpConnectInfo,
    pub(super) streams: Arc<Streams>,
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
    fn a_stream_counts_until_its_guard_drops_and_wakes_the_connection() {
        let streams = Arc::new(Streams::default());
        let g = StreamGuard::new(streams.clone());
        assert_eq!(streams.open.load(Ordering::Acquire), 1);
        assert_eq!(streams.begun.load(Ordering::Acquire), 1);
        drop(g);
        assert_eq!(streams.open.load(Ordering::Acquire), 0);
        assert_eq!(streams.begun.load(Ordering::Acquire), 1);
    }
}
