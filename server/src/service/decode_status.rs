//! The statuses of requests that cannot be read, as the contract states them.
//!
//! tonic (and tonic-web, for the console's gRPC-web) decides these before a
//! handler runs, with the codes of the gRPC core implementations, which the
//! contract does not use:
//!
//! | what the client sent | tonic 0.14 answers | where it decides | the contract says |
//! |---|---|---|---|
//! | bytes that are not the request message | `INTERNAL` "failed to decode Protobuf message: …" | `tonic_prost::codec::from_decode_error` | `INVALID_ARGUMENT` |
//! | a body that ends inside a message | `INTERNAL` "Unexpected EOF decoding stream." | `tonic::codec::decode` (end of body) | `INVALID_ARGUMENT` |
//! | a message over [`MAX_MESSAGE_BYTES`](super::MAX_MESSAGE_BYTES) | `OUT_OF_RANGE` "Error, decoded message length too large: found N bytes, the limit is: L bytes" | `tonic::codec::decode` (`max_decoding_message_size`) | `RESOURCE_EXHAUSTED` (the gRPC convention for a message over a configured limit) |
//! | a message flagged compressed (flag 1) without a `grpc-encoding` | `INTERNAL` "protocol error: received message with compressed-flag but no grpc-encoding was specified" | `tonic::codec::decode` (message header) | `INVALID_ARGUMENT` |
//! | a compression flag other than 0 and 1 | `INTERNAL` "protocol error: received message with invalid compression flag: F (valid flags are 0 and 1), …" | `tonic::codec::decode` (message header) | `INVALID_ARGUMENT` |
//! | a unary (or server-stream) request whose body holds no message | `INTERNAL` "Missing request message." | `tonic::server::Grpc::map_request_unary` | `INVALID_ARGUMENT`, the message saying the body is empty |
//! | gRPC-web text (`application/grpc-web-text`) that is not base64 | `INTERNAL` "tonic-web: Invalid symbol …", "… Invalid last symbol …", "… Invalid input length …", "… Invalid padding", or "tonic-web: malformed base64 request" (characters left over at the end) | `tonic_web::call` (the body's base64, an error of the request body that tonic's decoder passes on) | `INVALID_ARGUMENT`, the message saying the body is not base64 |
//!
//! gRPC core's compression document asks for `INTERNAL` on a compressed flag
//! without an encoding; the contract answers every request the client got wrong
//! with `INVALID_ARGUMENT`, so that `INTERNAL` means a fault of the server.
//!
//! [`contract_status`] recognises these by their code and the start of tonic's
//! own message, and gives the contract's code; the message is kept (the limit's
//! message names the size found and the limit, in bytes), with what was wrong
//! put before it where tonic's words do not say it. A status a handler makes
//! never starts that way, nor do tonic-web's errors of the connection itself
//! (a body that fails to arrive), so nothing else is rewritten. The tests of the
//! serving layer send such bytes through a generic gRPC client, raw HTTP/2 and
//! raw HTTP/1.1 and check the codes, so a tonic that words them otherwise fails a
//! test rather than the contract.
//!
//! Where they surface:
//! - a unary request (and the one request of a server stream) is decoded before
//!   the handler: the status is the whole answer, in the response's headers
//!   ("trailers-only"). [`ContractStatus`] wraps a service and rewrites the
//!   status there (inside tonic-web's translation, so gRPC-web gets it too).
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

/// A status tonic gives a request it could not read, and the contract's.
struct DecodeFailure {
    /// The code tonic gives.
    tonic: Code,
    /// The start of tonic's message.
    starts: &'static str,
    /// The code the contract gives.
    contract: Code,
    /// What was wrong, put before tonic's message when its words do not say it.
    says: Option<&'static str>,
}

const fn failure(
    tonic: Code,
    starts: &'static str,
    contract: Code,
    says: Option<&'static str>,
) -> DecodeFailure {
    DecodeFailure {
        tonic,
        starts,
        contract,
        says,
    }
}

/// What a gRPC-web text body that is not base64 is said to be.
const NOT_BASE64: Option<&str> = Some("the gRPC-web text body is not base64");

/// The failures of the table above, in its order.
const DECODE_FAILURES: [DecodeFailure; 11] = [
    failure(
        Code::Internal,
        "failed to decode Protobuf message",
        Code::InvalidArgument,
        None,
    ),
    failure(
        Code::Internal,
        "Unexpected EOF decoding stream",
        Code::InvalidArgument,
        None,
    ),
    failure(
        Code::OutOfRange,
        "Error, decoded message length too large",
        Code::ResourceExhausted,
        None,
    ),
    failure(
        Code::Internal,
        "protocol error: received message with compressed-flag but no grpc-encoding",
        Code::InvalidArgument,
        None,
    ),
    failure(
        Code::Internal,
        "protocol error: received message with invalid compression flag",
        Code::InvalidArgument,
        None,
    ),
    failure(
        Code::Internal,
        "Missing request message",
        Code::InvalidArgument,
        Some("the request's body holds no message, and the call takes one"),
    ),
    // base64's `DecodeError`, as tonic-web words it.
    failure(
        Code::Internal,
        "tonic-web: Invalid symbol",
        Code::InvalidArgument,
        NOT_BASE64,
    ),
    failure(
        Code::Internal,
        "tonic-web: Invalid last symbol",
        Code::InvalidArgument,
        NOT_BASE64,
    ),
    failure(
        Code::Internal,
        "tonic-web: Invalid input length",
        Code::InvalidArgument,
        NOT_BASE64,
    ),
    failure(
        Code::Internal,
        "tonic-web: Invalid padding",
        Code::InvalidArgument,
        NOT_BASE64,
    ),
    // Also "… has unencoded trailers": trailers in a text body must be base64 too.
    failure(
        Code::Internal,
        "tonic-web: malformed base64 request",
        Code::InvalidArgument,
        NOT_BASE64,
    ),
];

/// The contract's code and message for a status tonic gave a request it could
/// not read; `None` for any other status.
pub fn contract_code(code: Code, message: &str) -> Option<(Code, String)> {
    let failure = DECODE_FAILURES
        .iter()
        .find(|f| f.tonic == code && message.starts_with(f.starts))?;
    let message = match failure.says {
        Some(says) => format!("{says}: {message}"),
        None => message.to_owned(),
    };
    Some((failure.contract, message))
}

/// `status` with the contract's code if it is a decode failure (message kept,
/// with what was wrong before it where tonic's words do not say it), unchanged
/// otherwise.
pub fn contract_status(status: Status) -> Status {
    match contract_code(status.code(), status.message()) {
        Some((code, message)) => Status::new(code, message),
        None => status,
    }
}

/// Rewrites the status of a trailers-only answer (a status in the headers).
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
    if let Some((code, message)) = contract_code(status.code(), status.message()) {
        // Writes both headers, the message percent-encoded.
        if Status::new(code, message).add_header(headers).is_err() {
            // A message that cannot be a header value (it can always be
            // percent-encoded): the code alone.
            headers.insert("grpc-status", HeaderValue::from(code as i32));
        }
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
    fn bodies_that_are_not_grpc_framing_are_invalid_arguments_that_say_why() {
        for (tonic, says) in [
            (
                "protocol error: received message with compressed-flag but no grpc-encoding was specified",
                "compressed-flag but no grpc-encoding",
            ),
            (
                "protocol error: received message with invalid compression flag: 7 (valid flags are 0 and 1), while sending request",
                "invalid compression flag: 7",
            ),
            ("Missing request message.", "body holds no message"),
            ("tonic-web: Invalid symbol 33, offset 0.", "not base64"),
            ("tonic-web: Invalid last symbol 66, offset 3.", "not base64"),
            ("tonic-web: Invalid input length: 5", "not base64"),
            ("tonic-web: Invalid padding", "not base64"),
            ("tonic-web: malformed base64 request", "not base64"),
        ] {
            let mapped = contract_status(Status::internal(tonic));
            assert_eq!(mapped.code(), Code::InvalidArgument, "{tonic}");
            assert!(mapped.message().contains(says), "{mapped:?}");
            assert!(mapped.message().ends_with(tonic), "{mapped:?}");
        }
    }

    #[test]
    fn other_statuses_are_left_alone() {
        for s in [
            Status::internal("reading recordings failed: disk"),
            // A request body that fails to arrive is the connection's, not the
            // client's message.
            Status::internal("tonic-web: error reading a body from connection"),
            Status::internal("Error decompressing: corrupt deflate stream, while sending request"),
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
        // A message with what was wrong put before it is rewritten too.
        let mut headers = HeaderMap::new();
        Status::internal("tonic-web: Invalid symbol 33, offset 0.")
            .add_header(&mut headers)
            .unwrap();
        rewrite_headers(&mut headers);
        let status = Status::from_header_map(&headers).unwrap();
        assert_eq!(status.code(), Code::InvalidArgument);
        assert_eq!(
            status.message(),
            "the gRPC-web text body is not base64: tonic-web: Invalid symbol 33, offset 0."
        );
        // Headers without a status (a stream that starts) are untouched.
        let mut plain = HeaderMap::new();
        plain.insert("content-type", HeaderValue::from_static("application/grpc"));
        rewrite_headers(&mut plain);
        assert_eq!(plain.len(), 1);
    }
}
