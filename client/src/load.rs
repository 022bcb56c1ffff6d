//! A load test: N concurrent stations on one session, each on its own connection.
//!
//! The first `min(N, free instruments)` stations each claim one free instrument of
//! the session (the default scene has two, "left" and "right") and send scripted
//! poses (the default press of [`crate::gestures`]) from a tokio task at the pose
//! rate; no force loop runs. The other stations join with an empty instrument list:
//! they receive surface frames, instrument states and events, and send no pose.
//! Such a station only watches, which needs an instructor token (as `Observe`
//! does): with a trainee token, run at most as many stations as free instruments.
//!
//! Measured: the pose-to-state latency over every posing station (as in
//! [`crate::station`]), the frames and states each station received, and, from
//! `Sessions.GetSession` at the end, the session's missed mechanics deadlines, tick
//! time percentiles and accepted and rejected pose counts. Without a session id a
//! session of the server's default scene is created and closed at the end.
//!
//! Nothing waits for ever: each connection is made within its connect timeout,
//! each join and unary call within [`CALL_TIMEOUT`], and each station stays its
//! duration and then leaves within [`LEAVE_GRACE`](crate::station::LEAVE_GRACE).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use tokio::task::JoinSet;
use tokio::time::MissedTickBehavior;

use crate::connect::{AuthChannel, CALL_TIMEOUT, ConnectConfig, Connection, connect, unary};
use crate::gestures::default_press_for;
use crate::latency::{LatencyHistogram, LatencySummary};
use crate::proto::v1::sessions_client::SessionsClient;
use crate::proto::v1::{
    CloseSessionRequest, CreateSessionRequest, GetSessionRequest, JoinRequest, Role, SessionInfo,
};
use crate::station::{
    Heartbeat, Intake, Link, POSE_RATE_RANGE_HZ, Poses, Received, Sent, StationError, answered,
    check_rate, sending_rate,
};

/// What [`run_load`] does.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadConfig {
    /// The server.
    pub connect: ConnectConfig,
    /// Session to load; `None` creates one from the server's default scene (and
    /// closes it at the end).
    pub session: Option<String>,
    /// Concurrent stations, ≥ 1.
    pub stations: usize,
    /// Pose rate of each posing station, Hz (finite, > 0).
    pub pose_rate_hz: f64,
    /// How long each station stays once joined.
    pub duration: Duration,
    /// Surface frame rate the stations ask for; `None` for the mechanics rate.
    pub surface_frame_rate_hz: Option<f64>,
    /// Scene of a created session; `None`: the server's default.
    pub scene: Option<String>,
    /// Whether a created session is recorded; `None`: as its scene says.
    pub record: Option<bool>,
}

/// Running totals over all stations, for live display.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadProgress {
    /// Stations joined so far.
    pub joined: u64,
    /// Surface frames received by all stations.
    pub frames: u64,
    /// Instrument states received by all stations.
    pub states: u64,
    /// Poses sent by all stations.
    pub poses_sent: u64,
}

#[derive(Debug, Default)]
struct Counters {
    joined: AtomicU64,
    frames: AtomicU64,
    states: AtomicU64,
    poses_sent: AtomicU64,
}

impl Counters {
    fn snapshot(&self) -> LoadProgress {
        LoadProgress {
            joined: self.joined.load(Ordering::Relaxed),
            frames: self.frames.load(Ordering::Relaxed),
            states: self.states.load(Ordering::Relaxed),
            poses_sent: self.poses_sent.load(Ordering::Relaxed),
        }
    }
}

/// What one station of a load run saw.
#[derive(Clone, Debug)]
struct StationLoad {
    /// The rate it sent poses at, Hz, if it posed: the run's, or the server's
    /// `Joined.max_pose_rate_hz` if lower.
    pose_rate_hz: Option<f64>,
    frames: u64,
    states: u64,
    poses_sent: u64,
    poses_dropped: u64,
    errors: BTreeMap<String, u64>,
    latency: LatencyHistogram,
}

impl StationLoad {
    /// What a station received and sent; a pose is dropped when the queue was full
    /// or the request stream gone.
    fn of(pose_rate_hz: Option<f64>, intake: Intake, poses: &Poses) -> Self {
        StationLoad {
            pose_rate_hz,
            frames: intake.frames,
            states: intake.states,
            poses_sent: poses.sent,
            poses_dropped: poses.full + poses.closed,
            errors: intake.errors,
            latency: intake.latency,
        }
    }
}

/// The result of a load run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadSummary {
    /// Session loaded.
    pub session_id: String,
    /// Whether the run created (and closed) it.
    pub created_session: bool,
    /// Stations started.
    pub stations: usize,
    /// Stations that held an instrument and sent poses.
    pub posing_stations: usize,
    /// Pose rate of each posing station, Hz: the run's, or the server's
    /// `Joined.max_pose_rate_hz` where that is lower.
    pub pose_rate_hz: f64,
    /// Configured duration, s.
    pub seconds: f64,
    /// Surface frames received by each station that completed, in station order.
    pub frames_per_station: Vec<u64>,
    /// Instrument states received by all stations.
    pub states: u64,
    /// Poses sent by all stations.
    pub poses_sent: u64,
    /// Poses dropped by the stations because their outgoing queue was full.
    pub poses_dropped: u64,
    /// Station errors received, by code name.
    pub errors: BTreeMap<String, u64>,
    /// Stations that failed, with why, in station order.
    pub failures: Vec<StationFailure>,
    /// Why the session's own figures (ticks, recorder) are missing: it ended
    /// before the run asked for them.
    pub session_gone: Option<String>,
    /// Pose-to-state latency over all posing stations.
    pub latency: LatencySummary,
    /// The session at the end (`GetSession`): missed mechanics deadlines.
    pub missed_deadlines: u64,
    /// Median mechanics tick wall time, ms.
    pub tick_time_p50_ms: f64,
    /// 99th percentile mechanics tick wall time, ms.
    pub tick_time_p99_ms: f64,
    /// Poses the session accepted since it started.
    pub poses_accepted: u64,
    /// Poses the session rejected since it started.
    pub poses_rejected: u64,
    /// Whether the session was being recorded (it names a file).
    pub recorded: bool,
    /// Items the session's recorder left out (it fell behind).
    pub recorder_dropped: u64,
    /// Most items waiting for the recorder at once.
    pub recorder_max_backlog: u64,
    /// Longest time from a frame's publication to its being written, ms.
    pub recorder_max_lag_ms: f64,
}

/// A station of a load run that failed.
#[derive(Clone, Debug, PartialEq)]
pub struct StationFailure {
    /// The station's index in the run; `None` for a task that ended without
    /// giving its result (it panicked).
    pub station: Option<usize>,
    /// Why, in words.
    pub why: String,
}

impl std::fmt::Display for StationFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.station {
            Some(i) => write!(f, "station {i}: {}", self.why),
            None => write!(f, "a station: {}", self.why),
        }
    }
}

impl LoadSummary {
    /// The failures with one line for each distinct reason, naming the stations
    /// it stopped ("stations 2, 64–9999 (9937): why"), in order of first station:
    /// a thousand stations refused for one reason are one line, not a thousand.
    pub fn failures_by_reason(&self) -> Vec<String> {
        let mut reasons: Vec<(&str, Vec<Option<usize>>)> = Vec::new();
        for failure in &self.failures {
            match reasons.iter_mut().find(|(why, _)| *why == failure.why) {
                Some((_, stations)) => stations.push(failure.station),
                None => reasons.push((&failure.why, vec![failure.station])),
            }
        }
        reasons
            .into_iter()
            .map(|(why, stations)| {
                if let [station] = stations[..] {
                    return StationFailure {
                        station,
                        why: why.to_owned(),
                    }
                    .to_string();
                }
                let mut known: Vec<usize> = stations.iter().flatten().copied().collect();
                known.sort_unstable();
                let mut named = ranges(&known);
                if known.len() < stations.len() {
                    named.push_str(if named.is_empty() { "?" } else { ", ?" });
                }
                format!("stations {named} ({}): {why}", stations.len())
            })
            .collect()
    }

    /// Mean surface frames per completed station.
    pub fn mean_frames(&self) -> f64 {
        if self.frames_per_station.is_empty() {
            0.0
        } else {
            self.frames_per_station.iter().sum::<u64>() as f64
                / self.frames_per_station.len() as f64
        }
    }

    /// The header of the table [`markdown_row`](Self::markdown_row) fills: its two
    /// lines, the names and the alignments, each printed as a line of its own
    /// (a line break within one printed line is escaped, `\n`).
    pub fn markdown_header() -> [&'static str; 2] {
        [
            "| stations | posing | pose Hz | s | frames/station min | mean | latency p50 ms | p99 ms | p99.9 ms | missed deadlines | tick p50 ms | tick p99 ms | poses accepted | rejected | recorded | recorder dropped | recorder backlog max | recorder lag max ms |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|",
        ]
    }

    /// This run as one markdown table row. What the run did not measure is "–",
    /// not 0: the frames when no station finished, the latencies when no pose was
    /// answered, and the session's own figures (ticks, poses, recorder) when the
    /// session ended before the run could ask for them ([`session_gone`]).
    ///
    /// [`session_gone`]: Self::session_gone
    pub fn markdown_row(&self) -> String {
        // `shown()` when `measured`, else "–".
        let cell = |measured: bool, shown: &dyn Fn() -> String| match measured {
            true => shown(),
            false => "–".to_owned(),
        };
        let frames = |f: &dyn Fn() -> String| cell(!self.frames_per_station.is_empty(), f);
        let latency = |ms: f64| cell(self.latency.count > 0, &|| format!("{ms:.2}"));
        let session = |f: &dyn Fn() -> String| cell(self.session_gone.is_none(), f);
        let min = self.frames_per_station.iter().min().copied().unwrap_or(0);
        let cells = [
            self.stations.to_string(),
            self.posing_stations.to_string(),
            self.pose_rate_hz.to_string(),
            self.seconds.to_string(),
            frames(&|| min.to_string()),
            frames(&|| format!("{:.1}", self.mean_frames())),
            latency(self.latency.p50_ms),
            latency(self.latency.p99_ms),
            latency(self.latency.p999_ms),
            session(&|| self.missed_deadlines.to_string()),
            session(&|| format!("{:.2}", self.tick_time_p50_ms)),
            session(&|| format!("{:.2}", self.tick_time_p99_ms)),
            session(&|| self.poses_accepted.to_string()),
            session(&|| self.poses_rejected.to_string()),
            session(&|| if self.recorded { "yes" } else { "no" }.to_owned()),
            session(&|| self.recorder_dropped.to_string()),
            session(&|| self.recorder_max_backlog.to_string()),
            session(&|| format!("{:.2}", self.recorder_max_lag_ms)),
        ];
        format!("| {} |", cells.join(" | "))
    }
}

/// Sorted, distinct indices written as runs: `[0, 2, 3, 4, 9]` as "0, 2–4, 9".
fn ranges(indices: &[usize]) -> String {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for &i in indices {
        match runs.last_mut() {
            Some((_, last)) if *last + 1 == i => *last = i,
            _ => runs.push((i, i)),
        }
    }
    runs.iter()
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}–{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether `stations` more stations fit `session`, by the limit its server states
/// (`SessionInfo.max_stations`, 0 for none). Checked before any station starts:
/// past the limit each join is refused, and a run of hundreds would end in as many
/// failures that bury the figures of the stations that did join.
fn check_room(session: &SessionInfo, stations: usize) -> Result<(), StationError> {
    let connected = session.stations.len();
    let max = session.max_stations;
    if max > 0 && connected.saturating_add(stations) > max as usize {
        return Err(StationError::NoRoom {
            session: session.session_id.clone(),
            asked: stations,
            connected,
            max,
        });
    }
    Ok(())
}

/// Which instrument each of `stations` stations claims: the free instruments of
/// `session` in order, one each, then none.
pub fn assign_instruments(session: &SessionInfo, stations: usize) -> Vec<Option<String>> {
    let mut free = session
        .instruments
        .iter()
        .filter(|h| h.station_id.is_none())
        .map(|h| h.instrument.clone());
    (0..stations).map(|_| free.next()).collect()
}

/// Runs the load test; see the [module documentation](self). `on_progress` is called
/// every second with the running totals.
///
/// Steps: open the session (the named one, or a new one), start one task a station,
/// gather their results while reporting progress, add them up, then read the
/// session's own figures and close the session if this run created it.
pub async fn run_load(
    config: LoadConfig,
    on_progress: impl FnMut(LoadProgress),
) -> Result<LoadSummary, StationError> {
    check_rate("pose rate", config.pose_rate_hz, &POSE_RATE_RANGE_HZ)?;
    let control = connect(&config.connect).await?;
    let mut sessions = control.sessions();
    let (session, created) = open_session(&mut sessions, &config).await?;
    if let Err(e) = check_room(&session, config.stations.max(1)) {
        if created {
            // Best effort: the refusal is the error to report, and an unclosed
            // session ends by its idle timeout.
            let _ = sessions
                .close_session(unary(CloseSessionRequest {
                    session_id: session.session_id.clone(),
                    reason: "load run refused: too many stations".into(),
                }))
                .await;
        }
        return Err(e);
    }
    let session_id = session.session_id.clone();
    let assignment = assign_instruments(&session, config.stations.max(1));
    let posing_stations = assignment.iter().filter(|a| a.is_some()).count();

    let counters = Arc::new(Counters::default());
    let tasks = start_stations(&config, &session_id, assignment, &counters);
    let results = gather(tasks, &counters, on_progress).await;

    let mut summary = LoadSummary {
        session_id: session_id.clone(),
        created_session: created,
        stations: config.stations.max(1),
        posing_stations,
        pose_rate_hz: config.pose_rate_hz,
        seconds: config.duration.as_secs_f64(),
        ..LoadSummary::default()
    };
    add_up(&mut summary, results);
    let info = match sessions
        .get_session(unary(GetSessionRequest {
            session_id: session_id.clone(),
        }))
        .await
    {
        Ok(info) => info.into_inner(),
        // The session ended under the run (closed, the server stopping): what
        // the stations counted and why they stopped is the run's result; the
        // session's own figures are gone with it.
        Err(status) if !summary.failures.is_empty() => {
            summary.session_gone = Some(status.message().to_string());
            return Ok(summary);
        }
        Err(status) => return Err(status.into()),
    };
    summary.missed_deadlines = info.missed_deadlines;
    summary.tick_time_p50_ms = info.tick_time_p50_ms;
    summary.tick_time_p99_ms = info.tick_time_p99_ms;
    summary.poses_accepted = info.poses_accepted;
    summary.poses_rejected = info.poses_rejected;
    summary.recorded = info.recording_file.is_some();
    summary.recorder_dropped = info.recorder_dropped;
    summary.recorder_max_backlog = info.recorder_max_backlog;
    summary.recorder_max_lag_ms = info.recorder_max_lag_ms;
    if created {
        sessions
            .close_session(unary(CloseSessionRequest {
                session_id,
                reason: "load run finished".into(),
            }))
            .await?;
    }
    Ok(summary)
}

/// The session the run loads: the one `config.session` names, or a new one of
/// `config.scene` (then `true`: the run closes it at the end).
async fn open_session(
    sessions: &mut SessionsClient<AuthChannel>,
    config: &LoadConfig,
) -> Result<(SessionInfo, bool), StationError> {
    Ok(match &config.session {
        Some(id) => (
            sessions
                .get_session(unary(GetSessionRequest {
                    session_id: id.clone(),
                }))
                .await?
                .into_inner(),
            false,
        ),
        None => (
            sessions
                .create_session(unary(CreateSessionRequest {
                    scene: config.scene.clone().unwrap_or_default(),
                    idle_timeout_s: None,
                    record: config.record,
                }))
                .await?
                .into_inner(),
            true,
        ),
    })
}

/// A station's result, with its index in the run (`None` for a task that
/// panicked).
type StationResult = (Option<usize>, Result<StationLoad, StationError>);

/// One task a station, each on its own connection, claiming the instrument
/// `assignment` gives it (or none).
fn start_stations(
    config: &LoadConfig,
    session_id: &str,
    assignment: Vec<Option<String>>,
    counters: &Arc<Counters>,
) -> JoinSet<StationResult> {
    let mut tasks = JoinSet::new();
    for (index, instrument) in assignment.into_iter().enumerate() {
        let connect_config = config.connect.clone();
        let open = JoinRequest {
            session_id: session_id.to_string(),
            role: Role::Trainee as i32,
            instruments: instrument.into_iter().collect(),
            surface_frame_rate_hz: config.surface_frame_rate_hz,
            client_name: format!("laparo load station {index}"),
        };
        let counters = Arc::clone(counters);
        let (rate, duration) = (config.pose_rate_hz, config.duration);
        tasks.spawn(async move {
            let result = async {
                let connection = connect(&connect_config).await?;
                load_station(&connection, open, rate, duration, &counters).await
            }
            .await;
            (Some(index), result)
        });
    }
    tasks
}

/// Waits for every station, calling `on_progress` every second with the running
/// totals; the results in station order.
async fn gather(
    mut tasks: JoinSet<StationResult>,
    counters: &Counters,
    mut on_progress: impl FnMut(LoadProgress),
) -> Vec<StationResult> {
    let mut results = Vec::new();
    let mut progress_tick = tokio::time::interval_at(
        tokio::time::Instant::now() + Duration::from_secs(1),
        Duration::from_secs(1),
    );
    progress_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            joined = tasks.join_next() => match joined {
                Some(Ok(result)) => results.push(result),
                Some(Err(e)) => results.push((None, Err(StationError::Protocol(format!("station task failed: {e}"))))),
                None => break,
            },
            _ = progress_tick.tick() => on_progress(counters.snapshot()),
        }
    }
    results.sort_by_key(|(i, _)| *i);
    results
}

/// Adds the stations' counts to `summary`: frames per station, states, poses,
/// errors by code, the latency of the posing stations, and each failure.
fn add_up(summary: &mut LoadSummary, results: Vec<StationResult>) {
    let mut latency = LatencyHistogram::new();
    for (index, result) in results {
        match result {
            Ok(station) => {
                summary.frames_per_station.push(station.frames);
                summary.states += station.states;
                summary.poses_sent += station.poses_sent;
                summary.poses_dropped += station.poses_dropped;
                for (code, n) in station.errors {
                    *summary.errors.entry(code).or_default() += n;
                }
                if let Some(rate) = station.pose_rate_hz {
                    latency.merge(&station.latency);
                    summary.pose_rate_hz = summary.pose_rate_hz.min(rate);
                }
            }
            Err(e) => summary.failures.push(StationFailure {
                station: index,
                why: e.to_string(),
            }),
        }
    }
    summary.latency = latency.summary();
}

/// One station of a load run: join, pose (if granted an instrument) and count for
/// `duration`, then leave; the steps of [`crate::station`], with the default press
/// sent from this task instead of a force loop.
async fn load_station(
    connection: &Connection,
    open: JoinRequest,
    pose_rate_hz: f64,
    duration: Duration,
    counters: &Counters,
) -> Result<StationLoad, StationError> {
    let mut link = answered("the join", CALL_TIMEOUT, Link::join(connection, open)).await?;
    counters.joined.fetch_add(1, Ordering::Relaxed);
    let t0 = Instant::now();
    let scene = link.joined.scene.clone().unwrap_or_default();
    // At most one instrument is claimed.
    let instrument = link.joined.instruments.first().and_then(|name| {
        let description = scene.instruments.iter().find(|d| &d.name == name)?;
        Some((name.clone(), default_press_for(&scene, description)))
    });
    let mut intake = Intake::new(&link.joined.instruments);
    let mut poses = Poses::new();
    // Faster than the server admits, a station would empty its burst allowance,
    // have poses refused and lose its stream, as `laparo station` would.
    let pose_rate_hz = sending_rate(pose_rate_hz, link.joined.max_pose_rate_hz);
    let sent_rate = instrument.as_ref().map(|_| pose_rate_hz);
    let mut pose_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / pose_rate_hz));
    pose_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut heartbeat = Heartbeat::new();
    let deadline = tokio::time::sleep(duration);
    tokio::pin!(deadline);

    loop {
        tokio::select! {
            biased;
            _ = &mut deadline => break,
            message = link.next() => match message? {
                Some(message) => match intake.take(&message, &mut poses)? {
                    Received::Frame => {
                        counters.frames.fetch_add(1, Ordering::Relaxed);
                    }
                    Received::State { .. } => {
                        counters.states.fetch_add(1, Ordering::Relaxed);
                    }
                    Received::Event(_) | Received::Error | Received::Nothing => {}
                },
                // The session closed before the end of the run.
                None => return Ok(StationLoad::of(sent_rate, intake, &poses)),
            },
            _ = heartbeat.due() => heartbeat.beat(&poses, &link.outgoing),
            _ = pose_tick.tick(), if instrument.is_some() => {
                let Some((name, path)) = &instrument else { continue };
                let t = t0.elapsed().as_secs_f64();
                let (tip, axis) = path(t);
                if poses.send(&link.outgoing, name, &tip, &axis, t) == Sent::Queued {
                    counters.poses_sent.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }
    link.leave("load run finished".into()).await;
    Ok(StationLoad::of(sent_rate, intake, &poses))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::v1::InstrumentHolder;

    #[test]
    fn stations_beyond_the_free_instruments_claim_none() {
        let session = SessionInfo {
            instruments: vec![
                InstrumentHolder {
                    instrument: "left".into(),
                    station_id: None,
                },
                InstrumentHolder {
                    instrument: "middle".into(),
                    station_id: Some(4),
                },
                InstrumentHolder {
                    instrument: "right".into(),
                    station_id: None,
                },
            ],
            ..Default::default()
        };
        assert_eq!(
            assign_instruments(&session, 4),
            vec![Some("left".into()), Some("right".into()), None, None]
        );
        assert_eq!(assign_instruments(&session, 1), vec![Some("left".into())]);
    }

    #[test]
    fn markdown_row_has_a_cell_per_header_column() {
        let summary = LoadSummary {
            session_id: "s".into(),
            created_session: true,
            stations: 3,
            posing_stations: 2,
            pose_rate_hz: 250.0,
            seconds: 10.0,
            frames_per_station: vec![600, 590, 601],
            missed_deadlines: 1,
            tick_time_p50_ms: 2.0,
            tick_time_p99_ms: 4.0,
            poses_accepted: 5000,
            recorded: true,
            recorder_max_backlog: 3,
            recorder_max_lag_ms: 0.5,
            ..LoadSummary::default()
        };
        let [names, alignments] = LoadSummary::markdown_header();
        let columns = names.matches('|').count();
        assert_eq!(alignments.matches('|').count(), columns);
        let row = summary.markdown_row();
        assert_eq!(row.matches('|').count(), columns, "{row}");
        assert!(
            row.starts_with("| 3 | 2 | 250 | 10 | 590 | 597.0 |"),
            "{row}"
        );
    }

    #[test]
    fn a_row_without_latency_samples_shows_none_not_zero() {
        let row = LoadSummary::default().markdown_row();
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        // Cells 5–6 are the frames and 7–9 the latency percentiles (cell 0 is
        // before the first bar); the session's figures were asked for.
        assert_eq!(cells[5..10], ["–", "–", "–", "–", "–"], "{row}");
        assert_eq!(
            cells[10..19].join(" "),
            "0 0.00 0.00 0 0 no 0 0 0.00",
            "{row}"
        );
    }

    #[test]
    fn a_row_whose_session_ended_under_it_shows_its_figures_as_unmeasured() {
        // The session closed mid-run: its own figures could not be asked for, and
        // 0 poses accepted or "recorded: no" would say what was not measured.
        let summary = LoadSummary {
            frames_per_station: vec![4620],
            session_gone: Some("session `s1` was closed".into()),
            ..LoadSummary::default()
        };
        let row = summary.markdown_row();
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(cells[5..7], ["4620", "4620.0"], "{row}");
        assert!(cells[10..19].iter().all(|c| *c == "–"), "{row}");
        let [names, _] = LoadSummary::markdown_header();
        assert_eq!(row.matches('|').count(), names.matches('|').count());
    }

    #[test]
    fn failures_are_told_once_per_reason_with_the_stations_it_stopped() {
        let failure = |station, why: &str| StationFailure {
            station,
            why: why.into(),
        };
        let mut failures = vec![failure(Some(1), "the session ended")];
        failures.extend((64..10_000).map(|i| failure(Some(i), "full")));
        failures.push(failure(Some(2), "full"));
        failures.push(failure(None, "full"));
        failures.push(failure(None, "panicked"));
        let summary = LoadSummary {
            failures,
            ..LoadSummary::default()
        };
        assert_eq!(
            summary.failures_by_reason(),
            [
                "station 1: the session ended",
                "stations 2, 64–9999, ? (9938): full",
                "a station: panicked",
            ]
        );
        assert_eq!(ranges(&[0, 2, 3, 4, 9]), "0, 2–4, 9");
        assert_eq!(ranges(&[]), "");
    }

    #[test]
    fn a_run_that_would_overfill_the_session_is_refused_before_it_starts() {
        let session = |connected: usize, max| SessionInfo {
            session_id: "s1".into(),
            stations: vec![Default::default(); connected],
            max_stations: max,
            ..Default::default()
        };
        assert!(check_room(&session(0, 64), 64).is_ok());
        assert!(check_room(&session(60, 64), 4).is_ok());
        // A server that states no limit leaves it to each join.
        assert!(check_room(&session(3, 0), 10_000).is_ok());
        let e = check_room(&session(60, 64), 5).unwrap_err();
        assert_eq!(
            e.to_string(),
            "5 more stations do not fit session `s1`: it takes at most 64 at once and has 60"
        );
        assert!(check_room(&session(0, 64), usize::MAX).is_err());
    }
}
