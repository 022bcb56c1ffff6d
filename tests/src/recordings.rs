//! A server that records, a session recorded through it, and what a replay of its
//! file should send.

use std::path::{Path, PathBuf};
use std::time::Duration;

use laparo_proto::v1;
use laparo_proto::v1::sessions_client::SessionsClient;
use laparo_server::service::ServeConfig;
use tonic::transport::Channel;

use crate::pressing::{front, press, state_of};
use crate::server::{TestServer, WAIT, join, wait_for, with_token};

/// A fresh directory for a test's recordings.
pub fn recordings_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A server recording into a fresh directory named after `test`, a channel to
/// it, and the directory.
pub async fn recording_server(test: &str) -> (TestServer, Channel, PathBuf) {
    let dir = recordings_dir(test);
    let server = TestServer::start(ServeConfig {
        recordings: Some(dir.clone()),
        ..ServeConfig::default()
    })
    .await;
    let ch = server.channel().await;
    (server, ch, dir)
}

/// Creates a recorded session of the default scene.
pub async fn create_recorded(sessions: &mut SessionsClient<Channel>) -> v1::SessionInfo {
    sessions
        .create_session(v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await
        .unwrap()
        .into_inner()
}

/// Waits (up to [`WAIT`]) until session `id` has run `at_least_s` of simulated
/// time.
pub async fn run_until(sessions: &mut SessionsClient<Channel>, id: &str, at_least_s: f64) {
    let get = v1::GetSessionRequest {
        session_id: id.to_string(),
    };
    tokio::time::timeout(WAIT, async {
        while sessions
            .get_session(get.clone())
            .await
            .unwrap()
            .into_inner()
            .sim_time_s
            < at_least_s
        {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    })
    .await
    .expect("the session runs");
}

/// A session recorded through the server.
pub struct Recorded {
    /// The recording's path.
    pub file: PathBuf,
    /// The session as it closed.
    pub closed: v1::SessionInfo,
    pub joined: v1::Joined,
}

/// Records a session of the default scene in `dir`: a station presses the liver
/// with the left instrument until it holds tissue and the session has run
/// `at_least_s` of simulated time, leaves, and the session is closed (which
/// finishes the file).
pub async fn record_press(ch: &Channel, dir: &Path, at_least_s: f64) -> Recorded {
    let mut sessions = SessionsClient::new(ch.clone());
    let info = create_recorded(&mut sessions).await;
    let file = dir.join(
        info.recording_file
            .clone()
            .expect("a recorded session names its file"),
    );
    let (mut a, joined) = join(ch.clone(), None, &info.session_id, &["left"])
        .await
        .unwrap();
    press(&a, "left", front(&joined), 0.0);
    assert!(
        wait_for(&mut a.rx, WAIT, |m| state_of(m, "left")
            .is_some_and(|s| s.held_vertex_count > 0))
        .await
        .is_some()
    );
    run_until(&mut sessions, &info.session_id, at_least_s).await;
    drop(a);
    let closed = sessions
        .close_session(v1::CloseSessionRequest {
            session_id: info.session_id.clone(),
            reason: "test over".into(),
        })
        .await
        .unwrap()
        .into_inner()
        .session
        .unwrap();
    Recorded {
        file,
        closed,
        joined,
    }
}

/// Simulated time of a replayed message, s (none for the scene).
pub fn sim_time(m: &v1::ObserveMessage) -> Option<f64> {
    use v1::observe_message::Kind as O;
    match m.kind.as_ref()? {
        O::Scene(_) => None,
        O::SurfaceFrame(f) => Some(f.sim_time_s),
        O::InstrumentState(s) => Some(s.sim_time_s),
        O::Event(e) => Some(e.sim_time_s),
    }
}

/// What a recording's file holds for a replay, in file order: its surface frames,
/// instrument states and events as observe messages, with their simulated times.
pub fn recorded_messages(
    recording: &laparo_server::recording::Recording,
) -> Vec<(f64, v1::ObserveMessage)> {
    use laparo_server::recording::Recorded as R;
    use v1::observe_message::Kind as O;
    recording
        .messages()
        .filter_map(|m| {
            let kind = match m.unwrap().message {
                R::Surface(f) => O::SurfaceFrame(f),
                R::Instrument(s) => O::InstrumentState(s),
                R::Event(e) => O::Event(e),
                R::Scene(_) | R::Pose(_) => return None,
            };
            let m = v1::ObserveMessage { kind: Some(kind) };
            Some((sim_time(&m).unwrap(), m))
        })
        .collect()
}

/// What a replay from `offset` sends after the scene: the newest tick at or before
/// the offset (its surface and states) and the events stamped at the offset, then
/// everything from the first message after the offset on, in file order.
pub fn expected_from(file: &[(f64, v1::ObserveMessage)], offset: f64) -> Vec<v1::ObserveMessage> {
    use v1::observe_message::Kind as O;
    if offset == 0.0 {
        return file.iter().map(|(_, m)| m.clone()).collect();
    }
    let after = file
        .iter()
        .position(|(t, _)| *t > offset)
        .unwrap_or(file.len());
    let tick = file[..after].iter().rev().find_map(|(_, m)| match &m.kind {
        Some(O::SurfaceFrame(f)) => Some(f.tick),
        _ => None,
    });
    let first = file[..after]
        .iter()
        .rposition(|(_, m)| matches!(&m.kind, Some(O::SurfaceFrame(_))));
    let held = file[..after]
        .iter()
        .enumerate()
        .filter(|(k, (t, m))| match &m.kind {
            Some(O::SurfaceFrame(_)) => Some(*k) == first,
            Some(O::InstrumentState(s)) => Some(s.tick) == tick && Some(*k) > first,
            Some(O::Event(_)) => *t == offset,
            _ => false,
        });
    held.map(|(_, (_, m))| m.clone())
        .chain(file[after..].iter().map(|(_, m)| m.clone()))
        .collect()
}

/// The messages of a replay, each with when it arrived after the call was made,
/// and how the stream ended; the call's own refusal as `Err`.
pub async fn replay_all(
    ch: &Channel,
    token: Option<&str>,
    request: v1::ReplayRequest,
) -> Result<
    (
        Vec<(Duration, v1::ObserveMessage)>,
        Result<(), tonic::Status>,
    ),
    tonic::Status,
> {
    let t0 = std::time::Instant::now();
    let mut stream = v1::recordings_client::RecordingsClient::new(ch.clone())
        .replay(with_token(request, token))
        .await?
        .into_inner();
    let mut got = Vec::new();
    let end = tokio::time::timeout(3 * WAIT, async {
        loop {
            match stream.message().await {
                Ok(Some(m)) => got.push((t0.elapsed(), m)),
                Ok(None) => return Ok(()),
                Err(status) => return Err(status),
            }
        }
    })
    .await
    .expect("the replay ends");
    Ok((got, end))
}

pub fn replay_request(file: &str, speed: Option<f64>, offset: Option<f64>) -> v1::ReplayRequest {
    v1::ReplayRequest {
        file: file.to_string(),
        speed,
        start_offset_s: offset,
        mode: v1::ReplayMode::Recorded as i32,
    }
}

/// Surface positions as bits, to compare frames bit for bit.
pub fn bits(m: &v1::ObserveMessage) -> Option<(u64, Vec<u32>)> {
    match &m.kind {
        Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some((
            f.sim_time_s.to_bits(),
            f.positions.iter().map(|x| x.to_bits()).collect(),
        )),
        _ => None,
    }
}

/// Each message arrives no earlier than its simulated time after the offset,
/// divided by the speed (less a millisecond for rounding).
pub fn assert_paced(got: &[(Duration, v1::ObserveMessage)], offset: f64, speed: f64) {
    for (arrived, m) in got {
        if let Some(t) = sim_time(m) {
            let due = (t - offset).max(0.0) / speed;
            assert!(
                arrived.as_secs_f64() >= due - 1e-3,
                "a message of t = {t} s arrived after {arrived:?}, before {due} s"
            );
        }
    }
}
