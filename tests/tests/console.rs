//! The browser console in a real browser (Debian's chromium, driven by
//! playwright-core from `web/tests/console.mjs`) against a real server with
//! tokens: the default scene listed; a session created and an instrument driven
//! into the liver (the surface moves, the force gauge reads above zero); a second
//! browser context observing sees the same instrument; the liver drawn
//! (liver-coloured pixels where it is); the session's close said on the
//! observer's page; the held vertices drawn, live and in a replay; a replay
//! paused (its time stands still), sought (it lands at the time asked) and
//! played to its end, after which a change of speed plays nothing and a seek
//! shows the frame sought and stays paused; a wrong token refused on the page;
//! the server stopped and started again on its port (the page says so and
//! comes back by itself);
//! a gamepad driving an instrument and its vibration growing with the force; an
//! instrument another station holds waited for and taken once let go; a live
//! view left releasing its WebGL context; a page drawing no frames (a hidden
//! tab) keeping its instrument past the station timeout; a reconnect keeping
//! the instrument where it was left; an evicted page staying out; the sessions
//! page keeping an action's error and the keyboard focus across refreshes; a
//! session created with the record box untouched recorded as its scene
//! declares; a station's 250-character client name keeping the sessions table
//! within the window; a station's name kept per tab (a new tab starting with
//! the last one given), and a pose batch in flight over a rejoin under a new
//! name not said as poses not sent; both instruments driven from one page: the
//! 3D view wide in a narrow window, hovering after a missed release not
//! pivoting, shift+wheel as a horizontal scroll inserting the second
//! instrument, the arrow keys and W moving the first, the token entered again
//! keeping the instruments where they were; a malformed address said over the
//! sessions list; a replay playing on through the server's restart;
//! the console over TLS (a self-signed certificate made here), an instrument
//! driven there over HTTP/2. Then, on a server
//! without tokens, a page opened by a name that is not the server's told that its
//! address is refused (`web/tests/host.mjs`).
//! The script fails on any uncaught exception or console error of a page.
//!
//! Needs node, chromium and `web/node_modules` (`.ci/run` installs them). Without
//! them the test fails when `CI` is set, and otherwise says it is skipped and passes.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use laparo_proto::v1;
use laparo_server::service::{Caller, PoseLimits, Role, ServeConfig, TlsFiles, Tokens};
use laparo_server::session::input::stall_burst;
use laparo_tests::server::{StationStream, TestServer, join_raw, open, with_token};

const TOKEN: &str = "console-instructor-token";
/// The whole browser run: about 60 s on a 2-core machine.
const RUN_LIMIT: Duration = Duration::from_secs(240);

fn chromium() -> PathBuf {
    std::env::var_os("LAPARO_CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"))
}

/// What is missing to run the browser tests, if anything.
fn missing(web: &Path) -> Option<String> {
    let node = Command::new("node")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !node.is_ok_and(|s| s.success()) {
        return Some("node is not installed".into());
    }
    if !chromium().exists() {
        return Some(format!("{} is not installed", chromium().display()));
    }
    if !web.join("node_modules/playwright-core").exists() {
        return Some("web/node_modules is missing (npm --prefix web ci)".into());
    }
    None
}

/// The console's folder, if the browser tests can run: without what they need,
/// `None` after saying so, or a failure when `CI` is set.
fn web_or_skip() -> Option<PathBuf> {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("../web");
    let Some(what) = missing(&web) else {
        return Some(web);
    };
    if std::env::var_os("CI").is_some() {
        panic!(
            "browser tests cannot run: {what}; .ci/run installs chromium and the packages of web/"
        );
    }
    println!("skipped: the console's browser tests: {what}");
    None
}

/// Runs `node script args…` (its output in `out/SCRIPT.log`), calling `between`
/// every 100 ms while it runs, and gives its output; fails the test when it
/// fails or runs longer than `limit`.
async fn run_script(
    script: &Path,
    args: &[String],
    out: &Path,
    limit: Duration,
    mut between: impl AsyncFnMut(),
) -> String {
    let name = script.file_stem().unwrap().to_string_lossy();
    let log_path = out.join(format!("{name}.log"));
    let log = std::fs::File::create(&log_path).unwrap();
    let mut child = Command::new("node")
        .arg(script)
        .args(args)
        .stdin(Stdio::null())
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .spawn()
        .expect("node starts");
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        between().await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let log = std::fs::read_to_string(&log_path).unwrap_or_default();
    println!("{log}");
    let status = status.unwrap_or_else(|| panic!("{name}.mjs took over {limit:?}:\n{log}"));
    assert!(status.success(), "{name}.mjs failed:\n{log}");
    log
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_console_works_in_a_real_browser() {
    let Some(web) = web_or_skip() else {
        return;
    };
    let mut tokens = Tokens::default();
    tokens.insert(
        TOKEN,
        Caller {
            name: "instructor".into(),
            role: Role::Instructor,
            instruments: None,
        },
    );
    let recordings = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let config = ServeConfig {
        tokens: Some(tokens.clone()),
        recordings: Some(recordings.path().to_path_buf()),
        ..ServeConfig::default()
    };
    let mut server = Some(TestServer::start(config.clone()).await);
    let addr = server.as_ref().unwrap().addr;
    // The same server over TLS, with a self-signed certificate made here.
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    std::fs::write(out.path().join("cert.pem"), cert.cert.pem()).unwrap();
    std::fs::write(out.path().join("key.pem"), cert.signing_key.serialize_pem()).unwrap();
    let tls = TestServer::start(ServeConfig {
        tls: Some(TlsFiles {
            cert: out.path().join("cert.pem"),
            key: out.path().join("key.pem"),
        }),
        recordings: None,
        // Lower than the page's 250 Hz: the page must sample at this instead.
        pose_limits: PoseLimits {
            rate_hz: 100.0,
            burst: stall_burst(100.0),
        },
        ..config.clone()
    })
    .await;
    let out_dir = out.path().to_path_buf();
    let args = [
        format!("http://{addr}/"),
        TOKEN.to_string(),
        out_dir.display().to_string(),
        format!("https://localhost:{}/", tls.addr.port()),
        recordings.path().display().to_string(),
    ];
    // The script asks for the server to be stopped (a file `stop` in OUT_DIR;
    // answered with `stopped`) and started again on its port (`start`, answered
    // with `started`), to see the page lose and regain it; and for a station
    // whose client name is 250 characters without a space (`station`, answered
    // with `station-joined` holding the id of the session it joined, one of its
    // own), for the sessions table's layout: kept by a heartbeat at each call.
    let mut long_named: Option<StationStream> = None;
    let log = run_script(
        &web.join("tests/console.mjs"),
        &args,
        &out_dir,
        RUN_LIMIT,
        async || {
            if out_dir.join("stop").exists() && !out_dir.join("stopped").exists() {
                long_named = None;
                server.take().unwrap().shutdown().await.unwrap();
                std::fs::write(out_dir.join("stopped"), "").unwrap();
            }
            if out_dir.join("start").exists() && !out_dir.join("started").exists() {
                server = Some(TestServer::start_at(addr, config.clone()).await);
                std::fs::write(out_dir.join("started"), "").unwrap();
            }
            if out_dir.join("station").exists() && !out_dir.join("station-joined").exists() {
                let (station, session) = join_long_named(server.as_ref().unwrap()).await;
                long_named = Some(station);
                // Written whole, then renamed: the script reads it once it is there.
                std::fs::write(out_dir.join("station-joining"), session).unwrap();
                std::fs::rename(
                    out_dir.join("station-joining"),
                    out_dir.join("station-joined"),
                )
                .unwrap();
            }
            if let Some(station) = &long_named {
                // Gone with its session (the script closes it): dropped.
                if station.tx.try_send(heartbeat()).is_err() && station.tx.is_closed() {
                    long_named = None;
                }
            }
        },
    )
    .await;
    assert!(log.contains("browser tests passed"), "{log}");
    if let Some(server) = server {
        server.shutdown().await.unwrap();
    }
    tls.shutdown().await.unwrap();
}

/// Creates an unrecorded session of the default scene on `server` and joins it
/// as a station named by 250 characters without a space, watching; returns the
/// station's stream and the session's id.
async fn join_long_named(server: &TestServer) -> (StationStream, String) {
    let channel = server.channel().await;
    let session = v1::sessions_client::SessionsClient::new(channel.clone())
        .create_session(with_token(
            v1::CreateSessionRequest {
                scene: "default".into(),
                idle_timeout_s: None,
                record: Some(false),
            },
            Some(TOKEN),
        ))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let mut first = open(&session, &[]);
    if let Some(v1::station_message::Kind::Open(o)) = &mut first.kind {
        o.client_name = "n".repeat(250);
    }
    let mut station = join_raw(channel, Some(TOKEN), Some(first)).await.unwrap();
    let joined = station.rx.message().await.unwrap();
    assert!(
        matches!(
            &joined,
            Some(v1::ServerMessage {
                kind: Some(v1::server_message::Kind::Joined(_))
            })
        ),
        "{joined:?}"
    );
    (station, session)
}

fn heartbeat() -> v1::StationMessage {
    v1::StationMessage {
        kind: Some(v1::station_message::Kind::Heartbeat(v1::Heartbeat {})),
    }
}

/// The console on a server without tokens opened by a name that resolves to it
/// but that the server does not know (`web/tests/host.mjs`): the page says its
/// address is refused and names `--allowed-host`, without asking for a token;
/// opened by the server's address, as localhost or by a name under .localhost,
/// it lists the scenes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_page_opened_by_a_name_the_server_does_not_know_is_told_so() {
    let Some(web) = web_or_skip() else {
        return;
    };
    let server = TestServer::start(ServeConfig::default()).await;
    let out = tempfile::tempdir().unwrap();
    let args = [
        server.addr.port().to_string(),
        out.path().display().to_string(),
    ];
    let script = web.join("tests/host.mjs");
    let log = run_script(&script, &args, out.path(), HOST_RUN_LIMIT, async || {}).await;
    assert!(log.contains("host tests passed"), "{log}");
    server.shutdown().await.unwrap();
}

/// The host check's browser run: a browser started and two pages loaded, about
/// 10 s on a 2-core machine.
const HOST_RUN_LIMIT: Duration = Duration::from_secs(120);
