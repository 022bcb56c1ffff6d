//! The request deadline, in paused time: a body that does not end fails at the
//! deadline with a status naming it; one that ends passes whole; a `Join`'s and
//! reflection's are left alone.

use std::convert::Infallible;
use std::future::poll_fn;

use tonic::Code;

use super::*;

/// A request body that never sends anything and never ends: a client trickling
/// nothing more.
struct Silent;

impl HttpBody for Silent {
    type Data = tonic::codegen::Bytes;
    type Error = Status;

    fn poll_frame(
        self: Pin<&mut Self>,
        _: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Status>>> {
        Poll::Pending
    }
}

/// A service that answers each request with its body, to read it as the handler
/// would.
struct Echo;

impl tower_service::Service<Request<Body>> for Echo {
    type Response = Body;
    type Error = Infallible;
    type Future = std::future::Ready<Result<Body, Infallible>>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, request: Request<Body>) -> Self::Future {
        std::future::ready(Ok(request.into_body()))
    }
}

async fn body_through(path: &str, body: Body) -> Body {
    use tower_layer::Layer;
    use tower_service::Service;
    let mut service = RequestDeadlineLayer::new(REQUEST_DEADLINE).layer(Echo);
    let request = Request::builder().uri(path).body(body).unwrap();
    service.call(request).await.unwrap()
}

async fn next_frame(body: &mut Body) -> Option<Result<Frame<tonic::codegen::Bytes>, Status>> {
    poll_fn(|cx| Pin::new(&mut *body).poll_frame(cx)).await
}

#[tokio::test(start_paused = true)]
async fn a_request_that_does_not_end_fails_at_its_deadline_naming_it() {
    let start = Instant::now();
    let mut body = body_through("/laparo.v1.Sessions/GetSession", Body::new(Silent)).await;
    let status = match next_frame(&mut body).await {
        Some(Err(status)) => status,
        other => panic!("a silent body should fail, not give {other:?}"),
    };
    assert_eq!(start.elapsed(), REQUEST_DEADLINE);
    assert_eq!(status.code(), Code::DeadlineExceeded);
    assert!(
        status.message().contains("within 30 s of its start"),
        "{status:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn a_request_that_arrives_passes_whole_and_a_stream_for_as_long_as_it_likes() {
    let mut body = body_through(
        "/laparo.v1.Sessions/GetSession",
        Body::new("s1".to_string()),
    )
    .await;
    let frame = next_frame(&mut body).await.unwrap().unwrap();
    assert_eq!(frame.into_data().unwrap(), "s1");
    assert!(next_frame(&mut body).await.is_none());
    for path in [
        "/laparo.v1.Station/Join",
        "/grpc.reflection.v1.ServerReflection/ServerReflectionInfo",
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
    ] {
        let mut stream = body_through(path, Body::new(Silent)).await;
        let waited = tokio::time::timeout(REQUEST_DEADLINE * 10, next_frame(&mut stream)).await;
        assert!(
            waited.is_err(),
            "{path}: a stream has no deadline: {waited:?}"
        );
    }
    // Anything else of those services, or a path that is not `/service/method`,
    // is a call like any other.
    for path in [
        "/laparo.v1.Station/SendPoses",
        "/laparo.v1.Station/Join/x",
        "Join",
    ] {
        assert!(!streams_its_request(path), "{path}");
    }
}

/// The status a gRPC or gRPC-web response carries, from its headers (a
/// trailers-only answer), its HTTP trailers (gRPC), or the trailer frame of its
/// body (gRPC-web: flag 0x80, a length, then `name: value` lines).
async fn status_of(response: http::Response<Body>) -> Status {
    if let Some(status) = Status::from_header_map(response.headers()) {
        return status;
    }
    let mut body = response.into_body();
    let mut bytes = Vec::new();
    while let Some(frame) = next_frame(&mut body).await {
        match frame.expect("the answer's body").into_data() {
            Ok(data) => bytes.extend_from_slice(&data),
            // gRPC's trailers, as HTTP trailers.
            Err(frame) => {
                if let Ok(trailers) = frame.into_trailers() {
                    return Status::from_header_map(&trailers).expect("a grpc-status");
                }
            }
        }
    }
    let at = bytes
        .iter()
        .position(|&b| b == 0x80)
        .unwrap_or_else(|| panic!("no trailer frame in {bytes:?}"));
    let mut trailers = http::HeaderMap::new();
    for line in String::from_utf8_lossy(&bytes[at + 5..]).lines() {
        if let Some((name, value)) = line.split_once(':') {
            trailers.insert(
                http::HeaderName::try_from(name.trim()).unwrap(),
                http::HeaderValue::try_from(value.trim()).unwrap(),
            );
        }
    }
    Status::from_header_map(&trailers).expect("a grpc-status in the trailers")
}

#[tokio::test(start_paused = true)]
async fn a_grpc_web_request_that_does_not_end_is_answered_deadline_exceeded() {
    // Through the server's own stack of layers to a real service (health): the
    // deadline acts on the translated body, so the status is the deadline's own,
    // not the translation's INTERNAL.
    use tower_layer::Layer;
    use tower_service::Service;
    let (_, health) = tonic_health::server::health_reporter();
    let mut service = crate::service::call_layers(REQUEST_DEADLINE).layer(health);
    let request = Request::builder()
        .method("POST")
        .version(http::Version::HTTP_11)
        .uri("/grpc.health.v1.Health/Check")
        .header("content-type", "application/grpc-web+proto")
        .body(Body::new(Silent))
        .unwrap();
    let start = Instant::now();
    let response = service.call(request).await.unwrap();
    let status = status_of(response).await;
    assert_eq!(start.elapsed(), REQUEST_DEADLINE);
    assert_eq!(status.code(), Code::DeadlineExceeded, "{status:?}");
    assert!(
        status.message().contains("within 30 s of its start"),
        "{status:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn a_second_message_in_a_one_message_call_is_refused_naming_it() {
    // Health's Check takes one message; an empty one is its 5-byte prefix alone.
    use tower_layer::Layer;
    use tower_service::Service;
    let (_, health) = tonic_health::server::health_reporter();
    let mut service = crate::service::call_layers(REQUEST_DEADLINE).layer(health);
    for (messages, content_type) in [
        (1, "application/grpc"),
        (2, "application/grpc"),
        (1, "application/grpc-web+proto"),
        (2, "application/grpc-web+proto"),
    ] {
        let version = match content_type {
            "application/grpc" => http::Version::HTTP_2,
            _ => http::Version::HTTP_11,
        };
        // NUL bytes are UTF-8: the messages go as a string body.
        let body = "\0".repeat(5 * messages);
        let request = Request::builder()
            .method("POST")
            .version(version)
            .uri("/grpc.health.v1.Health/Check")
            .header("content-type", content_type)
            .header("te", "trailers")
            .body(Body::new(body))
            .unwrap();
        let response = service.call(request).await.unwrap();
        let status = status_of(response).await;
        if messages == 1 {
            assert_eq!(status.code(), Code::Ok, "{content_type}: {status:?}");
        } else {
            assert_eq!(status.code(), Code::Internal, "{content_type}: {status:?}");
            assert!(status.message().contains("a second message"), "{status:?}");
        }
    }
}
