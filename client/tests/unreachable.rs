//! `laparo` against peers that are not a working laparo server: each run ends on its
//! own, with status 1 and a stderr line saying what happened in words (before,
//! a silent listener hung every subcommand for ever, a closed port read as
//! "transport error", an HTTP/1 server as "Cancelled", a bad CA file as "TLS:
//! transport error" without its name). Every run is killed past [`peers::LIMIT`].

mod peers;

use std::time::Duration;

use peers::{closed_port, closing, http1, laparo, silent};

fn url(address: std::net::SocketAddr) -> String {
    format!("http://{address}")
}

#[test]
fn a_silent_listener_is_named_after_the_connect_timeout_by_every_subcommand() {
    let server = url(silent());
    let s = server.as_str();
    let runs: [&[&str]; 5] = [
        &[
            "station",
            "--server",
            s,
            "--session",
            "s1",
            "--connect-timeout",
            "1",
        ],
        &[
            "observe",
            "--server",
            s,
            "--session",
            "s1",
            "--connect-timeout",
            "1",
        ],
        &[
            "replay",
            "some.mcap",
            "--server",
            s,
            "--connect-timeout",
            "1",
        ],
        &[
            "load",
            "--server",
            s,
            "--stations",
            "2",
            "--pose-rate",
            "100",
            "--seconds",
            "30",
            "--connect-timeout",
            "1",
        ],
        &[
            "recordings",
            "list",
            "--server",
            s,
            "--connect-timeout",
            "1",
        ],
    ];
    for args in runs {
        let run = laparo(args);
        run.fails_saying(&[&format!("no answer from {s} within 1 s"), "laparo server"]);
        assert!(
            !run.stdout.contains("| file |"),
            "a table header before any answer: {}",
            run.stdout
        );
    }
}

#[test]
fn the_default_connect_timeout_is_five_seconds() {
    let server = url(silent());
    let run = laparo(&["recordings", "list", "--server", &server]);
    run.fails_saying(&[&format!(
        "no answer from {server} within 5 s: is it a laparo server?"
    )]);
    assert!(run.took >= Duration::from_secs(5), "{:?}", run.took);
}

#[test]
fn seconds_bound_the_whole_run_connecting_included() {
    let server = url(silent());
    for command in ["station", "observe"] {
        let run = laparo(&[
            command,
            "--server",
            &server,
            "--session",
            "s1",
            "--seconds",
            "1",
        ]);
        run.fails_saying(&[&format!("no answer from {server} within 1 s")]);
    }
}

#[test]
fn a_closed_port_is_a_refused_connection() {
    let server = url(closed_port());
    for args in [
        vec!["recordings", "list", "--server", &server],
        vec!["observe", "--server", &server, "--session", "s1"],
        vec!["station", "--server", &server, "--session", "s1"],
    ] {
        laparo(&args).fails_saying(&[&format!("cannot connect to {server}: connection refused")]);
    }
}

#[test]
fn an_http1_server_does_not_speak_grpc() {
    let server = url(http1());
    for args in [
        vec!["recordings", "list", "--server", &server],
        vec!["observe", "--server", &server, "--session", "s1"],
    ] {
        let run = laparo(&args);
        run.fails_saying(&[&format!(
            "{server} does not speak gRPC (it answered HTTP/1.1 200 OK"
        )]);
        assert!(!run.stdout.contains("| file |"), "{}", run.stdout);
    }
}

#[test]
fn an_http1_server_behind_an_https_url_does_not_speak_tls() {
    let address = http1();
    let dir = tempdir("https-http1");
    let ca = dir.join("ca.pem");
    std::fs::write(&ca, CA).unwrap();
    let server = format!("https://{address}");
    let run = laparo(&[
        "recordings",
        "list",
        "--server",
        &server,
        "--ca",
        ca.to_str().unwrap(),
    ]);
    run.fails_saying(&[&format!(
        "{server} does not speak TLS (it answered HTTP/1.1"
    )]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_peer_that_closes_at_once_is_named() {
    let server = url(closing());
    laparo(&["observe", "--server", &server, "--session", "s1"])
        .fails_saying(&[&format!("{server} closed the connection without answering")]);
}

#[test]
fn a_ca_file_that_is_not_pem_is_named() {
    let dir = tempdir("bad-pem");
    let ca = dir.join("CA.pem");
    std::fs::write(&ca, "this is not a certificate\n").unwrap();
    let server = format!("https://{}", closed_port());
    let run = laparo(&[
        "recordings",
        "list",
        "--server",
        &server,
        "--ca",
        ca.to_str().unwrap(),
    ]);
    run.fails_saying(&[&format!("{}: not a PEM certificate", ca.display())]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A fresh directory under the system's temporary directory.
fn tempdir(what: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-{what}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A well-formed PEM certificate block (its contents are never checked: the peer
/// fails before any certificate is looked at).
const CA: &str = "-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n";
