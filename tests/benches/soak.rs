//! Soak: a real server process holding N recorded default sessions, each with two
//! stations streaming poses at 1 kHz (`laparo_client::load`, the default press),
//! plus observers (32 in all, spread over the sessions), for `--seconds`.
//!
//! Printed at the start of the measured window (after every station has joined
//! and a warm-up) and at its end: the server's RSS, threads and open file
//! descriptors (from `/proc/PID`), and over all sessions the missed mechanics
//! deadlines and the items the recorders left out. The verdict says whether
//! anything grew (threads, descriptors, RSS beyond 5 % + 16 MiB) or was lost
//! (a missed deadline or a recorder drop in the window, a station or observer
//! that failed).
//!
//! `--ramp` finds the most sessions this machine holds: it adds `--step` sessions
//! (with their stations and two observers each) at a time, lets them settle, and
//! stops at the first step whose sessions miss deadlines in a 10 s window.
//!
//! The server is this program run again as a child process (`LAPARO_SOAK_SERVE`),
//! serving with the machine's default limits (`--max-sessions` raised to N when
//! N is larger) and recording into a temporary directory. Stations join at most
//! 20 a second, under the server's join-rate limit (50 a second per caller and
//! address). The client side runs in this process and shares the machine's cores
//! with the server: on a small or shared machine the figures are noisy.
//!
//! `cargo bench -p laparo-tests --bench soak -- --sessions 64 --seconds 600`
//! (defaults: 64 sessions, 600 s, 32 observers, 10 s warm-up);
//! `cargo bench -p laparo-tests --bench soak -- --ramp`; `--unrecorded` runs the same
//! sessions without recordings, to tell what the recorders hold.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use laparo_client::connect::{ConnectConfig, connect};
use laparo_client::load::{LoadConfig, LoadSummary, run_load};
use laparo_proto::v1;
use laparo_server::service::capacity::Capacity;
use laparo_server::service::{ServeConfig, serve};
use tokio::task::JoinSet;

const SERVE_ENV: &str = "LAPARO_SOAK_SERVE";
const DIR_ENV: &str = "LAPARO_SOAK_DIR";
const SESSIONS_ENV: &str = "LAPARO_SOAK_MAX_SESSIONS";
/// Stations joining per second, under the join-rate limit of 50.
const JOINS_PER_SECOND: f64 = 20.0;

#[derive(Debug)]
struct Args {
    sessions: usize,
    seconds: f64,
    observers: usize,
    warmup: f64,
    ramp: bool,
    step: usize,
    /// `--unrecorded`: sessions without recordings, to tell what the recorders hold.
    unrecorded: bool,
}

fn args() -> Args {
    let mut a = Args {
        sessions: 64,
        seconds: 600.0,
        observers: 32,
        warmup: 10.0,
        ramp: false,
        step: 8,
        unrecorded: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| -> f64 {
            it.next()
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("{name} needs a number"))
        };
        match arg.as_str() {
            "--sessions" => a.sessions = value("--sessions") as usize,
            "--seconds" => a.seconds = value("--seconds"),
            "--observers" => a.observers = value("--observers") as usize,
            "--warmup" => a.warmup = value("--warmup"),
            "--step" => a.step = (value("--step") as usize).max(1),
            "--ramp" => a.ramp = true,
            "--unrecorded" => a.unrecorded = true,
            // `cargo bench` passes `--bench`; anything else is ignored too.
            _ => {}
        }
    }
    a
}

/// The child: a server with the machine's limits, recording into `dir`, until
/// SIGTERM.
fn serve_child(port: u16) {
    let dir = PathBuf::from(std::env::var(DIR_ENV).expect("recordings directory"));
    let sessions: usize = std::env::var(SESSIONS_ENV)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let machine = laparo_server::service::capacity::Machine::this();
    let mut capacity = Capacity::for_machine(machine);
    if sessions > capacity.sessions {
        capacity = capacity.with_sessions(sessions, machine);
    }
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
            .await
            .unwrap();
        let config = ServeConfig {
            recordings: Some(dir),
            capacity,
            ..ServeConfig::default()
        };
        let term = async {
            let mut term =
                tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).unwrap();
            term.recv().await;
        };
        serve(config, listener, term).await.unwrap();
    });
    runtime.shutdown_timeout(Duration::from_secs(1));
}

/// The server process, stopped with SIGTERM when dropped.
struct ServerProcess {
    child: Child,
    _dir: TempDir,
}

impl Drop for ServerProcess {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(15);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A directory removed when dropped.
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// What the server process holds, from `/proc/PID`.
#[derive(Clone, Copy, Debug, Default)]
struct Process {
    rss_kib: u64,
    threads: u64,
    fds: u64,
}

fn process(pid: u32) -> Process {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    Process {
        rss_kib: field("VmRSS:"),
        threads: field("Threads:"),
        fds: std::fs::read_dir(format!("/proc/{pid}/fd")).map_or(0, |d| d.count() as u64),
    }
}

/// Over all sessions of the server.
#[derive(Clone, Copy, Debug, Default)]
struct Sessions {
    count: usize,
    stations: usize,
    observers: u64,
    missed: u64,
    dropped: u64,
    p99_ms: f64,
}

async fn sessions(url: &str) -> Sessions {
    let c = connect(&ConnectConfig::new(url)).await.expect("connects");
    let list = c
        .sessions()
        .list_sessions(v1::ListSessionsRequest {})
        .await
        .expect("lists sessions")
        .into_inner()
        .sessions;
    let mut s = Sessions {
        count: list.len(),
        ..Sessions::default()
    };
    for i in &list {
        s.stations += i.stations.len();
        s.observers += u64::from(i.observer_count);
        s.missed += i.missed_deadlines;
        s.dropped += i.recorder_dropped;
        s.p99_ms = s.p99_ms.max(i.tick_time_p99_ms);
    }
    s
}

fn print_snapshot(label: &str, p: Process, s: Sessions) {
    println!(
        "{label:>5}: RSS {:>8.1} MiB  threads {:>4}  fds {:>4}  sessions {:>3}  stations {:>4}  \
         observers {:>3}  missed deadlines {:>6}  recorder drops {:>6}  worst tick p99 {:.2} ms",
        p.rss_kib as f64 / 1024.0,
        p.threads,
        p.fds,
        s.count,
        s.stations,
        s.observers,
        s.missed,
        s.dropped,
        s.p99_ms
    );
}

/// Starts the server process and waits until it serves.
async fn start_server(max_sessions: usize) -> (ServerProcess, String) {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = std::env::temp_dir().join(format!("laparo-soak-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let child = Command::new(std::env::current_exe().unwrap())
        .env(SERVE_ENV, port.to_string())
        .env(DIR_ENV, &dir)
        .env(SESSIONS_ENV, max_sessions.to_string())
        .stdin(Stdio::null())
        .spawn()
        .unwrap();
    let server = ServerProcess {
        child,
        _dir: TempDir(dir),
    };
    let url = format!("http://127.0.0.1:{port}");
    let deadline = Instant::now() + Duration::from_secs(30);
    while connect(&ConnectConfig::new(url.clone())).await.is_err() {
        assert!(Instant::now() < deadline, "the server never listened");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    (server, url)
}

/// Creates a default session, recorded when `record`.
async fn create(url: &str, record: bool) -> Result<String, tonic::Status> {
    let c = connect(&ConnectConfig::new(url))
        .await
        .map_err(|e| tonic::Status::unavailable(e.to_string()))?;
    Ok(c.sessions()
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(record),
        })
        .await?
        .into_inner()
        .session_id)
}

/// Two stations posing at 1 kHz on `session` for `duration`.
fn stations(url: &str, session: String, duration: Duration) -> LoadConfig {
    LoadConfig {
        connect: ConnectConfig::new(url),
        session: Some(session),
        stations: 2,
        pose_rate_hz: 1000.0,
        duration,
        surface_frame_rate_hz: None,
        scene: None,
        record: None,
    }
}

/// An observer of `session` until `until`: the frames it received and whether its
/// stream ended early (with why).
async fn observe(url: String, session: String, until: Instant) -> (u64, Option<String>) {
    let c = match connect(&ConnectConfig::new(url)).await {
        Ok(c) => c,
        Err(e) => return (0, Some(e.to_string())),
    };
    let mut stream = match c
        .observe()
        .observe(v1::ObserveRequest {
            session_id: session,
            frame_rate_hz: None,
        })
        .await
    {
        Ok(s) => s.into_inner(),
        Err(e) => return (0, Some(e.to_string())),
    };
    let mut frames = 0;
    loop {
        let next = tokio::time::timeout_at(until.into(), stream.message()).await;
        match next {
            Err(_) => return (frames, None),
            Ok(Ok(Some(m))) => {
                if matches!(m.kind, Some(v1::observe_message::Kind::SurfaceFrame(_))) {
                    frames += 1;
                }
            }
            Ok(Ok(None)) => return (frames, Some("the stream ended".into())),
            Ok(Err(e)) => return (frames, Some(e.to_string())),
        }
    }
}

/// Waits until `stations` stations have joined over all sessions.
async fn joined(url: &str, stations: usize, within: Duration) -> bool {
    let deadline = Instant::now() + within;
    while Instant::now() < deadline {
        if sessions(url).await.stations >= stations {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    false
}

async fn soak(a: &Args) {
    println!(
        "soak: {} {} default sessions, 2 stations each at 1 kHz, {} observers, \
         {} s (after {} s warm-up)",
        a.sessions,
        if a.unrecorded {
            "unrecorded"
        } else {
            "recorded"
        },
        a.observers,
        a.seconds,
        a.warmup
    );
    let (server, url) = start_server(a.sessions).await;
    let pid = server.child.id();
    let mut ids = Vec::new();
    for _ in 0..a.sessions {
        ids.push(
            create(&url, !a.unrecorded)
                .await
                .expect("creates a session"),
        );
    }
    let join_time = 2.0 * a.sessions as f64 / JOINS_PER_SECOND;
    let measured_end = Instant::now() + Duration::from_secs_f64(join_time + a.warmup + a.seconds);
    let mut loads = JoinSet::new();
    for (k, id) in ids.iter().enumerate() {
        // Each load's stations stay until the end of the window, and 2 s more.
        let stay = measured_end.saturating_duration_since(Instant::now()) + Duration::from_secs(2);
        loads.spawn(run_load(stations(&url, id.clone(), stay), |_| {}));
        if k + 1 < ids.len() {
            tokio::time::sleep(Duration::from_secs_f64(2.0 / JOINS_PER_SECOND)).await;
        }
    }
    let mut observers = JoinSet::new();
    for k in 0..a.observers {
        let id = ids[k % ids.len()].clone();
        // Watching until 2 s after the window, as the stations stay.
        observers.spawn(observe(
            url.clone(),
            id,
            measured_end + Duration::from_secs(2),
        ));
    }
    assert!(
        joined(&url, 2 * a.sessions, Duration::from_secs(60)).await,
        "every station joins"
    );
    tokio::time::sleep(Duration::from_secs_f64(a.warmup)).await;
    let (p0, s0) = (process(pid), sessions(&url).await);
    print_snapshot("start", p0, s0);
    let window_start = Instant::now();
    while Instant::now() < measured_end {
        let left = measured_end.saturating_duration_since(Instant::now());
        tokio::time::sleep(left.min(Duration::from_secs(60))).await;
        if Instant::now() < measured_end {
            print_snapshot(
                &format!("{:.0}s", window_start.elapsed().as_secs_f64()),
                process(pid),
                sessions(&url).await,
            );
        }
    }
    let (p1, s1) = (process(pid), sessions(&url).await);
    print_snapshot("end", p1, s1);

    let mut failures = Vec::new();
    let mut summaries: Vec<LoadSummary> = Vec::new();
    while let Some(r) = loads.join_next().await {
        match r {
            Ok(Ok(s)) => {
                failures.extend(s.failures.iter().map(|f| f.to_string()));
                summaries.push(s);
            }
            Ok(Err(e)) => failures.push(e.to_string()),
            Err(e) => failures.push(e.to_string()),
        }
    }
    let mut observer_frames = Vec::new();
    while let Some(r) = observers.join_next().await {
        match r {
            Ok((frames, None)) => observer_frames.push(frames),
            Ok((_, Some(why))) => failures.push(format!("observer: {why}")),
            Err(e) => failures.push(e.to_string()),
        }
    }
    let poses: u64 = summaries.iter().map(|s| s.poses_sent).sum();
    let rejected: u64 = summaries.iter().map(|s| s.poses_rejected).sum();
    println!(
        "stations: {} loads, {poses} poses sent, {rejected} rejected; observers: {} streaming \
         to the end, {} frames each at least",
        summaries.len(),
        observer_frames.len(),
        observer_frames.iter().min().copied().unwrap_or(0)
    );

    let mut verdict = Vec::new();
    if p1.threads > p0.threads {
        verdict.push(format!("threads grew {} → {}", p0.threads, p1.threads));
    }
    if p1.fds > p0.fds {
        verdict.push(format!("descriptors grew {} → {}", p0.fds, p1.fds));
    }
    if p1.rss_kib as f64 > p0.rss_kib as f64 * 1.05 + 16.0 * 1024.0 {
        verdict.push(format!(
            "RSS grew {:.1} → {:.1} MiB",
            p0.rss_kib as f64 / 1024.0,
            p1.rss_kib as f64 / 1024.0
        ));
    }
    if s1.missed > s0.missed {
        verdict.push(format!(
            "{} deadlines missed in the window",
            s1.missed - s0.missed
        ));
    }
    if s1.dropped > 0 {
        verdict.push(format!("recorders dropped {} items", s1.dropped));
    }
    if s1.count < a.sessions || s1.stations < 2 * a.sessions {
        verdict.push(format!(
            "{} sessions, {} stations at the end",
            s1.count, s1.stations
        ));
    }
    if !failures.is_empty() {
        verdict.push(format!("{} failures: {:?}", failures.len(), failures));
    }
    if verdict.is_empty() {
        println!(
            "verdict: HELD — nothing grew, nothing lost ({} sessions, {} s)",
            a.sessions, a.seconds
        );
    } else {
        println!("verdict: NOT HELD — {}", verdict.join("; "));
    }
    drop(server);
}

async fn ramp(a: &Args) {
    println!(
        "soak ramp: {} recorded default sessions more a step, 2 stations each at 1 kHz and 2 \
         observers; a step holds when its 10 s window misses no deadline",
        a.step
    );
    let (server, url) = start_server(512).await;
    let pid = server.child.id();
    let mut tasks = JoinSet::new();
    let mut held = 0;
    let mut n = 0;
    'ramp: loop {
        for _ in 0..a.step {
            let id = match create(&url, !a.unrecorded).await {
                Ok(id) => id,
                Err(e) => {
                    println!("cannot create session {}: {}", n + 1, e.message());
                    break 'ramp;
                }
            };
            n += 1;
            tasks.spawn({
                let load = stations(&url, id.clone(), Duration::from_secs(3600));
                async move {
                    let _ = run_load(load, |_| {}).await;
                }
            });
            for _ in 0..2 {
                let (url, id) = (url.clone(), id.clone());
                tasks.spawn(async move {
                    let _ = observe(url, id, Instant::now() + Duration::from_secs(3600)).await;
                });
            }
            tokio::time::sleep(Duration::from_secs_f64(2.0 / JOINS_PER_SECOND)).await;
        }
        if !joined(&url, 2 * n, Duration::from_secs(30)).await {
            println!("{n} sessions: not every station joined");
            break;
        }
        tokio::time::sleep(Duration::from_secs(5)).await;
        let s0 = sessions(&url).await;
        tokio::time::sleep(Duration::from_secs(10)).await;
        let s1 = sessions(&url).await;
        let p = process(pid);
        let missed = s1.missed - s0.missed;
        println!(
            "{n:>4} sessions: missed deadlines in 10 s {missed:>5}  worst tick p99 {:.2} ms  \
             RSS {:.1} MiB  threads {}  fds {}  recorder drops {}",
            s1.p99_ms,
            p.rss_kib as f64 / 1024.0,
            p.threads,
            p.fds,
            s1.dropped
        );
        if missed > 0 || s1.count < n {
            break;
        }
        held = n;
    }
    println!("ramp: this machine held {held} sessions without missed deadlines");
    tasks.abort_all();
    drop(server);
}

fn main() {
    if let Ok(port) = std::env::var(SERVE_ENV) {
        return serve_child(port.parse().expect("a port"));
    }
    let a = args();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        if a.ramp {
            ramp(&a).await
        } else {
            soak(&a).await
        }
    });
}
