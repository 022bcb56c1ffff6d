//! `laparo sessions create|list|info|close|evict` against a real server on
//! loopback: on a fresh server the README's station example works once a session
//! is created; an instructor evicts a station and closes the session; refusals are
//! said in words.

mod peers;

use std::time::{Duration, Instant};

use laparo_server::service::{Caller, Role, ServeConfig, Tokens, serve};
use peers::{Run, finish, laparo, start_laparo};

const TEACHER: &str = "instructor-token";
const TRAINEE: &str = "trainee-token";

/// A server with an instructor and a trainee token, on a runtime of its own for the
/// life of the test process.
fn start_server() -> String {
    let mut tokens = Tokens::default();
    for (token, name, role) in [
        (TEACHER, "Dr Ayache", Role::Instructor),
        (TRAINEE, "trainee", Role::Trainee),
    ] {
        tokens.insert(
            token,
            Caller {
                name: name.into(),
                role,
                instruments: None,
            },
        );
    }
    let config = ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    };
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Runtime::new().unwrap();
        runtime.block_on(async move {
            let listener = tokio::net::TcpListener::from_std(listener).unwrap();
            serve(config, listener, std::future::pending())
                .await
                .unwrap();
        });
    });
    url
}

/// `laparo sessions <args> --server <url> --token <token>`.
fn sessions(url: &str, token: &str, args: &[&str]) -> Run {
    let mut all = vec!["sessions"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--server", url, "--token", token]);
    laparo(&all)
}

fn succeeds(run: &Run) -> &str {
    assert_eq!(
        run.code,
        Some(0),
        "stdout: {}\nstderr: {}",
        run.stdout,
        run.stderr
    );
    &run.stdout
}

#[test]
fn an_instructor_creates_lists_describes_evicts_and_closes() {
    let url = start_server();
    // A fresh server has no session.
    let listed = sessions(&url, TRAINEE, &["list"]);
    assert_eq!(succeeds(&listed).lines().count(), 2, "{}", listed.stdout);
    // A trainee may not create one.
    sessions(&url, TRAINEE, &["create"]).fails_saying(&["permission denied", "instructor"]);
    let created = sessions(&url, TEACHER, &["create", "--no-record"]);
    let out = succeeds(&created);
    assert!(out.starts_with("created session s1\n"), "{out}");
    assert!(out.contains("scene              default"), "{out}");
    assert!(out.contains("recording          not recorded"), "{out}");

    // The README's station example now works.
    let station = laparo(&[
        "station",
        "--server",
        &url,
        "--token",
        TRAINEE,
        "--session",
        "s1",
        "--seconds",
        "1",
    ]);
    succeeds(&station);

    // A station that stays, until it is evicted.
    let start = Instant::now();
    let staying = start_laparo(&[
        "station",
        "--server",
        &url,
        "--token",
        TRAINEE,
        "--session",
        "s1",
        "--seconds",
        "60",
    ]);
    let deadline = Instant::now() + Duration::from_secs(30);
    let info = loop {
        let info = sessions(&url, TRAINEE, &["info", "s1"]);
        if succeeds(&info).contains("holds left") {
            break info;
        }
        assert!(Instant::now() < deadline, "the station never joined");
        std::thread::sleep(Duration::from_millis(100));
    };
    let id = info
        .stdout
        .lines()
        .find_map(|l| l.trim().strip_prefix("station ")?.split(' ').next())
        .and_then(|id| id.parse::<u64>().ok())
        .unwrap_or_else(|| panic!("no station line in {}", info.stdout));
    assert!(
        info.stdout.contains(&format!("left: station {id}")),
        "{}",
        info.stdout
    );
    assert!(info.stdout.contains("missed deadlines"), "{}", info.stdout);

    let id_text = id.to_string();
    sessions(&url, TRAINEE, &["evict", "s1", &id_text]).fails_saying(&["permission denied"]);
    let evicted = sessions(
        &url,
        TEACHER,
        &["evict", "s1", &id_text, "--reason", "hands off"],
    );
    assert!(
        succeeds(&evicted).contains(&format!("evicted station {id} (trainee")),
        "{}",
        evicted.stdout
    );
    let ended = finish(staying, start);
    ended.fails_saying(&["evicted", "Dr Ayache", "hands off"]);
    let info = sessions(&url, TRAINEE, &["info", "s1"]);
    assert!(succeeds(&info).contains("left: free"), "{}", info.stdout);

    let listed = sessions(&url, TRAINEE, &["list"]);
    assert!(
        succeeds(&listed)
            .lines()
            .any(|l| l.starts_with("| s1 | default |")),
        "{}",
        listed.stdout
    );
    sessions(&url, TRAINEE, &["close", "s1"]).fails_saying(&["permission denied"]);
    let closed = sessions(&url, TEACHER, &["close", "s1", "--reason", "end of class"]);
    assert!(
        succeeds(&closed).starts_with("closed session s1 at tick"),
        "{}",
        closed.stdout
    );
    sessions(&url, TRAINEE, &["info", "s1"]).fails_saying(&["session s1", "not found"]);
    sessions(&url, TEACHER, &["evict", "s1", "1"]).fails_saying(&["not found"]);
}
