use super::*;

fn name(n: &str) -> Option<Host> {
    Some(Host::Name(n.to_string()))
}

fn ip(a: &str) -> Option<Host> {
    Some(Host::Ip(a.parse().unwrap()))
}

#[test]
fn hosts_are_read_without_port_case_or_trailing_dot() {
    for (text, host) in [
        ("127.0.0.1", ip("127.0.0.1")),
        ("127.0.0.1:50051", ip("127.0.0.1")),
        ("127.0.0.1.:50051", ip("127.0.0.1")),
        ("10.1.2.3:", ip("10.1.2.3")),
        ("[::1]", ip("::1")),
        ("[::1]:50051", ip("::1")),
        ("[fe80::1:2]:8080", ip("fe80::1:2")),
        ("[::ffff:127.0.0.1]:1", ip("::ffff:127.0.0.1")),
        ("localhost", name("localhost")),
        ("LocalHost.:50051", name("localhost")),
        ("Attacker.EXAMPLE:50051", name("attacker.example")),
        ("attacker.example.", name("attacker.example")),
        ("console.localhost", name("console.localhost")),
        ("my_host-1", name("my_host-1")),
        // Not an address (leading zeros, too few parts): a name.
        ("127.000.000.001", name("127.000.000.001")),
        ("127.1", name("127.1")),
    ] {
        assert_eq!(parse_host(text), host, "{text}");
    }
}

#[test]
fn what_is_not_host_and_port_is_none() {
    let label = "a".repeat(64);
    let name = ["a".repeat(63).as_str(); 4].join(".");
    assert_eq!(name.len(), 255);
    for bad in [label.as_str(), name.as_str()] {
        assert_eq!(parse_host(bad), None, "{} characters", bad.len());
    }
    let longest = format!(
        "{}.{}",
        ["a".repeat(63).as_str(); 3].join("."),
        "a".repeat(61)
    );
    assert_eq!(longest.len(), MAX_NAME);
    assert!(parse_host(&longest).is_some());
    for bad in [
        "",
        ":50051",
        ".",
        "..",
        ".example",
        "a..example",
        "::1",
        "[::1",
        "[::1]x",
        "[::1]:x",
        "[::1]:123456",
        "[127.0.0.1]",
        "[fe80::1%25eth0]",
        "[]",
        "example:port",
        "example:123456",
        "example:80:80",
        "exa mple",
        "user@example",
        "example/path",
        "*",
    ] {
        assert_eq!(parse_host(bad), None, "{bad:?}");
    }
}

#[test]
fn allowed_are_addresses_localhost_and_the_names_given() {
    let allowed = AllowedHosts::new(
        &["LAPARO.lan.".to_string()],
        &[
            "http://console.example:5173".to_string(),
            "https://[::1]:8443".to_string(),
        ],
    )
    .unwrap();
    for good in [
        "127.0.0.1",
        "192.168.1.20",
        "[::1]",
        "[2001:db8::1]",
        "localhost",
        "station.localhost",
        "laparo.lan",
        "console.example",
    ] {
        assert!(allowed.allows(&parse_host(good).unwrap()), "{good}");
    }
    for bad in [
        "attacker.example",
        "notlocalhost",
        "localhost.example",
        "laparo.lan.example",
        "lan",
        "127.0.0.1.nip.io",
    ] {
        assert!(!allowed.allows(&parse_host(bad).unwrap()), "{bad}");
    }
    assert!(!AllowedHosts::default().allows(&parse_host("laparo.lan").unwrap()));
}

#[test]
fn allowed_host_arguments_are_names_without_port() {
    for (arg, normal) in [
        ("laparo.lan", "laparo.lan"),
        ("Laparo.LAN.", "laparo.lan"),
        ("10.0.0.1", "10.0.0.1"),
    ] {
        assert_eq!(parse_allowed_host(arg).unwrap(), normal, "{arg}");
    }
    for bad in [
        "",
        "*",
        "*.example",
        "laparo.lan:50051",
        "http://laparo.lan",
        "[::1]",
        "a b",
    ] {
        let e = parse_allowed_host(bad).unwrap_err();
        assert!(e.to_string().contains("--allowed-host"), "{bad}: {e}");
    }
    // A name with letters beyond ASCII is taken in the form browsers send it.
    let e = parse_allowed_host("bücher.example").unwrap_err();
    assert!(e.to_string().contains("xn--"), "{e}");
    assert_eq!(
        parse_allowed_host("xn--bcher-kva.example").unwrap(),
        "xn--bcher-kva.example"
    );
    assert!(AllowedHosts::new(&["x:1".to_string()], &[]).is_err());
}

fn request(headers: &[(&str, &[u8])], uri: &str) -> Request<()> {
    let mut r = Request::builder().method("POST").uri(uri);
    for (n, v) in headers {
        r = r.header(*n, HeaderValue::from_bytes(v).unwrap());
    }
    r.body(()).unwrap()
}

const ORIGIN: (&str, &[u8]) = ("origin", b"http://attacker.example:50051");

#[test]
fn browser_requests_are_checked_by_every_host_they_name() {
    let allowed = AllowedHosts::default();
    let path = "/laparo.v1.Scenes/ListScenes";
    let check = |headers: &[(&str, &[u8])], uri: &str| allowed.refusal(&request(headers, uri));
    // Without Origin (native gRPC, a navigation): nothing is checked.
    assert_eq!(check(&[("host", b"attacker.example:50051")], path), None);
    assert_eq!(check(&[], path), None);
    // Nor what reads the page's assets, with Origin or not; but a call sent as a
    // read (tonic serves it whatever the method) is checked.
    for method in ["GET", "HEAD"] {
        let mut read = request(&[ORIGIN, ("host", b"attacker.example:50051")], "/");
        *read.method_mut() = method.parse().unwrap();
        assert_eq!(allowed.refusal(&read), None, "{method}");
        for grpc in [&b"application/grpc"[..], b"application/grpc-web+proto"] {
            let mut call = request(
                &[
                    ORIGIN,
                    ("host", b"attacker.example:50051"),
                    ("content-type", grpc),
                ],
                path,
            );
            *call.method_mut() = method.parse().unwrap();
            assert_eq!(
                allowed.refusal(&call),
                Some(Refusal::NotAllowed("attacker.example".into())),
                "{method}"
            );
        }
    }
    // HTTP/1.1: the Host header.
    assert_eq!(
        check(&[ORIGIN, ("host", b"attacker.example:50051")], path),
        Some(Refusal::NotAllowed("attacker.example".into()))
    );
    assert_eq!(check(&[ORIGIN, ("host", b"127.0.0.1:50051")], path), None);
    assert_eq!(check(&[ORIGIN, ("host", b"localhost:50051")], path), None);
    // HTTP/2 (and an absolute-form target): the authority, and a Host too.
    let h2 = "http://attacker.example:50051/laparo.v1.Scenes/ListScenes";
    assert_eq!(
        check(&[ORIGIN], h2),
        Some(Refusal::NotAllowed("attacker.example".into()))
    );
    assert_eq!(check(&[ORIGIN], "http://[::1]:50051/x"), None);
    assert_eq!(
        check(&[ORIGIN, ("host", b"127.0.0.1")], h2),
        Some(Refusal::NotAllowed("attacker.example".into()))
    );
    assert_eq!(
        check(
            &[ORIGIN, ("host", b"attacker.example")],
            "http://127.0.0.1/x"
        ),
        Some(Refusal::NotAllowed("attacker.example".into()))
    );
    // None, two, malformed, not ASCII.
    assert_eq!(check(&[ORIGIN], path), Some(Refusal::NoHost));
    assert_eq!(
        check(
            &[
                ORIGIN,
                ("host", b"127.0.0.1"),
                ("host", b"attacker.example")
            ],
            path
        ),
        Some(Refusal::ManyHosts)
    );
    assert_eq!(
        check(&[ORIGIN, ("host", b"[::1")], path),
        Some(Refusal::Malformed("[::1".into()))
    );
    assert_eq!(
        check(&[ORIGIN, ("host", b"")], path),
        Some(Refusal::Malformed(String::new()))
    );
    assert_eq!(
        check(&[ORIGIN, ("host", b"\xffexample")], path),
        Some(Refusal::NotAscii)
    );
    assert_eq!(
        check(&[ORIGIN, ("host", b"exa mple")], path),
        Some(Refusal::Malformed("exa mple".into()))
    );
    let long = "x".repeat(300);
    let Some(Refusal::Malformed(echo)) =
        check(&[ORIGIN, ("host", format!("{long}:1:2").as_bytes())], path)
    else {
        panic!("a long malformed host is refused");
    };
    assert_eq!(echo.chars().count(), ECHOED_CHARS + 1);
    // A name no DNS can hold is malformed, and so cut: a 100,000-letter Host was
    // echoed whole, twice, as a name not allowed.
    let huge = "x".repeat(100_000);
    let Some(Refusal::Malformed(echo)) = check(&[ORIGIN, ("host", huge.as_bytes())], path) else {
        panic!("an overlong name is refused as malformed");
    };
    assert_eq!(echo.chars().count(), ECHOED_CHARS + 1);
}

#[test]
fn refusals_name_the_host_and_the_flag() {
    let message = Refusal::NotAllowed("attacker.example".into()).to_string();
    assert!(message.contains("`attacker.example`"), "{message}");
    assert!(
        message.contains("--allowed-host attacker.example"),
        "{message}"
    );
    assert!(message.contains("DNS rebinding"), "{message}");
    for other in [
        Refusal::Malformed("[::1".into()),
        Refusal::NotAscii,
        Refusal::NoHost,
        Refusal::ManyHosts,
    ] {
        assert!(other.to_string().contains("--allowed-host"), "{other}");
    }
}

#[test]
fn grpc_calls_are_refused_with_a_status_and_others_with_403() {
    let message = Refusal::NotAllowed("attacker.example".into()).to_string();
    let mut call = HeaderMap::new();
    call.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/grpc-web+proto"),
    );
    let response = refused(&call, &message);
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(
        response.headers()[header::CONTENT_TYPE],
        "application/grpc-web+proto"
    );
    let status = Status::from_header_map(response.headers()).unwrap();
    assert_eq!(status.code(), Code::PermissionDenied);
    assert_eq!(status.message(), message);
    assert_eq!(response.headers()[REFUSAL_HEADER], "host");
    let page = refused(&HeaderMap::new(), &message);
    assert_eq!(page.status(), StatusCode::FORBIDDEN);
    assert!(page.headers().get("grpc-status").is_none());
    assert_eq!(page.headers()[REFUSAL_HEADER], "host");
}
