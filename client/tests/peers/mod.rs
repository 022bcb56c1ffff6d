//! Peers that are not a working laparo server, on loopback, and the `laparo` binary
//! run against them with every wait bounded.

#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// How long a client may take before it is killed and the test fails: far above
/// every time limit the client applies (5 s to connect, 30 s a call).
pub const LIMIT: Duration = Duration::from_secs(90);

/// A loopback port nothing listens on: bound, then closed.
pub fn closed_port() -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    listener.local_addr().unwrap()
}

/// A listener that accepts every connection and never sends a byte (the sockets
/// are held open by its thread for the life of the test).
pub fn silent() -> SocketAddr {
    serve(|stream| {
        std::mem::forget(stream);
    })
}

/// An HTTP/1.1 server: reads what comes and answers `200 OK` with a short body,
/// then closes.
pub fn http1() -> SocketAddr {
    serve(|mut stream| {
        let mut buffer = [0u8; 1024];
        let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
        let _ = stream.read(&mut buffer);
        let _ = stream.write_all(
            b"HTTP/1.1 200 OK\r\nContent-Type: text/plain\r\nContent-Length: 5\r\nConnection: close\r\n\r\nhello",
        );
        // Close gracefully: end the answer, then read what the client still sends
        // until it hangs up. Dropping the socket with unread bytes in its buffer
        // (the rest of an HTTP/2 preface that came after the first read) makes the
        // kernel reset the connection, and the client may see the reset before the
        // answer.
        let _ = stream.shutdown(std::net::Shutdown::Write);
        while matches!(stream.read(&mut buffer), Ok(n) if n > 0) {}
    })
}

/// A listener that accepts each connection and closes it at once.
pub fn closing() -> SocketAddr {
    serve(drop)
}

/// A listener on loopback whose thread hands every accepted connection to `each`.
fn serve(each: impl Fn(TcpStream) + Send + 'static) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            each(stream);
        }
    });
    address
}

/// What a run of the client gave.
pub struct Run {
    /// Its exit status, `None` if killed by a signal.
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    /// How long it ran.
    pub took: Duration,
}

/// Runs `laparo args…` to its end, killing it (and failing) past [`LIMIT`].
pub fn laparo(args: &[&str]) -> Run {
    let start = Instant::now();
    finish(start_laparo(args), start)
}

/// Starts `laparo args…`, its output piped.
pub fn start_laparo(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_laparo"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("laparo runs")
}

/// Waits for `child`, started at `start`, to end; kills it (and fails) past
/// [`LIMIT`].
pub fn finish(mut child: Child, start: Instant) -> Run {
    loop {
        if child
            .try_wait()
            .expect("the client can be waited for")
            .is_some()
        {
            break;
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("laparo still ran after {LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let took = start.elapsed();
    let Output {
        status,
        stdout,
        stderr,
    } = child.wait_with_output().expect("the output is read");
    Run {
        code: status.code(),
        stdout: String::from_utf8_lossy(&stdout).into_owned(),
        stderr: String::from_utf8_lossy(&stderr).into_owned(),
        took,
    }
}

impl Run {
    /// Asserts exit status 1 and one line on stderr containing every one of `words`.
    pub fn fails_saying(&self, words: &[&str]) {
        assert_eq!(
            self.code,
            Some(1),
            "status {:?}\nstdout: {}\nstderr: {}",
            self.code,
            self.stdout,
            self.stderr
        );
        for w in words {
            assert!(
                self.stderr.contains(w),
                "stderr lacks {w:?}: {}",
                self.stderr
            );
        }
        assert!(
            !self.stderr.contains("transport error") && !self.stderr.contains("source:"),
            "stderr shows tonic's internals: {}",
            self.stderr
        );
    }
}
