//! The server as a service: roles, health and reflection for generic clients,
//! shutdown with streams open, and what a public address needs (TLS and tokens).

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::{Caller, Role, ServeConfig, ServeError, Tokens};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn roles_decide_who_may_do_what() {
    let tokens = tokens(&[
        ("instructor-token", "instructor", Role::Instructor, None),
        (
            "trainee-left-token",
            "trainee",
            Role::Trainee,
            Some(&["left"]),
        ),
    ]);
    let server = TestServer::start(ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    let (teacher, trainee) = (Some("instructor-token"), Some("trainee-left-token"));
    let code = |r: Result<v1::SessionInfo, tonic::Status>| r.err().map(|s| s.code());
    assert_eq!(
        code(create_session(ch.clone(), None).await),
        Some(Code::Unauthenticated)
    );
    assert_eq!(
        code(create_session(ch.clone(), Some("wrong-token")).await),
        Some(Code::Unauthenticated)
    );
    assert_eq!(
        code(create_session(ch.clone(), trainee).await),
        Some(Code::PermissionDenied)
    );
    let session = create_session(ch.clone(), teacher)
        .await
        .unwrap()
        .session_id;
    // The trainee may claim its own instrument, not another's, and may not observe.
    let claim = join(ch.clone(), trainee, &session, &["right"]).await;
    assert_eq!(claim.err().map(|s| s.code()), Some(Code::PermissionDenied));
    let observe = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(with_token(
            v1::ObserveRequest {
                session_id: session.clone(),
                frame_rate_hz: None,
            },
            trainee,
        ))
        .await;
    assert_eq!(
        observe.err().map(|s| s.code()),
        Some(Code::PermissionDenied)
    );
    let (_station, joined) = join(ch.clone(), trainee, &session, &["left"])
        .await
        .unwrap();
    assert_eq!(joined.instruments, vec!["left".to_string()]);
    // The instructor observes.
    let observe = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(with_token(
            v1::ObserveRequest {
                session_id: session.clone(),
                frame_rate_hz: None,
            },
            teacher,
        ))
        .await;
    assert!(observe.is_ok());
    drop(observe);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_and_reflection_answer_generic_clients() {
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::{HealthCheckRequest, health_client::HealthClient};
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    for service in ["laparo.v1.Station", "laparo.v1.Sessions"] {
        let status = HealthClient::new(ch.clone())
            .check(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner()
            .status;
        assert_eq!(status, ServingStatus::Serving as i32, "{service}");
    }
    use tonic_reflection::pb::v1::ServerReflectionRequest;
    use tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient;
    use tonic_reflection::pb::v1::server_reflection_request::MessageRequest;
    use tonic_reflection::pb::v1::server_reflection_response::MessageResponse;
    let request = ServerReflectionRequest {
        host: String::new(),
        message_request: Some(MessageRequest::ListServices(String::new())),
    };
    let mut replies = ServerReflectionClient::new(ch.clone())
        .server_reflection_info(tokio_stream::iter([request]))
        .await
        .unwrap()
        .into_inner();
    let reply = replies.message().await.unwrap().unwrap();
    let Some(MessageResponse::ListServicesResponse(list)) = reply.message_response else {
        panic!("{reply:?}");
    };
    let names: Vec<_> = list.service.iter().map(|s| s.name.as_str()).collect();
    for s in [
        "laparo.v1.Station",
        "laparo.v1.Observe",
        "laparo.v1.Sessions",
        "laparo.v1.Scenes",
    ] {
        assert!(names.contains(&s), "{names:?}");
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_ends_open_streams_with_a_status() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut a, _) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let mut observer = v1::observe_client::ObserveClient::new(ch.clone())
        .observe(v1::ObserveRequest {
            session_id: session.clone(),
            frame_rate_hz: None,
        })
        .await
        .unwrap()
        .into_inner();
    // Streams are live.
    assert!(
        wait_for(&mut a.rx, WAIT, |m| matches!(
            m.kind,
            Some(Kind::SurfaceFrame(_))
        ))
        .await
        .is_some()
    );
    let shutdown = tokio::spawn(server.shutdown());
    let status = tokio::time::timeout(WAIT, async {
        loop {
            match a.rx.message().await {
                Err(s) => return Some(s),
                Ok(None) => return None,
                Ok(Some(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    let status = status.expect("the station's stream ends with a status");
    assert_eq!(status.code(), Code::Unavailable, "{status:?}");
    assert!(status.message().contains("shutting down"), "{status:?}");
    let observed = tokio::time::timeout(WAIT, async {
        loop {
            match observer.message().await {
                Err(s) => return Some(s.code()),
                Ok(None) => return None,
                Ok(Some(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    assert_eq!(observed, Some(Code::Unavailable));
    shutdown.await.unwrap().unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_public_address_needs_tls_and_tokens_or_insecure() {
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let refused = laparo_server::service::serve(ServeConfig::default(), listener, async {}).await;
    assert!(
        matches!(refused, Err(ServeError::Insecure(_))),
        "{refused:?}"
    );
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let allowed = laparo_server::service::serve(
        ServeConfig {
            insecure: true,
            ..ServeConfig::default()
        },
        listener,
        async {},
    )
    .await;
    assert!(allowed.is_ok(), "{allowed:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_with_tokens_serves_a_public_address() {
    use tonic::transport::{Certificate, ClientTlsConfig};
    let dir = std::env::temp_dir().join(format!("laparo-tls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let (cert_pem, key_pem) = (cert.cert.pem(), cert.signing_key.serialize_pem());
    std::fs::write(dir.join("cert.pem"), &cert_pem).unwrap();
    std::fs::write(dir.join("key.pem"), &key_pem).unwrap();
    let mut tokens = Tokens::default();
    tokens.insert("instructor-token", Caller::open());
    // Not loopback, yet allowed: TLS and tokens.
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let config = ServeConfig {
        tokens: Some(tokens),
        tls: Some(laparo_server::service::TlsFiles {
            cert: dir.join("cert.pem"),
            key: dir.join("key.pem"),
        }),
        ..ServeConfig::default()
    };
    let server = tokio::spawn(laparo_server::service::serve(config, listener, async {
        let _ = stopped.await;
    }));
    let tls = ClientTlsConfig::new()
        .ca_certificate(Certificate::from_pem(&cert_pem))
        .domain_name("localhost");
    let ch = Channel::from_shared(format!("https://127.0.0.1:{port}"))
        .unwrap()
        .tls_config(tls)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let info = create_session(ch.clone(), Some("instructor-token"))
        .await
        .unwrap();
    assert!(!info.session_id.is_empty());
    // Plain text to a TLS port gets nowhere.
    let plain = Channel::from_shared(format!("http://127.0.0.1:{port}"))
        .unwrap()
        .connect()
        .await;
    if let Ok(plain) = plain {
        assert!(
            create_session(plain, Some("instructor-token"))
                .await
                .is_err()
        );
    }
    let _ = stop.send(());
    server.await.unwrap().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_files_that_cannot_serve_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let pair = |name: &str| {
        let cert = rcgen::generate_simple_self_signed(vec![name.to_string()]).unwrap();
        let (c, k) = (
            dir.path().join(format!("{name}.crt")),
            dir.path().join(format!("{name}.key")),
        );
        std::fs::write(&c, cert.cert.pem()).unwrap();
        std::fs::write(&k, cert.signing_key.serialize_pem()).unwrap();
        (c, k)
    };
    let (a_cert, a_key) = pair("a.example");
    let (_, b_key) = pair("b.example");
    let serve = |cert: &std::path::Path, key: &std::path::Path| {
        let config = ServeConfig {
            tls: Some(laparo_server::service::TlsFiles {
                cert: cert.to_path_buf(),
                key: key.to_path_buf(),
            }),
            ..ServeConfig::default()
        };
        async move {
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            laparo_server::service::serve(config, listener, async {})
                .await
                .unwrap_err()
                .to_string()
        }
    };
    // A device is not read (it would never end), and says what it is.
    let zero = std::path::Path::new("/dev/zero");
    let e = serve(zero, &a_key).await;
    assert!(
        e.contains("/dev/zero is a character device, not a regular file"),
        "{e}"
    );
    // A certificate with another's key says why, not just "transport error".
    let e = serve(&a_cert, &b_key).await;
    assert!(e.contains(&*b_key.display().to_string()), "{e}");
    assert!(e.contains("its own key"), "{e}");
    // A file that is not what its option takes is named with what it lacks, not
    // as "transport error: peer sent no certificates".
    let empty = dir.path().join("empty.pem");
    std::fs::write(&empty, b"").unwrap();
    for (cert, key, named, lacks) in [
        (&a_key, &a_cert, &a_key, "--tls-cert"),
        (&empty, &a_key, &empty, "--tls-cert"),
        (&a_cert, &empty, &empty, "--tls-key"),
        (&a_cert, &a_cert, &a_cert, "--tls-key"),
    ] {
        let e = serve(cert, key).await;
        let what = match lacks {
            "--tls-cert" => "is not a PEM certificate",
            _ => "is not a PEM private key",
        };
        assert!(
            e.contains(&format!("{lacks} {} {what}", named.display())),
            "{e}"
        );
        assert!(!e.contains("transport error"), "{e}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_refused_a_ca_certificate_as_the_servers_own_says_so_in_words() {
    use laparo_client::connect::{ConnectConfig, connect};
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: String| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    // A self-signed CA certificate (CA:TRUE) served as the server's own.
    let key = rcgen::KeyPair::generate().unwrap();
    let names = vec!["localhost".to_string(), "127.0.0.1".to_string()];
    let mut params = rcgen::CertificateParams::new(names).unwrap();
    params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    let ca = params.self_signed(&key).unwrap();
    let (cert, key) = (
        write("ca.crt", ca.pem()),
        write("ca.key", key.serialize_pem()),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let config = ServeConfig {
        tls: Some(laparo_server::service::TlsFiles {
            cert: cert.clone(),
            key,
        }),
        ..ServeConfig::default()
    };
    let server = tokio::spawn(laparo_server::service::serve(config, listener, async {
        let _ = stopped.await;
    }));
    let config = ConnectConfig {
        ca_file: Some(cert.clone()),
        ..ConnectConfig::new(format!("https://127.0.0.1:{port}"))
    };
    let Err(e) = connect(&config).await else {
        panic!("connected to a server whose certificate is a CA");
    };
    let e = e.to_string();
    assert!(
        e.contains("presents a CA certificate (CA:TRUE) as its own"),
        "{e}"
    );
    let _ = stop.send(());
    server.await.unwrap().unwrap();
}
