//! The connection's checks that need no server: URLs, CA files, and how peers'
//! first bytes and transport failures are put in words.

use std::time::Duration;

use super::failure::{certificate_words, lost, peer_answer};
use super::*;

#[tokio::test]
async fn urls_are_checked_before_connecting() {
    let bad = |url: &'static str| async move {
        let mut c = ConnectConfig::new(url);
        c.connect_timeout = Duration::from_millis(100);
        connect(&c).await.unwrap_err()
    };
    assert!(matches!(
        bad("ftp://127.0.0.1:1").await,
        ConnectError::UnsupportedScheme { .. }
    ));
    assert!(matches!(
        bad("https://127.0.0.1:1").await,
        ConnectError::MissingCa { .. }
    ));
    assert!(matches!(
        bad("not a url").await,
        ConnectError::InvalidUrl { .. }
    ));
    for (url, port) in [
        ("http://127.0.0.1:99999", "99999"),
        ("http://127.0.0.1:0", "0"),
        ("http://localhost:65536/", "65536"),
        ("http://[::1]:70000", "70000"),
    ] {
        let e = bad(url).await;
        assert!(matches!(e, ConnectError::InvalidUrl { .. }), "{e}");
        assert!(
            e.to_string()
                .ends_with(&format!("port {port} is not a TCP port (1 to 65535)")),
            "{e}"
        );
    }
    let mut c = ConnectConfig::new("https://127.0.0.1:1");
    c.ca_file = Some("/nonexistent/ca.pem".into());
    let e = connect(&c).await.unwrap_err();
    assert!(matches!(e, ConnectError::ReadCa { .. }));
    assert!(e.to_string().contains("https://127.0.0.1:1"), "{e}");
}

#[test]
fn a_peer_is_named_by_its_first_bytes() {
    let http1 = b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n";
    assert_eq!(
        peer_answer(http1, false).as_deref(),
        Some("HTTP/1.1 400 Bad Request …")
    );
    assert_eq!(
        peer_answer(http1, true).as_deref(),
        Some("HTTP/1.1 400 Bad Request …")
    );
    let alert = [0x15, 0x03, 0x03, 0x00, 0x02, 0x02, 0x46];
    assert!(peer_answer(&alert, false).unwrap().contains("https"));
    // An HTTP/2 server's first frame: SETTINGS (type 4), empty, stream 0.
    let settings = [0, 0, 0, 4, 0, 0, 0, 0, 0];
    assert_eq!(peer_answer(&settings, false), None);
    assert_eq!(peer_answer(&[], false), None);
    assert!(peer_answer(b"SSH-2.0-OpenSSH_9.6\r\n", false).is_some());
}

#[test]
fn a_status_from_the_server_is_not_a_lost_connection_and_a_reset_is() {
    assert_eq!(lost(&tonic::Status::not_found("no session")), None);
    let reset = std::io::Error::from(std::io::ErrorKind::ConnectionReset);
    let status = tonic::Status::from_error(Box::new(reset));
    let words = lost(&status).expect("a reset is a lost connection");
    assert!(words.contains("closed the connection"), "{words}");
    assert!(!describe_status(&status).contains("Unknown"));
}

#[test]
fn certificate_faults_are_put_in_words_and_other_failures_are_not() {
    let chain = |fault: &str| format!("transport error: invalid peer certificate: {fault}");
    for (fault, words) in [
        (
            "Other(OtherError(CaUsedAsEndEntity))",
            "CA certificate (CA:TRUE)",
        ),
        (
            "UnknownIssuer",
            "not signed by the CA certificate given (--ca)",
        ),
        (
            "NotValidForNameContext { expected: DnsName(\"a\"), presented: [] }",
            "does not name the host",
        ),
        ("ExpiredContext { time: 1, not_after: 0 }", "has expired"),
    ] {
        let said = certificate_words(&chain(fault)).unwrap_or_default();
        assert!(said.contains(words), "{fault}: {said}");
    }
    assert_eq!(certificate_words("transport error: connection reset"), None);
    assert_eq!(certificate_words("UnknownIssuer in a log line"), None);
}
