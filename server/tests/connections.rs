//! A real `laparo-server`'s connections: closed when idle (a silent TCP connection,
//! one that sent only the HTTP/2 preface), kept while a stream is open, refused
//! past `--max-connections`, out of file descriptors the accept loop waits
//! instead of spinning a core, serving again once connections close, and a
//! connection whose peer reads nothing is closed after `--write-stall` while one
//! that reads slowly is not.

use std::ffi::OsStr;
use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use laparo_proto::v1;

mod common;
use common::process::{Server, connect, free_port, spawn};

/// The client preface every HTTP/2 connection starts with (RFC 9113 §3.4).
const PREFACE: &[u8] = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";

/// Reads `conn` until the server closes it (EOF or reset); `false` if it is still
/// open after `wait`.
fn closed_by_server(conn: &mut TcpStream, wait: Duration) -> bool {
    conn.set_read_timeout(Some(wait)).unwrap();
    let mut buf = [0u8; 4096];
    loop {
        match conn.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return false;
            }
            Err(_) => return true,
        }
    }
}

async fn list_scenes(port: u16) -> Result<usize, tonic::Status> {
    let ch = tonic::transport::Endpoint::from_shared(format!("http://127.0.0.1:{port}"))
        .unwrap()
        .connect_timeout(Duration::from_secs(2))
        .timeout(Duration::from_secs(2))
        .connect()
        .await
        .map_err(|e| tonic::Status::unavailable(e.to_string()))?;
    let scenes = v1::scenes_client::ScenesClient::new(ch)
        .list_scenes(v1::ListScenesRequest {})
        .await?
        .into_inner()
        .scenes;
    Ok(scenes.len())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_without_a_stream_are_closed_after_the_idle_timeout_and_streams_are_kept() {
    let port = free_port();
    let _server = spawn(
        port,
        &[
            OsStr::new("--no-recording"),
            OsStr::new("--idle-connection"),
            OsStr::new("1"),
        ],
    );
    let ch = connect(port).await;
    let session = v1::sessions_client::SessionsClient::new(ch.clone())
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(false),
        })
        .await
        .unwrap()
        .into_inner();
    let mut observe = v1::observe_client::ObserveClient::new(ch)
        .observe(v1::ObserveRequest {
            session_id: session.session_id,
            frame_rate_hz: None,
        })
        .await
        .unwrap()
        .into_inner();

    let mut silent = TcpStream::connect(("127.0.0.1", port)).unwrap();
    let mut preface_only = TcpStream::connect(("127.0.0.1", port)).unwrap();
    preface_only.write_all(PREFACE).unwrap();
    // The bound of the wait only turns a connection left open into a failure.
    let wait = Duration::from_secs(20);
    assert!(
        closed_by_server(&mut silent, wait),
        "silent connection kept"
    );
    assert!(
        closed_by_server(&mut preface_only, wait),
        "preface-only connection kept"
    );
    // The observer's connection, busy with its stream all this time, still is.
    for _ in 0..10 {
        observe
            .message()
            .await
            .expect("the observe stream is still open")
            .expect("and sends");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_connection_past_the_limit_is_closed_at_once_and_served_once_one_closes() {
    let port = free_port();
    let _server = spawn(
        port,
        &[
            OsStr::new("--no-recording"),
            OsStr::new("--max-connections"),
            OsStr::new("2"),
            OsStr::new("--idle-connection"),
            OsStr::new("3600"),
        ],
    );
    // Two connections: this channel's and `a`.
    let ch = connect(port).await;
    let wait = Duration::from_secs(20);
    let mut a = TcpStream::connect(("127.0.0.1", port)).unwrap();
    a.write_all(PREFACE).unwrap();
    let mut over = TcpStream::connect(("127.0.0.1", port)).unwrap();
    assert!(
        closed_by_server(&mut over, wait),
        "a third connection was kept"
    );
    assert!(
        list_scenes(port).await.is_err(),
        "a call past the limit is refused"
    );
    assert!(
        !closed_by_server(&mut a, Duration::from_millis(300)),
        "the first two stay"
    );
    // The channel still works.
    v1::scenes_client::ScenesClient::new(ch)
        .list_scenes(v1::ListScenesRequest {})
        .await
        .unwrap();
    drop(a);
    let deadline = Instant::now() + wait;
    loop {
        match list_scenes(port).await {
            Ok(n) => {
                assert!(n >= 1);
                break;
            }
            Err(e) => assert!(Instant::now() < deadline, "never served again: {e:?}"),
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// CPU time (user + system) of process `pid`, in clock ticks (`/proc/PID/stat`
/// fields 14 and 15).
fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    // The command name (field 2) is in parentheses and may hold spaces.
    let rest = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // `rest` starts at field 3.
    fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn out_of_file_descriptors_the_accept_loop_waits_and_serves_again_once_they_free() {
    const FD_LIMIT: u64 = 64;
    let port = free_port();
    let mut command = Command::new(env!("CARGO_BIN_EXE_laparo-server"));
    command
        .args(["--listen", &format!("127.0.0.1:{port}"), "--no-recording"])
        // The connection limit above the descriptors: the fd limit is what binds.
        .args(["--max-connections", "10000", "--idle-connection", "3600"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    // SAFETY: setrlimit is async-signal-safe; the child runs nothing else first.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: FD_LIMIT,
                rlim_max: FD_LIMIT,
            };
            if libc::setrlimit(libc::RLIMIT_NOFILE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command.spawn().unwrap();
    let stderr = child.stderr.take().unwrap();
    let (lines_tx, lines) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            eprintln!("server: {line}");
            let _ = lines_tx.send(line);
        }
    });
    let server = Server(child);
    let pid = server.0.id();
    connect(port).await;

    // More connections than the process has descriptors: the kernel queues the
    // ones the server cannot accept (the listen backlog is larger).
    let mut held: Vec<TcpStream> = (0..FD_LIMIT + 16)
        .map(|_| TcpStream::connect(("127.0.0.1", port)).unwrap())
        .collect();
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let line = lines
            .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            .expect("the server says it is out of file descriptors");
        if line.contains("out of file descriptors") {
            break;
        }
    }
    // Out of descriptors with connections pending: a spinning loop burns a whole
    // core (100 ticks a second); the backoff, a few accept calls a second.
    let before = cpu_ticks(pid);
    tokio::time::sleep(Duration::from_secs(2)).await;
    let used = cpu_ticks(pid) - before;
    assert!(
        used <= 20,
        "{used} ticks of CPU in 2 s out of descriptors: the accept loop spins"
    );

    held.clear();
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match list_scenes(port).await {
            Ok(n) => {
                assert!(n >= 1);
                break;
            }
            Err(e) => assert!(Instant::now() < deadline, "never served again: {e:?}"),
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// The largest of the console's files the server serves, and its size: `GET`s of it
/// are what a peer that reads nothing would ask for.
fn largest_asset() -> (String, usize) {
    use laparo_server::console::assets::{Assets, STAMP};
    Assets::iter()
        .filter(|name| name != STAMP)
        .map(|name| (Assets::get(&name).unwrap().data.len(), name.into_owned()))
        .max()
        .map(|(len, name)| (format!("/{name}"), len))
        .expect("the console has files")
}

/// `n` pipelined `GET`s of `path`, the last closing the connection.
fn pipelined_gets(path: &str, n: usize) -> Vec<u8> {
    (0..n)
        .map(|i| {
            let close = if i + 1 == n {
                "connection: close\r\n"
            } else {
                ""
            };
            format!("GET {path} HTTP/1.1\r\nhost: 127.0.0.1\r\n{close}\r\n")
        })
        .collect::<String>()
        .into_bytes()
}

/// Answers to ask for so that they overfill both sockets' buffers many times over:
/// the server's send buffer grows to at most `net.ipv4.tcp_wmem`'s 4 MiB by
/// default.
const ANSWER_BYTES: usize = 16 << 20;

/// A connection to the server on `port` with a receive buffer of `recv_buffer`
/// bytes that sent `requests` and was served: the start of the first answer has
/// come (past `--max-connections`, the connection is closed at once, and this
/// tries again).
async fn served(port: u16, recv_buffer: u32, requests: &[u8]) -> tokio::net::TcpStream {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        // Before connecting: the window it advertises follows from it.
        socket.set_recv_buffer_size(recv_buffer).unwrap();
        if let Ok(mut conn) = socket.connect(([127, 0, 0, 1], port).into()).await
            && conn.write_all(requests).await.is_ok()
        {
            let mut head = [0u8; 12];
            if conn.read_exact(&mut head).await.is_ok() {
                assert_eq!(&head, b"HTTP/1.1 200", "the asset is served");
                return conn;
            }
        }
        assert!(Instant::now() < deadline, "never served");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Whether the kernel still has a socket of the server on `port` connected to
/// `peer_port` on loopback (any state: an orphan closing keeps its buffers too),
/// from `/proc/net/tcp`.
fn server_socket_open(port: u16, peer_port: u16) -> bool {
    let port_of = |field: &str| u16::from_str_radix(field.rsplit(':').next().unwrap(), 16).ok();
    std::fs::read_to_string("/proc/net/tcp")
        .unwrap()
        .lines()
        .skip(1)
        .any(|line| {
            let mut fields = line.split_whitespace().skip(1);
            let (local, remote) = (fields.next().unwrap(), fields.next().unwrap());
            port_of(local) == Some(port) && port_of(remote) == Some(peer_port)
        })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_peer_that_reads_nothing_is_cut_after_the_write_stall_and_frees_its_slot() {
    let port = free_port();
    // One connection in all: the one that reads nothing holds it until it is cut.
    let _server = spawn(
        port,
        &[
            OsStr::new("--no-recording"),
            OsStr::new("--max-connections"),
            OsStr::new("1"),
            OsStr::new("--idle-connection"),
            OsStr::new("3600"),
            OsStr::new("--write-stall"),
            OsStr::new("1"),
        ],
    );
    let (path, len) = largest_asset();
    let n = ANSWER_BYTES / len + 1;
    // A small receive buffer: the peer's window closes after a few kB.
    let conn = served(port, 4096, &pipelined_gets(&path, n)).await;
    let peer_port = conn.local_addr().unwrap().port();
    assert!(server_socket_open(port, peer_port));
    // From now on it reads nothing. The bound only turns a connection kept
    // forever into a failure.
    let start = Instant::now();
    while server_socket_open(port, peer_port) {
        assert!(
            start.elapsed() < Duration::from_secs(15),
            "the server, or its kernel, still holds a connection whose peer has read \
             nothing for {:?}",
            start.elapsed()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    eprintln!("cut after {:?} of reading nothing", start.elapsed());
    // Its slot, the only one, serves another client.
    let deadline = Instant::now() + Duration::from_secs(20);
    while let Err(e) = list_scenes(port).await {
        assert!(Instant::now() < deadline, "the slot never freed: {e:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // The peer, reading at last, finds its connection ended before the answers.
    let mut conn = conn.into_std().unwrap();
    conn.set_nonblocking(false).unwrap();
    let mut got = 0;
    let mut buf = vec![0u8; 1 << 16];
    conn.set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    loop {
        match conn.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(k) => got += k,
        }
    }
    assert!(got < n * len, "{got} bytes: every answer came");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_peer_that_reads_slowly_is_served_whole_though_each_write_waits_past_the_limit() {
    use tokio::io::AsyncReadExt;
    let port = free_port();
    let _server = spawn(
        port,
        &[
            OsStr::new("--no-recording"),
            OsStr::new("--write-stall"),
            OsStr::new("0.5"),
        ],
    );
    let (path, len) = largest_asset();
    // More than the server's send buffer holds (megabytes on loopback): its
    // writes wait for this reader.
    let n = (4 << 20) / len + 1;
    let mut conn = served(port, 16 << 10, &pipelined_gets(&path, n)).await;
    // At most 16 KiB every 10 ms, about 1 MB/s: a write goes on only once the
    // reader has taken a third of the server's send buffer, which takes it longer
    // than the limit, but it takes bytes all the while, and that must keep the
    // connection.
    let start = Instant::now();
    let mut got = 12;
    let mut buf = vec![0u8; 16 << 10];
    loop {
        let k = tokio::time::timeout(Duration::from_secs(20), conn.read(&mut buf))
            .await
            .expect("the server goes on sending")
            .expect("and does not cut the connection");
        if k == 0 {
            break;
        }
        got += k;
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(
        got > n * len,
        "{got} bytes of {n} answers of {len}: cut short"
    );
    eprintln!("{got} bytes in {:?}", start.elapsed());
}

/// A peer that sends one `GET` of the console's largest file, asking the server to
/// close after it, and then reads nothing: the answer fits in the server's send
/// buffer, so no write waits and the write-stall timer never runs; the server closes
/// the connection as asked, and the kernel is left with an orphaned socket holding
/// the unsent answer. That orphan must go within the write-stall limit too, not
/// after the minutes the kernel's own zero-window probing takes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_answer_left_unread_after_the_connection_closes_goes_with_the_write_stall() {
    let port = free_port();
    let _server = spawn(
        port,
        &[
            OsStr::new("--no-recording"),
            OsStr::new("--idle-connection"),
            OsStr::new("3600"),
            OsStr::new("--write-stall"),
            OsStr::new("1"),
        ],
    );
    let (path, _) = largest_asset();
    let conn = served(port, 4096, &pipelined_gets(&path, 1)).await;
    let peer_port = conn.local_addr().unwrap().port();
    let start = Instant::now();
    while server_socket_open(port, peer_port) {
        assert!(
            start.elapsed() < Duration::from_secs(15),
            "the kernel still holds the server's socket, with the answer its peer \
             reads nothing of, {:?} after the answer began",
            start.elapsed()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    eprintln!("gone after {:?} of reading nothing", start.elapsed());
    drop(conn);
}
