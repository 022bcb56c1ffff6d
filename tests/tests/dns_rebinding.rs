//! DNS rebinding against a real server without tokens: a page at
//! `http://attacker.example:PORT` whose name comes to point at the server calls
//! it same-origin, and the server refuses it by the host the call names
//! (`PERMISSION_DENIED` naming the host and `--allowed-host`; nothing done).
//! Calls naming an IP address, `localhost`, a `--cors-origin`'s host or an
//! `--allowed-host` are served; with tokens the interceptor answers instead; a
//! native gRPC client (no `Origin`) is served whatever authority it names, and
//! the page's assets whatever host the request names; a malformed or non-ASCII
//! host is refused and the server goes on.

use laparo_proto::v1;
use laparo_server::service::{Role, ServeConfig};
use laparo_tests::server::*;
use tonic::codegen::http::HeaderMap;
use tonic::transport::Channel;
use tonic::{Code, Request, Status};

const TEACHER: &str = "instructor-token";

/// A gRPC-web call of `method` with an empty message, as a page at `origin`
/// sends it to `host`.
fn grpc_web(method: &str, host: &str, origin: &str) -> String {
    format!(
        "POST /{method} HTTP/1.1\r\nhost: {host}\r\norigin: {origin}\r\ncontent-type: application/grpc-web+proto\r\nx-grpc-web: 1\r\ncontent-length: 5\r\nconnection: close\r\n\r\n\0\0\0\0\0"
    )
}

const LIST_SCENES: &str = "laparo.v1.Scenes/ListScenes";
const CREATE_SESSION: &str = "laparo.v1.Sessions/CreateSession";

/// The status of an answer whose head holds one (trailers-only), its message
/// percent-decoded (lower-cased, as the helpers read answers).
fn head_status(answer: &str) -> Option<Status> {
    let head = &answer[..answer.find("\r\n\r\n").unwrap_or(answer.len())];
    let mut headers = HeaderMap::new();
    for line in head.lines().skip(1) {
        for name in ["grpc-status", "grpc-message"] {
            if let Some(value) = line.strip_prefix(name).and_then(|v| v.strip_prefix(": ")) {
                headers.insert(name, value.parse().unwrap());
            }
        }
    }
    Status::from_header_map(&headers)
}

/// Asserts that `answer` is the refusal of a host: `PERMISSION_DENIED` in the
/// head, naming `host` and `--allowed-host`, marked as the host check's for the
/// console (`laparo-refusal: host`).
fn assert_refused(answer: &str, host: &str) {
    assert!(answer.starts_with("http/1.1 200"), "{answer}");
    assert!(answer.contains("\r\nlaparo-refusal: host\r\n"), "{answer}");
    let status = head_status(answer).unwrap_or_else(|| panic!("no status: {answer}"));
    assert_eq!(status.code(), Code::PermissionDenied, "{answer}");
    assert!(status.message().contains(host), "{status:?}");
    assert!(status.message().contains("--allowed-host"), "{status:?}");
}

/// Asserts that `answer` is a served `ListScenes`: a message with the default
/// scene, then `grpc-status:0` in the trailers frame.
fn assert_served(answer: &str) {
    assert!(answer.starts_with("http/1.1 200"), "{answer}");
    assert!(head_status(answer).is_none(), "{answer}");
    assert!(answer.contains("default"), "{answer}");
    assert!(answer.contains("grpc-status:0"), "{answer}");
}

async fn open_server(allowed_hosts: &[&str], cors_origins: &[&str]) -> TestServer {
    TestServer::start(ServeConfig {
        allowed_hosts: allowed_hosts.iter().map(|s| s.to_string()).collect(),
        cors_origins: cors_origins.iter().map(|s| s.to_string()).collect(),
        recordings: None,
        ..ServeConfig::default()
    })
    .await
}

async fn sessions(channel: Channel) -> usize {
    v1::sessions_client::SessionsClient::new(channel)
        .list_sessions(v1::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner()
        .sessions
        .len()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rebound_page_is_refused_by_the_host_it_names() {
    let server = open_server(&[], &[]).await;
    let port = server.addr.port();
    let host = format!("attacker.example:{port}");
    let origin = format!("http://{host}");
    let answer = http_exchange(&server, &grpc_web(LIST_SCENES, &host, &origin)).await;
    assert_refused(&answer, "attacker.example");
    assert!(
        answer.contains("content-type: application/grpc-web+proto"),
        "{answer}"
    );
    // Nothing is done: no session is created.
    let answer = http_exchange(&server, &grpc_web(CREATE_SESSION, &host, &origin)).await;
    assert_refused(&answer, "attacker.example");
    assert_eq!(sessions(server.channel().await).await, 0);
    // Case, a trailing dot and another port name the same host.
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, "Attacker.Example.:80", &origin),
    )
    .await;
    assert_refused(&answer, "attacker.example");
    // Any other request a page sends with its Origin, but one that reads: HTTP 403.
    let post = http_exchange(
        &server,
        &format!(
            "POST / HTTP/1.1\r\nhost: {host}\r\norigin: {origin}\r\ncontent-type: text/plain\r\ncontent-length: 2\r\nconnection: close\r\n\r\nhi"
        ),
    )
    .await;
    assert!(post.starts_with("http/1.1 403"), "{post}");
    assert!(
        post.contains("attacker.example") && post.contains("--allowed-host"),
        "{post}"
    );
    // The page's assets are served, with Origin (a module script is fetched so)
    // or without (a navigation): they hold no secret and do nothing.
    for origin in [format!("origin: {origin}\r\n"), String::new()] {
        let page = http_head(
            &server,
            &format!("GET / HTTP/1.1\r\nhost: {host}\r\n{origin}\r\n"),
        )
        .await;
        assert!(page.starts_with("http/1.1 200"), "{origin}: {page}");
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn addresses_and_localhost_are_served() {
    let server = open_server(&[], &[]).await;
    let port = server.addr.port();
    for host in [
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        format!("LOCALHOST.:{port}"),
        format!("console.localhost:{port}"),
        format!("[::1]:{port}"),
        "192.168.1.20".to_string(),
    ] {
        let answer = http_exchange(
            &server,
            &grpc_web(LIST_SCENES, &host, &format!("http://{host}")),
        )
        .await;
        assert_served(&answer);
    }
    // A session made by the console at its own address.
    let host = format!("127.0.0.1:{port}");
    let answer = http_exchange(
        &server,
        &grpc_web(CREATE_SESSION, &host, &format!("http://{host}")),
    )
    .await;
    assert!(answer.contains("grpc-status:0"), "{answer}");
    assert_eq!(sessions(server.channel().await).await, 1);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn allowed_hosts_and_the_hosts_of_cors_origins_are_served() {
    let server = open_server(&["attacker.example"], &["http://console.example:5173"]).await;
    let port = server.addr.port();
    let host = format!("attacker.example:{port}");
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, &host, &format!("http://{host}")),
    )
    .await;
    assert_served(&answer);
    let host = format!("console.example:{port}");
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, &host, "http://console.example:5173"),
    )
    .await;
    assert_served(&answer);
    let host = format!("other.example:{port}");
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, &host, &format!("http://{host}")),
    )
    .await;
    assert_refused(&answer, "other.example");
    // A page of a `--cors-origin` calling the server by a name not allowed is
    // refused with the CORS headers it needs to read why, the mark included.
    let host = format!("elsewhere.example:{port}");
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, &host, "http://console.example:5173"),
    )
    .await;
    assert_refused(&answer, "elsewhere.example");
    assert!(
        answer.contains("\r\naccess-control-allow-origin: http://console.example:5173\r\n"),
        "{answer}"
    );
    let exposed = answer
        .lines()
        .find_map(|l| l.strip_prefix("access-control-expose-headers: "))
        .unwrap_or_else(|| panic!("no exposed headers: {answer}"));
    assert!(exposed.contains("laparo-refusal"), "{exposed}");
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_the_interceptor_answers_not_the_host_check() {
    let server = TestServer::start(ServeConfig {
        tokens: Some(tokens(&[(TEACHER, "teacher", Role::Instructor, None)])),
        recordings: None,
        ..ServeConfig::default()
    })
    .await;
    let host = format!("attacker.example:{}", server.addr.port());
    let origin = format!("http://{host}");
    let answer = http_exchange(&server, &grpc_web(LIST_SCENES, &host, &origin)).await;
    let status = head_status(&answer).unwrap_or_else(|| panic!("no status: {answer}"));
    assert_eq!(status.code(), Code::Unauthenticated, "{answer}");
    // A page with the token (which a rebound page has not) is served.
    let with_token = grpc_web(LIST_SCENES, &host, &origin).replace(
        "x-grpc-web: 1\r\n",
        &format!("x-grpc-web: 1\r\nauthorization: Bearer {TEACHER}\r\n"),
    );
    assert_served(&http_exchange(&server, &with_token).await);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn native_grpc_is_served_whatever_authority_it_names() {
    let server = open_server(&[], &[]).await;
    // HTTP/2 with `:authority: attacker.example:PORT`, as a client given that
    // name sends it.
    let channel = Channel::from_shared(format!("http://{}", server.addr))
        .unwrap()
        .origin(
            format!("http://attacker.example:{}", server.addr.port())
                .parse()
                .unwrap(),
        )
        .connect()
        .await
        .unwrap();
    let mut scenes = v1::scenes_client::ScenesClient::new(channel.clone());
    let listed = scenes
        .list_scenes(v1::ListScenesRequest {})
        .await
        .expect("a native client sends no Origin and is served")
        .into_inner();
    assert!(!listed.scenes.is_empty());
    // The same authority with an Origin (a browser over HTTP/2) is refused.
    let mut request = Request::new(v1::ListScenesRequest {});
    request.metadata_mut().insert(
        "origin",
        format!("http://attacker.example:{}", server.addr.port())
            .parse()
            .unwrap(),
    );
    let refused = scenes.list_scenes(request).await.unwrap_err();
    assert_eq!(refused.code(), Code::PermissionDenied, "{refused:?}");
    assert!(
        refused.message().contains("attacker.example")
            && refused.message().contains("--allowed-host"),
        "{refused:?}"
    );
    // The ordinary channel, too.
    assert_eq!(sessions(server.channel().await).await, 0);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_hosts_are_refused_and_the_server_goes_on() {
    let server = open_server(&[], &[]).await;
    let origin = "http://attacker.example";
    for (host, says) in [
        ("[::1", "not host[:port]"),
        ("exa mple", "not host[:port]"),
        ("attacker.example:http", "not host[:port]"),
        ("", "not host[:port]"),
        ("exämple", "not ascii"),
        ("127.0.0.1\r\nhost: attacker.example", "more than one host"),
    ] {
        let answer = http_exchange(&server, &grpc_web(LIST_SCENES, host, origin)).await;
        assert!(answer.starts_with("http/1.1 200"), "{host:?}: {answer}");
        let status = head_status(&answer).unwrap_or_else(|| panic!("{host:?}: {answer}"));
        assert_eq!(status.code(), Code::PermissionDenied, "{host:?}: {answer}");
        assert!(status.message().contains(says), "{host:?}: {status:?}");
        assert!(status.message().contains("--allowed-host"), "{status:?}");
    }
    // No Host at all.
    let answer = http_exchange(
        &server,
        &grpc_web(LIST_SCENES, "x", origin).replace("host: x\r\n", ""),
    )
    .await;
    let status = head_status(&answer).unwrap_or_else(|| panic!("{answer}"));
    assert_eq!(status.code(), Code::PermissionDenied, "{answer}");
    assert!(status.message().contains("names no host"), "{status:?}");
    assert_eq!(sessions(server.channel().await).await, 0);
    server.shutdown().await.unwrap();
}
