//! `laparo … | head -1`: when the reader of standard output closes the pipe, the
//! client ends quietly, with status 0 and nothing on stderr (it panicked with
//! "failed printing to stdout" before).
//!
//! The listing printed here is several times a pipe's buffer (64 KiB on Linux), so
//! the client is still writing when the pipe closes, however the two processes are
//! scheduled. Every wait is bounded: a client still running after [`LIMIT`] is
//! killed and the test fails.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// How long a client may take to end after its pipe closed.
const LIMIT: Duration = Duration::from_secs(60);
/// A Linux pipe's default buffer, bytes.
const PIPE_BUFFER: usize = 64 * 1024;
/// Names of the listed copies of the recording: long, so that the rows are.
const NAME_LENGTH: usize = 200;
/// Copies listed.
const COPIES: usize = 1000;

fn laparo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_laparo"))
}

/// Waits for `child` up to [`LIMIT`]; kills it and fails past that.
fn wait_bounded(child: &mut Child) -> ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("the client can be waited for") {
            return status;
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the client was still running {LIMIT:?} after its pipe closed");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `command` with its output piped, reads the first line of it and closes the
/// pipe; returns that line, how the client ended and what it wrote on stderr.
fn read_one_line_then_close(command: &mut Command) -> (String, ExitStatus, String) {
    let mut client = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("laparo runs");
    let mut stdout = BufReader::new(client.stdout.take().unwrap());
    let mut first = String::new();
    stdout.read_line(&mut first).unwrap();
    drop(stdout);
    let status = wait_bounded(&mut client);
    let mut stderr = String::new();
    client
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    (first, status, stderr)
}

/// A recording made by `laparo demo` in `dir`.
fn record(dir: &Path) -> PathBuf {
    let out = laparo()
        .args(["demo", "--seconds", "1", "--recordings"])
        .arg(dir)
        .output()
        .expect("laparo runs");
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_dir(dir)
        .expect("the demo made its recordings directory")
        .map(|e| e.expect("a directory entry").path())
        .find(|p| p.extension().is_some_and(|x| x == "mcap"))
        .expect("the demo recorded its session")
}

#[test]
fn a_listing_piped_into_a_reader_that_stops_after_one_line_ends_quietly() {
    let root = std::env::temp_dir().join(format!("laparo-closed-pipe-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let recording = record(&root.join("made"));
    let listed = root.join("listed");
    std::fs::create_dir_all(&listed).unwrap();
    for i in 0..COPIES {
        let name = format!("{i:04}-{}.mcap", "r".repeat(NAME_LENGTH));
        let copy = listed.join(name);
        if std::fs::hard_link(&recording, &copy).is_err() {
            std::fs::copy(&recording, &copy).unwrap();
        }
    }
    let list = |command: &mut Command| {
        command
            .args(["recordings", "list", "--dir"])
            .arg(&listed)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
    };

    // Read whole, the listing is several pipe buffers long.
    let mut whole = laparo();
    list(&mut whole);
    let whole = whole.output().expect("laparo runs");
    assert!(whole.status.success());
    assert!(
        whole.stdout.len() > 4 * PIPE_BUFFER,
        "{} bytes listed",
        whole.stdout.len()
    );

    // Read one line, then the pipe closes.
    let mut client = laparo();
    list(&mut client);
    let (first, status, stderr) = read_one_line_then_close(&mut client);
    assert!(first.starts_with("| file |"), "{first}");
    assert!(status.success(), "{status}: {stderr}");
    assert_eq!(stderr, "");
    std::fs::remove_dir_all(&root).unwrap();
}

/// The demo records a session in its own process: a reader that stops after one
/// line silences it, but the session still closes and its recording is finished
/// (summary and footer written), not cut off where the pipe closed.
#[test]
fn a_demo_whose_reader_stops_after_one_line_still_finishes_its_recording() {
    let root = std::env::temp_dir().join(format!("laparo-closed-demo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let mut client = laparo();
    client
        .args(["demo", "--seconds", "1", "--recordings"])
        .arg(&root);
    let (first, status, stderr) = read_one_line_then_close(&mut client);
    assert!(first.starts_with("demo:"), "{first}");
    assert!(status.success(), "{status}: {stderr}");
    let file = std::fs::read_dir(&root)
        .expect("the demo made its recordings directory")
        .map(|e| e.expect("a directory entry").path())
        .find(|p| p.extension().is_some_and(|x| x == "mcap"))
        .expect("the demo recorded its session");
    let recording = laparo_server::recording::Recording::open(&file)
        .expect("the recording is finished: summary and footer written");
    assert!(recording.is_complete());
    let surfaces = recording.surfaces().expect("the surfaces read back");
    assert!(
        !surfaces.is_empty(),
        "the finished recording holds the session's ticks"
    );
    std::fs::remove_dir_all(&root).unwrap();
}

/// A failure said on a standard error that cannot take it (a full disk, a log pipe
/// nobody reads) still ends with status 1; `eprintln!` panicked there (status 101).
#[test]
fn a_failure_with_standard_error_unwritable_still_ends_with_status_1() {
    let closed = || {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        Stdio::from(writer)
    };
    let full = || Stdio::from(std::fs::File::create("/dev/full").unwrap());
    let missing = std::env::temp_dir().join("laparo-no-such-recording.mcap");
    for (what, stderr) in [("a full disk", full()), ("a closed pipe", closed())] {
        let status = laparo()
            .arg("replay")
            .arg(&missing)
            .stdout(Stdio::null())
            .stderr(stderr)
            .status()
            .expect("laparo runs");
        assert_eq!(status.code(), Some(1), "stderr on {what}: {status}");
    }
}
