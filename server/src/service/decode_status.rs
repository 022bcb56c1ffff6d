//! The statuses of requests that cannot be read, as the contract states them.
//!
//! tonic decides these before a handler runs, with the codes of the gRPC core
//! implementations, which the contract does not use:
//!
//! | what the client sent | tonic 0.14 answers | where it decides | the contract says |
//! |---|---|---|---|
//! | bytes that are not the request message | `INTERNAL` "failed to decode Protobuf message: …" | `tonic_prost::codec::from_decode_error` | `INVALID_ARGUMENT` |
//! | a body that ends inside a message | `INTERNAL` "Unexpected EOF decoding stream." | `tonic::codec::decode` (end of body) | `INVALID_ARGUMENT` |
//! | a message over [`MAX_MESSAGE_BYTES`](super::MAX_MESSAGE_BYTES) | `OUT_OF_RANGE` "Error, decoded message length too large: found N bytes, the limit is: L bytes" | `tonic::codec::decode` (`max_decoding_message_size`) | `RESOURCE_EXHAUSTED` (the gRPC convention for a message over a configured limit) |
//!
//! [`contract_code`] recognises these three by their code and the start of tonic's
//! own message, and gives the contract's code; the message is kept (the limit's
//! message names the size found and the limit, in bytes). A status a handler
//! makes never starts that way, so nothing else is rewritten. The tests of the
//! serving layer send such bytes through a generic gRPC client and check the
//! codes, so a tonic that words them otherwise fails a test rather than the
//! contract.
//!
//! Where they surface:
//! - a unary request (and the one request of a server stream) is decoded before
//!   the handler: the status is the whole answer, in the response's headers
//!   ("trailers-only"). [`ContractStatus`] wraps a service and rewrites the code
//!   there.
//! - the messages of a client stream (`Station.Join`) are decoded as the handler
//!   reads them: the handler maps the status with [`contract_status`] before it
//!   ends the stream with it.

use std::convert::Infallible;
use std::task::{Context, Poll};

use tonic::Code;
use tonic::Status;
use tonic::body::Body;
use tonic::codegen::http::{self, HeaderMap, HeaderValue};
use tonic::codegen::{BoxFuture, Service};
use tonic::server::NamedService;

/// Starts of tonic's messages for a request it could not read, with the code it
/// gives and the one the contract gives.
const DECODE_FAILURES: [(Code, &str, Code); 3] = [
    (
        Code::Internal,
        "failed to decode Protobuf message",
        Code::InvalidArgument,
    ),
    (
        Code::Internal,
        "Unexpected EOF decoding stream",
        Code::InvalidArgument,
    ),
    (
        Code::OutOfRange,
        "Error, decoded message length too large",
        Code::ResourceExhausted,
    ),
];

/// The contract's code for a status tonic gave a request it could not read;
/// `None` for any other status.
pub fn contract_code(code: Code, message: &str) -> Option<Code> {
    DECODE_FAILURES
        .iter()
        .find(|(from, start, _)| *from == code && message.starts_with(start))
        .map(|&(_, _, to)| to)
}

/// `status` with the contract's code if it is a decode failure (message kept),
/// unchanged otherwise.
pub fn contract_status(status: Status) -> Status {
    match contract_code(status.code(), status.message()) {
        Some(code) => Status::new(code, status.message()),
        None => status,
    }
}

/// Rewrites the code of a trailers-only answer (a status in the headers).
fn rewrite_headers(headers: &mut HeaderMap) {
    let (Some(code), message) = (
        headers.get("grpc-status"),
        headers.get("grpc-message").cloned(),
    ) else {
        return;
    };
    // Only the two headers are read: the message is percent-encoded on the wire.
    let mut status_only = HeaderMap::with_capacity(2);
    status_only.insert("grpc-status", code.clone());
    if let Some(m) = message {
        status_only.insert("grpc-message", m);
    }
    let Some(status) = Status::from_header_map(&status_only) else {
        return;
    };
    if let Some(code) = contract_code(status.code(), status.message()) {
        headers.insert("grpc-status", HeaderValue::from(code as i32));
    }
}

/// A service whose decode failures answer with the contract's codes.
#[derive(Clone)]
pub struct ContractStatus<S>(pub S);

impl<S: NamedService> NamedService for ContractStatus<S> {
    const NAME: &'static str = S::NAME;
}

impl<S, B> Service<http::Request<Body>> for ContractStatus<S>
where
    S: Service<http::Request<Body>, Response = http::Response<B>, Error = Infallible>,
    S::Future: Send + 'static,
{
    type Response = http::Response<B>;
    type Error = Infallible;
    type Future = BoxFuture<Self::Response, Self::Error>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.0.poll_ready(cx)
    }

    fn call(&mut self, request: http::Request<Body>) -> Self::Future {
        let answer = self.0.call(request);
        Box::pin(async move {
            let mut response = answer.await?;
            rewrite_headers(response.headers_mut());
            Ok(response)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_failures_get_the_contracts_codes_and_keep_their_messages() {
        let garbage = Status::internal("failed to decode Protobuf message: invalid wire type");
        let mapped = contract_status(garbage);
        assert_eq!(mapped.code(), Code::InvalidArgument);
        assert_eq!(
            mapped.message(),
            "failed to decode Protobuf message: invalid wire type"
        );
        let big = Status::out_of_range(
            "Error, decoded message length too large: found 70000 bytes, the limit is: 65536 bytes",
        );
        let mapped = contract_status(big);
        assert_eq!(mapped.code(), Code::ResourceExhausted);
        assert!(mapped.message().contains("65536 bytes"));
        let cut = contract_status(Status::internal("Unexpected EOF decoding stream."));
        assert_eq!(cut.code(), Code::InvalidArgument);
    }

    #[test]
    fn other_statuses_are_left_alone() {
        for s in [
            Status::internal("reading recordings failed: disk"),
            Status::out_of_range("start_offset_s is past the end"),
            Status::invalid_argument("failed to decode Protobuf message"),
            Status::not_found("no session"),
        ] {
            let (code, message) = (s.code(), s.message().to_owned());
            let same = contract_status(s);
            assert_eq!((same.code(), same.message()), (code, message.as_str()));
        }
    }

    #[test]
    fn a_trailers_only_answer_is_rewritten_in_its_headers() {
        let mut headers = HeaderMap::new();
        Status::internal("failed to decode Protobuf message: buffer underflow")
            .add_header(&mut headers)
            .unwrap();
        headers.insert("content-type", HeaderValue::from_static("application/grpc"));
        rewrite_headers(&mut headers);
        let status = Status::from_header_map(&headers).unwrap();
        assert_eq!(status.code(), Code::InvalidArgument);
        assert_eq!(
            status.message(),
            "failed to decode Protobuf message: buffer underflow"
        );
        assert_eq!(headers["content-type"], "application/grpc");
        // Headers without a status (a stream that starts) are untouched.
        let mut plain = HeaderMap::new();
        plain.insert("content-type", HeaderValue::from_static("application/grpc"));
        rewrite_headers(&mut plain);
        assert_eq!(plain.len(), 1);
    }
}
