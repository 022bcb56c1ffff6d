//! The browser console in a real browser (Debian's chromium, driven by
//! playwright-core from `web/tests/console.mjs`) against a real server with
//! tokens: the default scene listed; a session created and an instrument driven
//! into the liver (the surface moves, the force gauge reads above zero); a second
//! browser context observing sees the same instrument; the liver drawn
//! (liver-coloured pixels where it is); the session's close said on the
//! observer's page; a replay played to its end; a wrong token refused on the page.
//! The script fails on any uncaught exception or console error of a page.
//!
//! Needs node, chromium and `web/node_modules` (`.ci/run` installs them). Without
//! them the test fails when `CI` is set, and otherwise says it is skipped and passes.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use laparo_server::service::{Caller, Role, ServeConfig, Tokens};
use laparo_tests::server::TestServer;

const TOKEN: &str = "console-instructor-token";
/// The whole browser run: about 50 s on a 2-core machine.
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_console_works_in_a_real_browser() {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("../web");
    if let Some(what) = missing(&web) {
        if std::env::var_os("CI").is_some() {
            panic!(
                "browser tests cannot run: {what}; .ci/run installs chromium and runs npm ci in web/"
            );
        }
        println!("skipped: the console's browser tests: {what}");
        return;
    }
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
    let server = TestServer::start(ServeConfig {
        tokens: Some(tokens),
        recordings: Some(recordings.path().to_path_buf()),
        ..ServeConfig::default()
    })
    .await;
    let url = format!("http://{}/", server.addr);
    let out_dir = out.path().to_path_buf();
    let script = web.join("tests/console.mjs");
    let (status, log) = tokio::task::spawn_blocking(move || {
        let log_path = out_dir.join("browser.log");
        let log = std::fs::File::create(&log_path).unwrap();
        let mut child = Command::new("node")
            .arg(&script)
            .arg(&url)
            .arg(TOKEN)
            .arg(&out_dir)
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
            if start.elapsed() > RUN_LIMIT {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        (
            status,
            std::fs::read_to_string(&log_path).unwrap_or_default(),
        )
    })
    .await
    .unwrap();
    println!("{log}");
    let status =
        status.unwrap_or_else(|| panic!("the browser run took over {RUN_LIMIT:?}:\n{log}"));
    assert!(status.success(), "the browser tests failed:\n{log}");
    assert!(log.contains("browser tests passed"), "{log}");
    server.shutdown().await.unwrap();
}
