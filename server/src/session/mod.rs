//! One running scene: its fixed-rate mechanics thread, the poses stations send it, the
//! frames and events it publishes.
//!
//! The mechanics thread ([`mechanics`]) owns the
//! [`Simulation`](crate::engine::simulation::Simulation); nothing else touches
//! it. Poses reach it through one latest-value slot per instrument (a triple buffer:
//! the thread reads the newest without waiting, a station overwrites without
//! waiting). Each tick it publishes a [`Frame`] (made by [`crate::frame`], as a
//! replay makes it) on a `watch` channel — every stream
//! sends the newest it has not sent, so a slow client skips frames and never delays
//! the tick — and events on a `broadcast` channel. The roster (who holds which
//! instrument) is behind a mutex only the network side takes.
//!
//! A recorded session also hands every tick's frame, every event and every accepted
//! pose to its [`Recorder`], which writes them on a thread of its own; handing over
//! never waits, and what the recorder leaves out or fails on is published as an
//! event. The mechanics thread finishes the file when it stops.

pub mod closing;
mod error;
pub mod eviction;
mod halt;
pub mod idle;
pub mod input;
mod mechanics;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use laparo_proto::v1;
use tokio::sync::{broadcast, watch};

use crate::engine::scene::Scene;
use crate::frame::Frame;
use crate::frame::description::description;
use crate::recording::{Item, Recorder, RecorderWatch, Report, SessionHeader};
pub use closing::Closing;
pub use error::SessionError;
pub use eviction::Eviction;
pub use halt::first_fault;
pub use idle::{MAX_IDLE_TIMEOUT_S, idle_timeout};
pub use input::{PoseIn, RateLimit, Rejection, Slot, Workspace, check_pose};

/// How a session runs.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    /// Close after this long with no station and no observer; `None`: never.
    pub idle_timeout: Option<Duration>,
    /// Directory to record the session in (one MCAP file); `None`: not recorded.
    pub recordings: Option<PathBuf>,
}

/// Counters the mechanics thread and the streams keep.
#[derive(Debug, Default)]
pub struct SessionStats {
    pub tick: AtomicU64,
    /// Simulated time, f64 bits.
    pub sim_time_bits: AtomicU64,
    pub missed_deadlines: AtomicU64,
    /// Tick wall-time percentiles over the last second, ms, f64 bits.
    pub tick_p50_bits: AtomicU64,
    pub tick_p99_bits: AtomicU64,
    pub poses_accepted: AtomicU64,
    pub poses_rejected: AtomicU64,
    /// Open station and observe streams.
    pub connected: AtomicU64,
    /// Why the simulation stopped (a non-finite value, or the surface beyond
    /// ±`MAX_COORDINATE_M`), once it has.
    pub simulation_error: OnceLock<String>,
}

/// Who is in the session.
#[derive(Debug, Default)]
pub struct Roster {
    pub stations: BTreeMap<u64, v1::StationInfo>,
    /// Holder station of each instrument, in scene order.
    pub holders: Vec<Option<u64>>,
    pub observers: u32,
    next_station: u64,
    /// Each station's eviction handle ([`eviction`]).
    evictions: BTreeMap<u64, tokio::sync::oneshot::Sender<Eviction>>,
    /// Each instrument's pose-rate bucket as its last holder left it, with the
    /// instant its times count from ([`Session::keep_pose_budget`]).
    pose_budgets: Vec<Option<(input::RateLimit, Instant)>>,
}

/// A running session.
pub struct Session {
    pub id: String,
    pub scene: Scene,
    pub created_at: SystemTime,
    pub description: v1::SceneDescription,
    pub workspace: Workspace,
    pub idle_timeout: Option<Duration>,
    pub stats: Arc<SessionStats>,
    roster: Mutex<Roster>,
    slots: Vec<Mutex<triple_buffer::Input<Slot>>>,
    frames: watch::Receiver<Arc<Frame>>,
    events: broadcast::Sender<v1::Event>,
    closing: Closing,
    stop: Arc<AtomicBool>,
    thread: Mutex<Option<JoinHandle<()>>>,
    recorder: Option<Arc<Recorder>>,
}

/// Events a slow stream may fall behind by before it skips (and is told so).
pub const EVENT_BACKLOG: usize = 1024;

/// How long closing a session (or the server) waits for its mechanics thread: 5 s.
/// The thread stops within one explicit substep or CG iteration of being told (a few
/// ms on the largest mesh), then finishes the recording (writes its last chunk and
/// footer); a thread still busy after that is left to end on its own, so that closing
/// never hangs.
pub const MECHANICS_JOIN_TIMEOUT: Duration = Duration::from_secs(5);

impl Session {
    /// Builds the scene and starts its mechanics thread.
    pub fn start(
        id: String,
        scene: Scene,
        config: &SessionConfig,
    ) -> Result<Arc<Self>, SessionError> {
        let sim = scene.build()?;
        let description = description(&scene, &sim);
        let (lo, hi) = sim.mesh.bounding_box();
        let reach = sim.instruments.iter().map(|i| i.length).fold(0.0, f64::max) + 0.05;
        let workspace = Workspace {
            min: lo - nalgebra::Vector3::repeat(reach),
            max: hi + nalgebra::Vector3::repeat(reach),
        };
        let n = sim.instruments.len();
        let (inputs, outputs): (Vec<_>, Vec<_>) = (0..n)
            .map(|_| triple_buffer::triple_buffer(&Slot::Untouched))
            .unzip();
        let (frame_tx, frames) = watch::channel(Arc::new(Frame::default()));
        let (events, _) = broadcast::channel(EVENT_BACKLOG);
        let stats = Arc::new(SessionStats::default());
        let stop = Arc::new(AtomicBool::new(false));
        let created_at = SystemTime::now();
        let recorder = match &config.recordings {
            Some(dir) => {
                let path = free_recording_path(dir, &id, &scene.name, created_at);
                let header = SessionHeader {
                    session_id: id.clone(),
                    scene_name: scene.name.clone(),
                    scene_toml: scene.text.clone(),
                    scene_dir: scene
                        .base_dir
                        .as_ref()
                        .map(|d| std::path::absolute(d).unwrap_or_else(|_| d.clone())),
                    start: created_at,
                    description: description.clone(),
                };
                let recorder =
                    Recorder::start(path, header).map_err(|source| SessionError::Spawn {
                        thread: "recorder",
                        source,
                    })?;
                Some(Arc::new(recorder))
            }
            None => None,
        };
        let session = Arc::new(Session {
            id,
            created_at,
            description,
            workspace,
            idle_timeout: config.idle_timeout,
            stats: stats.clone(),
            roster: Mutex::new(Roster {
                holders: vec![None; n],
                pose_budgets: vec![None; n],
                ..Roster::default()
            }),
            slots: inputs.into_iter().map(Mutex::new).collect(),
            frames,
            events: events.clone(),
            closing: Closing::new(),
            stop: stop.clone(),
            thread: Mutex::new(None),
            recorder: recorder.clone(),
            scene,
        });
        let weak = Arc::downgrade(&session);
        let thread = mechanics::spawn(mechanics::Mechanics {
            sim,
            inputs: outputs,
            frames: frame_tx,
            events,
            stats,
            stop,
            session: weak,
            recorder,
        })
        .map_err(|source| SessionError::Spawn {
            thread: "mechanics",
            source,
        })?;
        *session.thread.lock().unwrap_or_else(|e| e.into_inner()) = Some(thread);
        Ok(session)
    }

    /// The roster, for the network side.
    pub fn roster(&self) -> MutexGuard<'_, Roster> {
        self.roster.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The index of the instrument called `name`.
    pub fn instrument_index(&self, name: &str) -> Option<usize> {
        self.scene.instruments.iter().position(|i| i.name == name)
    }

    /// Adds a station holding `instruments` (indices, checked free by the caller
    /// under the same roster lock).
    pub fn add_station(
        roster: &mut Roster,
        role: v1::Role,
        client_name: &str,
        instruments: &[usize],
        names: Vec<String>,
    ) -> u64 {
        roster.next_station += 1;
        let id = roster.next_station;
        for &k in instruments {
            roster.holders[k] = Some(id);
        }
        roster.stations.insert(
            id,
            v1::StationInfo {
                station_id: id,
                role: role as i32,
                client_name: client_name.to_string(),
                instruments: names,
                joined_at: Some(SystemTime::now().into()),
            },
        );
        id
    }

    /// Removes a station and withdraws the instruments it held: each is taken out
    /// of the body at the next tick (its held vertices let go, its force zero) and
    /// has no holder until a station claims it again. The withdrawal is written
    /// under the roster lock, so it cannot overwrite the pose of a station that
    /// claims the instrument right after.
    /// Keeps instrument `k`'s pose-rate bucket, its times counted from `since`,
    /// for the next station to claim it: a station that left and joined again
    /// started with a full bucket each time, and a loop of joins sent 663,000
    /// poses a second against a limit of 2,000 (and drowned the recording).
    pub fn keep_pose_budget(&self, k: usize, budget: input::RateLimit, since: Instant) {
        if let Some(slot) = self.roster().pose_budgets.get_mut(k) {
            *slot = Some((budget, since));
        }
    }

    /// Instrument `k`'s pose-rate bucket as its last holder left it, its times
    /// counted from `now`; `None` if no station has held it.
    pub fn take_pose_budget(&self, k: usize, now: Instant) -> Option<input::RateLimit> {
        let (budget, since) = self.roster().pose_budgets.get_mut(k)?.take()?;
        Some(budget.rebased(now.saturating_duration_since(since).as_secs_f64()))
    }

    pub fn remove_station(&self, station: u64) {
        let mut roster = self.roster();
        roster.stations.remove(&station);
        roster.evictions.remove(&station);
        for (k, h) in roster.holders.iter_mut().enumerate() {
            if *h == Some(station) {
                *h = None;
                self.write_slot(k, Slot::Withdrawn);
            }
        }
    }

    /// Hands a checked pose of instrument `k` to the mechanics thread.
    pub fn submit_pose(&self, k: usize, pose: PoseIn) {
        self.write_slot(k, Slot::Pose(pose));
    }

    fn write_slot(&self, k: usize, value: Slot) {
        let mut slot = self.slots[k].lock().unwrap_or_else(|e| e.into_inner());
        slot.write(value);
    }

    /// Hands a pose the station service accepted to the recorder, stamped now.
    pub fn record_pose(&self, pose: &v1::DevicePose) {
        if let Some(r) = &self.recorder {
            let report = r.offer(Item::Pose {
                received: SystemTime::now(),
                pose: pose.clone(),
            });
            self.report(report);
        }
    }

    /// The session's recorder, when it is recorded.
    pub fn recorder(&self) -> Option<&Recorder> {
        self.recorder.as_deref()
    }

    /// A handle on whether the session's recorder still writes its file and why it
    /// failed, that does not keep the recorder alive ([`Recorder::watch`]).
    pub fn recorder_watch(&self) -> Option<RecorderWatch> {
        self.recorder.as_ref().map(|r| r.watch())
    }

    /// Publishes what the recorder asks to tell (to the live streams only: the
    /// recorder notes its own gaps in the file).
    fn report(&self, report: Option<Report>) {
        if let Some(report) = report {
            let _ = self
                .events
                .send(self.event(report.kind(), None, None, report.detail()));
        }
    }

    fn event(
        &self,
        kind: v1::EventKind,
        station: Option<u64>,
        instrument: Option<String>,
        detail: String,
    ) -> v1::Event {
        v1::Event {
            tick: self.stats.tick.load(Ordering::Relaxed),
            sim_time_s: f64::from_bits(self.stats.sim_time_bits.load(Ordering::Relaxed)),
            kind: kind as i32,
            station_id: station,
            instrument,
            detail,
        }
    }

    /// The newest frame and its channel.
    pub fn frames(&self) -> watch::Receiver<Arc<Frame>> {
        self.frames.clone()
    }

    /// The event stream.
    pub fn events(&self) -> broadcast::Receiver<v1::Event> {
        self.events.subscribe()
    }

    /// Publishes an event from the network side, and records it.
    pub fn publish(
        &self,
        kind: v1::EventKind,
        station: Option<u64>,
        instrument: Option<String>,
        detail: String,
    ) {
        let event = self.event(kind, station, instrument, detail);
        broadcast_event(self.recorder.as_deref(), &self.events, event);
    }

    /// Resolves to the reason once the session is closing.
    pub fn closing(&self) -> watch::Receiver<Option<String>> {
        self.closing.watch()
    }

    pub fn is_closed(&self) -> bool {
        self.closing.is_closed()
    }

    /// Closes the session: streams end, the mechanics thread stops. Idempotent.
    pub fn close(&self, reason: &str) {
        if self.closing.close(reason) {
            // A close's or an eviction's reason is a client's text: escaped in the
            // log, sent as it is.
            let printable = laparo_proto::text::printable(reason);
            tracing::info!(session = %self.id, reason = %printable, "session closed");
            self.publish(
                v1::EventKind::SessionClosing,
                None,
                None,
                reason.to_string(),
            );
            self.stop.store(true, Ordering::Relaxed);
        }
    }

    /// Waits for the mechanics thread to end (after [`close`](Self::close)), at most
    /// [`MECHANICS_JOIN_TIMEOUT`]; whether it ended.
    pub fn join(&self) -> bool {
        self.join_until(Instant::now() + MECHANICS_JOIN_TIMEOUT)
    }

    /// Waits for the mechanics thread to end until `deadline`; whether it ended. A
    /// thread still running then is left to end on its own (it has been told to stop).
    pub fn join_until(&self, deadline: Instant) -> bool {
        let mut slot = self.thread.lock().unwrap_or_else(|e| e.into_inner());
        let Some(t) = slot.as_ref() else {
            return true;
        };
        while !t.is_finished() {
            if Instant::now() >= deadline {
                tracing::warn!(
                    session = %self.id,
                    "the mechanics thread has not stopped yet; not waiting for it"
                );
                return false;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        if let Some(t) = slot.take() {
            let _ = t.join();
        }
        true
    }

    /// The session as the contract describes it.
    pub fn info(&self) -> v1::SessionInfo {
        let roster = self.roster();
        let s = &self.stats;
        let bits = |a: &AtomicU64| f64::from_bits(a.load(Ordering::Relaxed));
        let recorder = |f: fn(&crate::recording::RecorderStats) -> u64| {
            self.recorder.as_ref().map_or(0, |r| f(r.stats()))
        };
        v1::SessionInfo {
            session_id: self.id.clone(),
            scene: self.scene.name.clone(),
            created_at: Some(self.created_at.into()),
            tick: s.tick.load(Ordering::Relaxed),
            sim_time_s: bits(&s.sim_time_bits),
            stations: roster.stations.values().cloned().collect(),
            instruments: self
                .scene
                .instruments
                .iter()
                .zip(&roster.holders)
                .map(|(i, h)| v1::InstrumentHolder {
                    instrument: i.name.clone(),
                    station_id: *h,
                })
                .collect(),
            observer_count: roster.observers,
            idle_timeout_s: self.idle_timeout.map(|d| d.as_secs_f64()),
            recording_file: self
                .recorder
                .as_ref()
                .filter(|r| r.error().is_none() || r.created_file())
                .and_then(|r| r.path().file_name())
                .map(|f| f.to_string_lossy().into_owned()),
            missed_deadlines: s.missed_deadlines.load(Ordering::Relaxed),
            tick_time_p50_ms: bits(&s.tick_p50_bits),
            tick_time_p99_ms: bits(&s.tick_p99_bits),
            poses_accepted: s.poses_accepted.load(Ordering::Relaxed),
            poses_rejected: s.poses_rejected.load(Ordering::Relaxed),
            recording_error: self.recorder.as_ref().and_then(|r| r.error()),
            recorder_dropped: recorder(|r| r.dropped.load(Ordering::Relaxed)),
            recorder_max_backlog: recorder(|r| r.max_backlog.load(Ordering::Relaxed)),
            recorder_max_lag_ms: recorder(|r| r.max_lag_us.load(Ordering::Relaxed)) as f64 * 1e-3,
            simulation_error: s.simulation_error.get().cloned(),
            // The service's limit, which it fills in (`service::sessions`).
            max_stations: 0,
        }
    }

    /// What a station or observer arriving now is told about the recording
    /// before anything else: whether it stopped, whether items were left out. Live
    /// streams were told when it happened.
    pub fn recording_events(&self) -> Vec<v1::Event> {
        let Some(r) = &self.recorder else {
            return Vec::new();
        };
        r.standing_reports()
            .into_iter()
            .map(|report| self.event(report.kind(), None, None, report.detail()))
            .collect()
    }

    /// Counts a stream as connected until the guard drops.
    pub fn connect(self: &Arc<Self>) -> Connected {
        self.stats.connected.fetch_add(1, Ordering::Relaxed);
        Connected(self.clone())
    }
}

/// `<session id>-<scene>-<unix time s>.mcap`, with anything but letters, digits,
/// `-` and `_` in the scene's name replaced by `_`, and the scene's part cut to its
/// first [`MAX_SCENE_IN_FILE_NAME`] characters.
pub fn recording_file_name(id: &str, scene: &str, created_at: SystemTime) -> String {
    let scene: String = scene
        .chars()
        .take(MAX_SCENE_IN_FILE_NAME)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let unix = created_at
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!("{id}-{scene}-{unix}.mcap")
}

/// Where a session's recording goes: `dir` joined with [`recording_file_name`], or,
/// when a file of that name is there already, the same name with `-2`, `-3`, …
/// before `.mcap`. Session ids start again at `s1` when a server restarts, so a
/// session created within a second of the last one's `s1` would otherwise take its
/// name, and the recorder (which creates its file new, never over another) would
/// fail. Two servers sharing a directory can still race for one name within the
/// same instant; the later then reports that it cannot create the file, and its
/// session goes on unrecorded.
pub fn free_recording_path(dir: &Path, id: &str, scene: &str, created_at: SystemTime) -> PathBuf {
    let name = recording_file_name(id, scene, created_at);
    let first = dir.join(&name);
    let stem = name.trim_end_matches(".mcap");
    let taken = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    std::iter::once(first.clone())
        .chain((2..=MAX_NAME_SUFFIX).map(|k| dir.join(format!("{stem}-{k}.mcap"))))
        .find(|p| !taken(p))
        .unwrap_or(first)
}

/// Most characters of the scene's name in a recording's file name (each one byte
/// once replaced). A file name holds at most 255 bytes: a scene named with 256
/// (the most a scene may have) made one of 275, the recorder could not create it,
/// and the session, which had answered that it records, went on unrecorded. With
/// 128, the id (a server's `s` and a count), the time (at most 20 digits), a `-k`
/// suffix and the dashes and `.mcap` stay under 200. The recording holds the whole
/// name.
pub const MAX_SCENE_IN_FILE_NAME: usize = 128;

/// Most `-k` suffixes tried for a free recording name; past it the first name is
/// used and its creation fails as it says.
const MAX_NAME_SUFFIX: u32 = 1000;

/// Publishes `event` to the session's streams and offers it to the recorder; what
/// the recorder reports (falling behind, failing) is published too, stamped like the
/// event. Shared by the mechanics thread and the network side.
fn broadcast_event(
    recorder: Option<&Recorder>,
    events: &broadcast::Sender<v1::Event>,
    event: v1::Event,
) {
    if let Some(r) = recorder {
        let wall = SystemTime::now();
        let offered = r.offer(Item::Event {
            event: event.clone(),
            wall,
        });
        if let Some(report) = offered {
            let _ = events.send(report.event(event.tick, event.sim_time_s));
        }
    }
    let _ = events.send(event);
}

/// A stream connected to a session (see [`Session::connect`]).
pub struct Connected(Arc<Session>);

impl Drop for Connected {
    fn drop(&mut self) {
        self.0.stats.connected.fetch_sub(1, Ordering::Relaxed);
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests;
