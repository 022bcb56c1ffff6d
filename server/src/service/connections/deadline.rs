//! A call's request must arrive whole within [`REQUEST_DEADLINE`] of its start,
//! but a `Join`'s, which is the station's stream for as long as it stays (and
//! server reflection's, a stream too).
//!
//! Every other call sends one message (unary calls, and `Attach`, `Observe` and
//! `Replay`, whose answer streams); its request body is a few hundred bytes to
//! 64 KiB and ends with that message. A body sent a byte at a time held its call,
//! its stream count and so its connection open for ever: the idle timeout closes a
//! connection with no open stream, hyper's header timeout covers headers only, and
//! HTTP/2 keepalive answers PINGs while the body trickles. One peer could so keep
//! its share of connections without ever reconnecting. Here the body of such a
//! call fails with `DEADLINE_EXCEEDED` naming the limit when it has not ended by
//! the deadline; the call ends, and with it the stream. `Join` is left to the
//! station's own timeout (`--station-timeout`), which counts whole messages.
//!
//! Such a call's body must also hold one message: a second is answered
//! `INTERNAL`, naming it, as gRPC's own servers answer it ([`framing`]).
//!
//! The layer sits inside gRPC-web's translation ([`call_layers`]), so that it
//! reads the gRPC body a browser's call is translated to and its status reaches
//! the browser as it is.
//!
//! [`call_layers`]: crate::service::call_layers

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use http::Request;
use http_body::{Body as HttpBody, Frame, SizeHint};
use tokio::time::{Instant, Sleep};
use tonic::Status;
use tonic::body::Body;

use framing::Framing;

/// How long a call's request may take to arrive whole, from its start: a 64 KiB
/// request over any working link arrives in well under a second; a client that
/// has not sent it in this long is not sending it.
pub const REQUEST_DEADLINE: Duration = Duration::from_secs(30);

/// The calls whose request is a stream, as (service, method): the station's
/// `Join`, and server reflection's `ServerReflectionInfo` (both versions), which
/// a tool may keep open between its questions.
const STREAMED: [(&str, &str); 3] = [
    (laparo_proto::v1::station_server::SERVICE_NAME, "Join"),
    (
        tonic_reflection::pb::v1::server_reflection_server::SERVICE_NAME,
        "ServerReflectionInfo",
    ),
    (
        tonic_reflection::pb::v1alpha::server_reflection_server::SERVICE_NAME,
        "ServerReflectionInfo",
    ),
];

/// Whether `path` (`/service/method`) names one of the [`STREAMED`] calls.
fn streams_its_request(path: &str) -> bool {
    path.strip_prefix('/')
        .and_then(|p| p.split_once('/'))
        .is_some_and(|call| STREAMED.contains(&call))
}

/// The layer of [`RequestDeadline`].
#[derive(Clone, Copy, Debug)]
pub struct RequestDeadlineLayer {
    deadline: Duration,
}

impl RequestDeadlineLayer {
    /// Requests (but those of the [`STREAMED`] calls) must end within `deadline`
    /// of their start.
    pub fn new(deadline: Duration) -> Self {
        RequestDeadlineLayer { deadline }
    }
}

impl<S> tower_layer::Layer<S> for RequestDeadlineLayer {
    type Service = RequestDeadline<S>;

    fn layer(&self, inner: S) -> RequestDeadline<S> {
        RequestDeadline {
            inner,
            deadline: self.deadline,
        }
    }
}

/// Gives every request body but those of the [`STREAMED`] calls a deadline (see
/// the module).
#[derive(Clone, Debug)]
pub struct RequestDeadline<S> {
    inner: S,
    deadline: Duration,
}

impl<S, B> tower_service::Service<Request<B>> for RequestDeadline<S>
where
    S: tower_service::Service<Request<Body>>,
    B: HttpBody<Data = tonic::codegen::Bytes> + Send + 'static,
    B::Error: Into<tonic::codegen::StdError>,
{
    type Response = S::Response;
    type Error = S::Error;
    type Future = S::Future;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: Request<B>) -> S::Future {
        if streams_its_request(request.uri().path()) {
            return self.inner.call(request.map(Body::new));
        }
        let deadline = self.deadline;
        self.inner.call(request.map(|body| {
            Body::new(Deadlined {
                body: Body::new(body),
                sleep: Box::pin(tokio::time::sleep_until(Instant::now() + deadline)),
                deadline,
                framing: Framing::default(),
            })
        }))
    }
}

/// A request body that fails once its deadline passes before it ends, or once a
/// second message begins in it.
struct Deadlined {
    body: Body,
    sleep: Pin<Box<Sleep>>,
    deadline: Duration,
    framing: Framing,
}

impl HttpBody for Deadlined {
    type Data = tonic::codegen::Bytes;
    type Error = Status;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Status>>> {
        if let Poll::Ready(frame) = Pin::new(&mut self.body).poll_frame(cx) {
            if let Some(Ok(frame)) = &frame
                && let Some(data) = frame.data_ref()
                && !self.framing.read(data)
            {
                return Poll::Ready(Some(Err(Status::internal(
                    "the request held a second message: this call takes one (only \
                     Join's request may stream)",
                ))));
            }
            return Poll::Ready(frame);
        }
        match self.sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Some(Err(Status::deadline_exceeded(format!(
                "the request did not arrive whole within {} s of its start (the \
                 server's limit for a call's request; only Join's may stream)",
                self.deadline.as_secs_f64()
            ))))),
            Poll::Pending => Poll::Pending,
        }
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.body.size_hint()
    }
}

mod framing;
#[cfg(test)]
mod tests;
