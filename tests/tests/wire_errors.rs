//! Requests that cannot be read, sent as raw bytes through tonic's generic client
//! (as a client in another language, or a broken one, would send them): bytes that
//! are not the request message answer `INVALID_ARGUMENT`, a message over the
//! server's size limit `RESOURCE_EXHAUSTED` naming the limit in bytes, on a unary
//! call and on the `Station.Join` stream, before and after `Joined`. Bodies that
//! are not even gRPC framing (a compression flag without an encoding, a flag that
//! does not exist, no message at all, gRPC-web text that is not base64) are sent
//! as raw HTTP/2 or HTTP/1.1 and answer `INVALID_ARGUMENT` too.

use bytes::{Buf, BufMut, Bytes};
use laparo_proto::v1;
use laparo_server::service::{MAX_MESSAGE_BYTES, ServeConfig};
use laparo_tests::server::*;
use prost::Message;
use tonic::codec::{Codec, DecodeBuf, Decoder, EncodeBuf, Encoder};
use tonic::codegen::Service;
use tonic::codegen::http::{self, uri::PathAndQuery};
use tonic::transport::Channel;
use tonic::{Code, Request, Status};

/// A codec that sends and receives message bodies as they are.
#[derive(Clone, Copy, Default)]
struct Raw;

impl Codec for Raw {
    type Encode = Bytes;
    type Decode = Bytes;
    type Encoder = Raw;
    type Decoder = Raw;
    fn encoder(&mut self) -> Raw {
        Raw
    }
    fn decoder(&mut self) -> Raw {
        Raw
    }
}

impl Encoder for Raw {
    type Item = Bytes;
    type Error = Status;
    fn encode(&mut self, item: Bytes, dst: &mut EncodeBuf<'_>) -> Result<(), Status> {
        dst.put_slice(&item);
        Ok(())
    }
}

impl Decoder for Raw {
    type Item = Bytes;
    type Error = Status;
    fn decode(&mut self, src: &mut DecodeBuf<'_>) -> Result<Option<Bytes>, Status> {
        Ok(Some(src.copy_to_bytes(src.remaining())))
    }
}

/// Not a protobuf message: field 1 with wire type 7, which does not exist.
fn garbage() -> Bytes {
    Bytes::from_static(&[0x0f, 0xde, 0xad, 0xbe, 0xef])
}

/// A message body one byte over the limit (its content never matters: the limit
/// is checked on the length).
fn oversize() -> Bytes {
    Bytes::from(vec![0u8; MAX_MESSAGE_BYTES + 1])
}

async fn unary(ch: Channel, path: &'static str, body: Bytes) -> Result<Bytes, Status> {
    let mut grpc = tonic::client::Grpc::new(ch);
    grpc.ready().await.unwrap();
    grpc.unary(Request::new(body), PathAndQuery::from_static(path), Raw)
        .await
        .map(|r| r.into_inner())
}

/// Opens `Station.Join` with `bodies` as its messages; the call's status, or the
/// messages received before the stream ended and the status it ended with.
async fn join_bytes(ch: Channel, bodies: Vec<Bytes>) -> (Vec<v1::ServerMessage>, Status) {
    let mut grpc = tonic::client::Grpc::new(ch);
    grpc.ready().await.unwrap();
    // The request stream stays open after its messages, as a station's does.
    let stream = tokio_stream::StreamExt::chain(
        tokio_stream::iter(bodies),
        tokio_stream::pending::<Bytes>(),
    );
    let call = grpc
        .streaming(
            Request::new(stream),
            PathAndQuery::from_static("/laparo.v1.Station/Join"),
            Raw,
        )
        .await;
    let mut rx = match call {
        Ok(r) => r.into_inner(),
        Err(status) => return (Vec::new(), status),
    };
    let mut received = Vec::new();
    let ended = tokio::time::timeout(WAIT, async {
        loop {
            match rx.message().await {
                Ok(Some(body)) => received.push(v1::ServerMessage::decode(body).unwrap()),
                Ok(None) => return Status::ok(""),
                Err(status) => return status,
            }
        }
    })
    .await
    .expect("the server ends the stream");
    (received, ended)
}

/// An opening message claiming nothing (the test server has no tokens: every
/// caller is an instructor and may watch).
fn open_bytes(session: &str) -> Bytes {
    Bytes::from(open(session, &[]).encode_to_vec())
}

fn assert_over_limit(status: &Status) {
    assert_eq!(status.code(), Code::ResourceExhausted, "{status:?}");
    assert!(
        status
            .message()
            .contains(&format!("{MAX_MESSAGE_BYTES} bytes")),
        "the message names the limit in bytes: {status:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_unary_request_that_cannot_be_read_gets_the_contracts_code() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let path = "/laparo.v1.Sessions/GetSession";
    let bad = unary(ch.clone(), path, garbage()).await.unwrap_err();
    assert_eq!(bad.code(), Code::InvalidArgument, "{bad:?}");
    assert!(bad.message().contains("decode"), "{bad:?}");
    let big = unary(ch.clone(), path, oversize()).await.unwrap_err();
    assert_over_limit(&big);
    // A request that is read answers as before: an empty GetSessionRequest names
    // no session.
    let empty = unary(ch.clone(), path, Bytes::new()).await.unwrap_err();
    assert_eq!(empty.code(), Code::NotFound, "{empty:?}");
    // A server stream's request is read the same way.
    let observe = "/laparo.v1.Observe/Observe";
    let mut grpc = tonic::client::Grpc::new(ch.clone());
    grpc.ready().await.unwrap();
    let bad = grpc
        .server_streaming(
            Request::new(garbage()),
            PathAndQuery::from_static(observe),
            Raw,
        )
        .await
        .unwrap_err();
    assert_eq!(bad.code(), Code::InvalidArgument, "{bad:?}");
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_message_that_cannot_be_read_ends_join_with_the_contracts_code() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    // As the opening message: no Joined, the call's status.
    let (received, status) = join_bytes(ch.clone(), vec![garbage()]).await;
    assert!(received.is_empty(), "{received:?}");
    assert_eq!(status.code(), Code::InvalidArgument, "{status:?}");
    let (received, status) = join_bytes(ch.clone(), vec![oversize()]).await;
    assert!(received.is_empty(), "{received:?}");
    assert_over_limit(&status);
    // After Joined: the stream ends with the status.
    for (bad, code) in [
        (garbage(), Code::InvalidArgument),
        (oversize(), Code::ResourceExhausted),
    ] {
        let (received, status) = join_bytes(ch.clone(), vec![open_bytes(&session), bad]).await;
        assert!(
            matches!(
                received.first().and_then(|m| m.kind.as_ref()),
                Some(v1::server_message::Kind::Joined(_))
            ),
            "{received:?}"
        );
        assert_eq!(status.code(), code, "{status:?}");
        if code == Code::ResourceExhausted {
            assert_over_limit(&status);
        }
    }
    server.shutdown().await.unwrap();
}

/// `body` as the whole HTTP/2 body of a gRPC call to `path`, framing and all; the
/// status the server answers with before reading further (a trailers-only answer:
/// the status in the response's headers).
async fn raw_h2(ch: Channel, path: &str, body: &'static str) -> Status {
    // The bytes these tests send are all below 0x80: a `String` carries them as
    // they are, and is an HTTP body.
    let body = if body.is_empty() {
        tonic::body::Body::empty()
    } else {
        tonic::body::Body::new(body.to_string())
    };
    let request = http::Request::post(format!("http://laparo{path}"))
        .header("content-type", "application/grpc")
        .header("te", "trailers")
        .body(body)
        .unwrap();
    let mut ch = ch;
    std::future::poll_fn(|cx| ch.poll_ready(cx)).await.unwrap();
    let response = tokio::time::timeout(WAIT, ch.call(request))
        .await
        .expect("the server answers")
        .unwrap();
    Status::from_header_map(response.headers())
        .unwrap_or_else(|| panic!("a trailers-only answer: {response:?}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_body_that_is_not_grpc_framing_gets_invalid_argument() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let path = "/laparo.v1.Scenes/GetScene";
    for (what, body, says) in [
        (
            "flagged compressed without grpc-encoding",
            // flag 1, length 3, GetSceneRequest { name: "a" }
            "\x01\0\0\0\x03\x0a\x01a",
            "compressed-flag but no grpc-encoding",
        ),
        (
            "a compression flag that does not exist",
            "\x07\0\0\0\0",
            "invalid compression flag: 7",
        ),
        ("no message at all", "", "no message"),
    ] {
        let status = raw_h2(ch.clone(), path, body).await;
        assert_eq!(status.code(), Code::InvalidArgument, "{what}: {status:?}");
        assert!(status.message().contains(says), "{what}: {status:?}");
    }
    // The same framing with flag 0 is read: the scene "a" does not exist.
    let plain = raw_h2(ch.clone(), path, "\0\0\0\0\x03\x0a\x01a").await;
    assert_eq!(plain.code(), Code::NotFound, "{plain:?}");
    server.shutdown().await.unwrap();
}

/// A gRPC-web text call (`application/grpc-web-text`, the body in base64) to
/// `Sessions.GetSession` over HTTP/1.1; the response's head, lower-cased.
async fn grpc_web_text(server: &TestServer, body: &str) -> String {
    let request = format!(
        "POST /laparo.v1.Sessions/GetSession HTTP/1.1\r\nhost: x\r\ncontent-type: application/grpc-web-text\r\ncontent-length: {}\r\n\r\n{body}",
        body.len()
    );
    http_head(server, &request).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_web_text_that_is_not_base64_gets_invalid_argument() {
    let server = TestServer::start(ServeConfig::default()).await;
    // Five zero bytes (an empty GetSessionRequest, framed) in base64: read, and
    // the empty id names no session.
    let read = grpc_web_text(&server, "AAAAAAA=").await;
    assert!(read.contains("grpc-status: 5"), "{read}");
    // "!" is no base64 symbol; three characters are no whole base64 group.
    for body in ["!!!!!!!!", "AAA"] {
        let head = grpc_web_text(&server, body).await;
        assert!(head.starts_with("http/1.1 200"), "{body}: {head}");
        assert!(head.contains("grpc-status: 3"), "{body}: {head}");
        assert!(head.contains("base64"), "{body}: {head}");
    }
    server.shutdown().await.unwrap();
}
