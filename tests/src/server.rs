//! A real server on a loopback port for integration tests, and the clients to talk to
//! it.

use std::net::SocketAddr;
use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::{ServeConfig, ServeError, serve};
use tokio::sync::{mpsc, oneshot};
use tokio::task::JoinHandle;
use tokio_stream::wrappers::ReceiverStream;
use tonic::transport::Channel;
use tonic::{Request, Status, Streaming};

/// How long a test waits for something a server should do in well under a second.
pub const WAIT: Duration = Duration::from_secs(20);

/// `attempt`'s answer once it is anything but `code`, trying again every 50 ms for
/// up to [`WAIT`]: a place given back (a station's, an observer's, a replay slot)
/// is free only once the server has seen its stream end. The last answer if it
/// is still `code` then.
pub async fn once_not<T, F: std::future::Future<Output = Result<T, Status>>>(
    code: tonic::Code,
    mut attempt: impl FnMut() -> F,
) -> Result<T, Status> {
    let start = std::time::Instant::now();
    loop {
        match attempt().await {
            Err(e) if e.code() == code && start.elapsed() < WAIT => {
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            answer => return answer,
        }
    }
}

/// Sends `request`, raw HTTP/1.1, to `server` on a connection of its own and
/// returns the answer's head (status line and headers, lower-cased), read up to
/// the blank line within [`WAIT`].
pub async fn http_head(server: &TestServer, request: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tokio::net::TcpStream::connect(server.addr).await.unwrap();
    s.write_all(request.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let mut buf = [0u8; 4096];
    while !out.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = tokio::time::timeout(WAIT, s.read(&mut buf))
            .await
            .expect("the server answers")
            .unwrap();
        if n == 0 {
            break;
        }
        out.extend_from_slice(&buf[..n]);
    }
    let text = String::from_utf8_lossy(&out).to_lowercase();
    text[..text.find("\r\n\r\n").unwrap_or(text.len())].to_string()
}

/// Sends `request`, raw HTTP/1.1, to `server` on a connection of its own and
/// returns the whole answer, head and body (a gRPC-web body holds its trailers),
/// lossily as text and lower-cased, read until the server closes within
/// [`WAIT`]: the request must say `connection: close`.
pub async fn http_exchange(server: &TestServer, request: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tokio::net::TcpStream::connect(server.addr).await.unwrap();
    s.write_all(request.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    tokio::time::timeout(WAIT, s.read_to_end(&mut out))
        .await
        .expect("the server answers and closes")
        .unwrap();
    String::from_utf8_lossy(&out).to_lowercase()
}

/// A server serving on `127.0.0.1:<free port>` in this runtime.
pub struct TestServer {
    pub addr: SocketAddr,
    stop: Option<oneshot::Sender<()>>,
    task: JoinHandle<Result<(), ServeError>>,
}

impl TestServer {
    pub async fn start(config: ServeConfig) -> Self {
        Self::start_at("127.0.0.1:0".parse().unwrap(), config).await
    }

    /// A server on `addr` (port 0: a free one), as a restarted server comes back
    /// on the port it had.
    pub async fn start_at(addr: SocketAddr, config: ServeConfig) -> Self {
        let listener = tokio::net::TcpListener::bind(addr).await.unwrap();
        let addr = listener.local_addr().unwrap();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(serve(config, listener, async {
            let _ = stopped.await;
        }));
        TestServer {
            addr,
            stop: Some(stop),
            task,
        }
    }

    pub async fn channel(&self) -> Channel {
        Channel::from_shared(format!("http://{}", self.addr))
            .unwrap()
            .connect()
            .await
            .unwrap()
    }

    /// Shuts down as SIGTERM would and waits for `serve` to return.
    pub async fn shutdown(mut self) -> Result<(), ServeError> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        tokio::time::timeout(Duration::from_secs(20), &mut self.task)
            .await
            .expect("the server shuts down within 20 s")
            .expect("the server task does not panic")
    }
}

/// The status a stream ends with (`None`: it ended cleanly), reading and dropping
/// what comes before it; fails the test unless it ends within [`WAIT`].
pub async fn final_status<T>(rx: &mut Streaming<T>) -> Option<Status> {
    tokio::time::timeout(WAIT, async {
        loop {
            match rx.message().await {
                Ok(Some(_)) => continue,
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .expect("the stream ends")
}

/// A request with a bearer token, if any.
pub fn with_token<T>(message: T, token: Option<&str>) -> Request<T> {
    let mut request = Request::new(message);
    if let Some(t) = token {
        request
            .metadata_mut()
            .insert("authorization", format!("Bearer {t}").parse().unwrap());
    }
    request
}

/// A joined (or refused) station stream: what it sends, what it receives.
pub struct StationStream {
    pub tx: mpsc::Sender<v1::StationMessage>,
    pub rx: Streaming<v1::ServerMessage>,
}

/// Opens `Join` and sends `first`; the server's answer to the opening is the first
/// message of `rx` (or the call's error).
pub async fn join_raw(
    channel: Channel,
    token: Option<&str>,
    first: Option<v1::StationMessage>,
) -> Result<StationStream, Status> {
    let (tx, out) = mpsc::channel(1024);
    if let Some(m) = first {
        tx.send(m).await.unwrap();
    }
    let mut client = v1::station_client::StationClient::new(channel);
    let rx = client
        .join(with_token(ReceiverStream::new(out), token))
        .await?
        .into_inner();
    Ok(StationStream { tx, rx })
}

/// The opening message.
pub fn open(session: &str, instruments: &[&str]) -> v1::StationMessage {
    v1::StationMessage {
        kind: Some(v1::station_message::Kind::Open(v1::JoinRequest {
            session_id: session.to_string(),
            role: v1::Role::Trainee as i32,
            instruments: instruments.iter().map(|s| s.to_string()).collect(),
            surface_frame_rate_hz: None,
            client_name: "test".into(),
        })),
    }
}

/// A pose message.
pub fn pose(instrument: &str, tip: [f64; 3], axis: [f64; 3], sequence: u64) -> v1::StationMessage {
    let v = |a: [f64; 3]| v1::Vec3 {
        x: a[0],
        y: a[1],
        z: a[2],
    };
    v1::StationMessage {
        kind: Some(v1::station_message::Kind::Pose(v1::DevicePose {
            instrument: instrument.to_string(),
            pose: Some(v1::Pose {
                tip: Some(v(tip)),
                axis: Some(v(axis)),
            }),
            device_time_s: 0.0,
            sequence,
        })),
    }
}

/// Joins `session` claiming `instruments`, and waits for `Joined`.
pub async fn join(
    channel: Channel,
    token: Option<&str>,
    session: &str,
    instruments: &[&str],
) -> Result<(StationStream, v1::Joined), Status> {
    let mut s = join_raw(channel, token, Some(open(session, instruments))).await?;
    match s.rx.message().await? {
        Some(v1::ServerMessage {
            kind: Some(v1::server_message::Kind::Joined(j)),
        }) => Ok((s, j)),
        other => panic!("expected Joined, got {other:?}"),
    }
}

/// Creates a session of the default scene.
pub async fn create_session(
    channel: Channel,
    token: Option<&str>,
) -> Result<v1::SessionInfo, Status> {
    v1::sessions_client::SessionsClient::new(channel)
        .create_session(with_token(
            v1::CreateSessionRequest {
                scene: "default".into(),
                idle_timeout_s: None,
                record: None,
            },
            token,
        ))
        .await
        .map(|r| r.into_inner())
}

/// Reads server messages until `pred` holds for one (returning it) or `timeout`.
pub async fn wait_for<F>(
    rx: &mut Streaming<v1::ServerMessage>,
    timeout: Duration,
    mut pred: F,
) -> Option<v1::ServerMessage>
where
    F: FnMut(&v1::ServerMessage) -> bool,
{
    tokio::time::timeout(timeout, async {
        while let Ok(Some(m)) = rx.message().await {
            if pred(&m) {
                return Some(m);
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
}

/// A token table: `(token, caller name, role, instruments it may claim or None for
/// any)` a row.
pub fn tokens(
    rows: &[(&str, &str, laparo_server::service::Role, Option<&[&str]>)],
) -> laparo_server::service::Tokens {
    let mut tokens = laparo_server::service::Tokens::default();
    for &(token, name, role, instruments) in rows {
        tokens.insert(
            token,
            laparo_server::service::Caller {
                name: name.into(),
                role,
                instruments: instruments.map(|i| i.iter().map(|s| s.to_string()).collect()),
            },
        );
    }
    tokens
}
