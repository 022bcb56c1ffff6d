//! A trainee station: joins a session, drives its instruments with simulated devices
//! through force loops, and measures what it receives.
//!
//! [`run_station`] opens a `Station.Join` stream, claims the configured instruments
//! and, for each one the server grants, runs a [`ForceLoop`] on its own thread with a
//! [`ScriptedDevice`] following the configured gesture (by default
//! [`default_press`](crate::gestures::default_press) on the rest-surface vertex nearest the instrument's trocar). One
//! tokio task then:
//!
//! - every `1/pose_rate_hz` s reads each loop's newest device pose from its
//!   [`PoseOutbox`] and sends it as a `DevicePose`, numbered by one increasing
//!   sequence shared by all the station's instruments, remembering the send time of
//!   each sequence number ([`SendTimes`]);
//! - turns the `local_model` of every `InstrumentState` of its instruments into a
//!   [`LocalModel`] and writes it to that loop's [`ModelInbox`] (a missing or invalid
//!   model is counted and skipped: the loop keeps blending the last good one);
//! - records the pose-to-state latency: when a state's `pose_sequence` is new for the
//!   instrument, now − send time of that sequence;
//! - publishes a [`StationProgress`] on a watch channel for live display.
//!
//! It ends when the configured duration has elapsed or the stop future completes
//! (it then sends `Leave` and lets the server end the stream), or when the server
//! ends the stream: normally (for example after `SESSION_CLOSING`), and the summary
//! says so, or with a gRPC status, returned as [`StationError::Status`].

use std::collections::{BTreeMap, HashMap};
use std::future::Future;
use std::pin::Pin;
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, watch};
use tokio::time::MissedTickBehavior;
use tokio_stream::wrappers::ReceiverStream;
use tonic::Streaming;

use crate::connect::{ConnectConfig, ConnectError, connect};
use crate::haptics::{
    ConfigError, ForceLoop, ForceLoopConfig, ForceLoopHandle, LoopStats, ModelInbox, PoseOutbox,
    ScriptedDevice, Trajectory,
};
use crate::latency::{LatencyHistogram, LatencySummary, SendTimes};
use crate::proto::force::{LocalModel, wire};
use crate::proto::v1::{
    self, ErrorCode, InstrumentDescription, InstrumentState, JoinRequest, Joined, Leave, Role,
    SceneDescription, ServerMessage, StationMessage, server_message, station_message,
};

use crate::gestures::{default_press_for, trocar};

/// Default rate at which device poses are sent, Hz.
pub const DEFAULT_POSE_RATE_HZ: f64 = 250.0;
/// Largest force the simulated devices render, N.
pub const DEVICE_MAX_FORCE_N: f64 = 10.0;
/// Sequence numbers whose send time is remembered: several seconds of poses at
/// 250 Hz for a few instruments.
pub const SEND_TIMES_CAPACITY: usize = 4096;
/// Depth of the queue of outgoing messages. When the network cannot take the poses
/// as fast as they are sampled, newer poses are dropped (and counted) rather than
/// queued: a queued pose is a stale pose.
pub const OUTGOING_QUEUE: usize = 64;
/// How long to wait for the server to end the stream after `Leave`.
pub const LEAVE_GRACE: Duration = Duration::from_secs(2);
/// How often [`StationProgress`] is published.
pub const PROGRESS_PERIOD: Duration = Duration::from_millis(100);

/// Makes the gesture of an instrument once the scene is known.
pub type GestureFn =
    Box<dyn Fn(&SceneDescription, &InstrumentDescription) -> Trajectory + Send + Sync>;

/// A future that stops the station when it completes (for example Ctrl-C).
pub type StopSignal = Pin<Box<dyn Future<Output = ()> + Send>>;

/// Called with every event of the session, as it arrives.
pub type EventSink = Box<dyn FnMut(&v1::Event) + Send>;

/// Completes after `duration`, or never without one.
pub(crate) async fn after(duration: Option<Duration>) {
    match duration {
        Some(d) => tokio::time::sleep(d).await,
        None => std::future::pending().await,
    }
}

/// Completes with `stop`, or never without one.
pub(crate) async fn when_stopped(stop: Option<StopSignal>) {
    match stop {
        Some(f) => f.await,
        None => std::future::pending().await,
    }
}

/// What [`run_station`] does.
pub struct StationConfig {
    /// The server.
    pub connect: ConnectConfig,
    /// Session to join.
    pub session_id: String,
    /// Instruments to claim, by name.
    pub instruments: Vec<String>,
    /// The station's role.
    pub role: Role,
    /// Client name sent in the `JoinRequest`.
    pub client_name: String,
    /// Rate at which device poses are sent, Hz (finite, > 0).
    pub pose_rate_hz: f64,
    /// Haptic rate of the force loops, Hz (see [`crate::haptics::force_loop`]).
    pub haptic_rate_hz: f64,
    /// Surface frame rate to ask for; `None` for the mechanics rate.
    pub surface_frame_rate_hz: Option<f64>,
    /// How long to stay; `None` until stopped or the server ends the stream.
    pub duration: Option<Duration>,
    /// The gesture of each instrument; `None` for [`default_press_for`].
    pub gesture: Option<GestureFn>,
    /// Receives a [`StationProgress`] every [`PROGRESS_PERIOD`].
    pub progress: Option<watch::Sender<StationProgress>>,
    /// Receives every event.
    pub on_event: Option<EventSink>,
    /// Stops the station (as the duration would) when it completes.
    pub stop: Option<StopSignal>,
}

impl StationConfig {
    /// A trainee station at `url` joining `session_id` with `instruments`, default
    /// rates, until stopped.
    pub fn new(
        url: impl Into<String>,
        session_id: impl Into<String>,
        instruments: Vec<String>,
    ) -> Self {
        StationConfig {
            connect: ConnectConfig::new(url),
            session_id: session_id.into(),
            instruments,
            role: Role::Trainee,
            client_name: "laparo station".into(),
            pose_rate_hz: DEFAULT_POSE_RATE_HZ,
            haptic_rate_hz: crate::haptics::force_loop::DEFAULT_RATE_HZ,
            surface_frame_rate_hz: None,
            duration: None,
            gesture: None,
            progress: None,
            on_event: None,
            stop: None,
        }
    }
}

impl std::fmt::Debug for StationConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StationConfig")
            .field("connect", &self.connect)
            .field("session_id", &self.session_id)
            .field("instruments", &self.instruments)
            .field("pose_rate_hz", &self.pose_rate_hz)
            .field("haptic_rate_hz", &self.haptic_rate_hz)
            .field("duration", &self.duration)
            .finish_non_exhaustive()
    }
}

/// Why a station could not run.
#[derive(Debug, thiserror::Error)]
pub enum StationError {
    /// The server could not be reached.
    #[error(transparent)]
    Connect(#[from] ConnectError),
    /// The server ended the call with a gRPC status.
    #[error("the server ended the stream with {code:?}: {message}")]
    Status { code: tonic::Code, message: String },
    /// The server broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A rate out of range.
    #[error("{field} = {value} Hz is out of range (expected {expected})")]
    Rate {
        field: &'static str,
        value: f64,
        expected: &'static str,
    },
    /// The force loop configuration was refused.
    #[error(transparent)]
    ForceLoop(#[from] ConfigError),
}

impl From<tonic::Status> for StationError {
    fn from(status: tonic::Status) -> Self {
        StationError::Status {
            code: status.code(),
            message: status.message().to_owned(),
        }
    }
}

/// Live figures of a running station.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StationProgress {
    /// Wall time since the station joined, s.
    pub elapsed_s: f64,
    /// Newest mechanics tick received.
    pub tick: u64,
    /// Simulated time of that tick, s.
    pub sim_time_s: f64,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received (all instruments).
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Station errors received.
    pub errors: u64,
    /// Device poses sent.
    pub poses_sent: u64,
    /// Server force |F| on each granted instrument at the newest state, N, in the
    /// order of [`StationSummary::instruments`].
    pub forces_n: Vec<(String, f64)>,
    /// Achieved haptic rate of each force loop, Hz, same order.
    pub haptic_rates_hz: Vec<f64>,
    /// Median pose-to-state latency so far, ms.
    pub latency_p50_ms: f64,
    /// 99th percentile pose-to-state latency so far, ms.
    pub latency_p99_ms: f64,
    /// Local models missing or invalid, skipped.
    pub models_invalid: u64,
}

/// How a station run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StationEnd {
    /// The configured duration elapsed.
    Duration,
    /// The stop signal completed.
    Stopped,
    /// The server ended the stream normally.
    ServerClosed,
}

/// The figures of one instrument at the end.
#[derive(Clone, Debug, PartialEq)]
pub struct InstrumentSummary {
    /// Instrument name.
    pub name: String,
    /// Local models written to the force loop.
    pub models_applied: u64,
    /// Local models missing or invalid, skipped.
    pub models_invalid: u64,
    /// Largest server force |F| received, N.
    pub max_force_n: f64,
    /// The force loop's final figures.
    pub loop_stats: LoopStats,
}

/// What a station run saw.
#[derive(Clone, Debug, PartialEq)]
pub struct StationSummary {
    /// Id the server gave the station.
    pub station_id: u64,
    /// Session joined.
    pub session_id: String,
    /// Instruments granted (the others were refused with a station error).
    pub instruments: Vec<String>,
    /// How the run ended.
    pub end: StationEnd,
    /// Wall time from joining to the end, s.
    pub elapsed_s: f64,
    /// Distinct mechanics ticks seen (in frames or states).
    pub ticks: u64,
    /// Newest mechanics tick seen.
    pub last_tick: u64,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received (all instruments).
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Station errors received, by code name.
    pub errors: BTreeMap<String, u64>,
    /// Device poses sent.
    pub poses_sent: u64,
    /// Device poses dropped because the outgoing queue was full.
    pub poses_dropped: u64,
    /// Largest server force |F| on any granted instrument, N.
    pub max_force_n: f64,
    /// Pose-to-state latency.
    pub latency: LatencySummary,
    /// Per granted instrument.
    pub per_instrument: Vec<InstrumentSummary>,
}

/// One granted instrument: its force loop and what the network side knows of it.
struct Instrument {
    name: String,
    inbox: ModelInbox,
    /// Offset of the force loop's haptic clock on the station clock, s.
    clock_offset_s: f64,
    outbox: PoseOutbox,
    handle: Option<ForceLoopHandle<ScriptedDevice>>,
    models: ModelIntake,
    force_n: f64,
    max_force_n: f64,
    last_pose_sequence: Option<u64>,
}

/// Turns the local models of an instrument's states into [`LocalModel`]s for its
/// force loop, counting those that cannot be used.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ModelIntake {
    /// Models written to the inbox.
    pub applied: u64,
    /// Models missing or invalid, skipped.
    pub invalid: u64,
}

impl ModelIntake {
    /// Writes the state's local model to `inbox` if it is valid, counts it otherwise.
    /// Returns the model written.
    pub fn take(&mut self, state: &InstrumentState, inbox: &mut ModelInbox) -> Option<LocalModel> {
        let converted = state
            .local_model
            .as_ref()
            .ok_or(wire::WireError::Missing("local_model"))
            .and_then(LocalModel::try_from);
        match converted {
            Ok(model) => {
                inbox.write(model);
                self.applied += 1;
                Some(model)
            }
            Err(e) => {
                self.invalid += 1;
                tracing::debug!(
                    instrument = %state.instrument,
                    tick = state.tick,
                    "local model skipped: {e}"
                );
                None
            }
        }
    }
}

fn check_rate(
    field: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), StationError> {
    if ok {
        Ok(())
    } else {
        Err(StationError::Rate {
            field,
            value,
            expected,
        })
    }
}

/// An open `Join` stream: the sender of station messages and the server's stream,
/// after `Joined`.
pub(crate) struct JoinedStream {
    pub outgoing: mpsc::Sender<StationMessage>,
    pub incoming: Streaming<ServerMessage>,
    pub joined: Joined,
}

/// Opens a `Join` stream with `open` and waits for `Joined`.
pub(crate) async fn join(
    connection: &crate::connect::Connection,
    open: JoinRequest,
) -> Result<JoinedStream, StationError> {
    let (outgoing, rx) = mpsc::channel(OUTGOING_QUEUE);
    outgoing
        .try_send(StationMessage {
            kind: Some(station_message::Kind::Open(open)),
        })
        .expect("a new channel has room for the first message");
    let mut incoming = connection
        .station()
        .join(ReceiverStream::new(rx))
        .await?
        .into_inner();
    match incoming.message().await? {
        Some(ServerMessage {
            kind: Some(server_message::Kind::Joined(joined)),
        }) => Ok(JoinedStream {
            outgoing,
            incoming,
            joined,
        }),
        Some(other) => Err(StationError::Protocol(format!(
            "expected Joined as the first server message, got {:?}",
            other.kind.as_ref().map(kind_name)
        ))),
        None => Err(StationError::Protocol(
            "the server ended the stream before Joined".into(),
        )),
    }
}

/// The name of a server message kind, for errors.
pub(crate) fn kind_name(kind: &server_message::Kind) -> &'static str {
    match kind {
        server_message::Kind::Joined(_) => "Joined",
        server_message::Kind::SurfaceFrame(_) => "SurfaceFrame",
        server_message::Kind::InstrumentState(_) => "InstrumentState",
        server_message::Kind::Event(_) => "Event",
        server_message::Kind::Error(_) => "StationError",
    }
}

/// The name of a station error code, as the contract spells it.
pub(crate) fn error_code_name(code: i32) -> String {
    ErrorCode::try_from(code)
        .map(|c| c.as_str_name().to_owned())
        .unwrap_or_else(|_| format!("UNKNOWN_{code}"))
}

/// The magnitude of a state's server force, N; 0 when absent or not finite.
pub(crate) fn force_magnitude(state: &InstrumentState) -> f64 {
    state
        .force
        .as_ref()
        .and_then(|f| wire::vector(f.force.as_ref(), "force.force").ok())
        .map_or(0.0, |f| f.norm())
}

/// Counts distinct mechanics ticks.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct TickCounter {
    pub ticks: u64,
    pub last: Option<u64>,
    pub sim_time_s: f64,
}

impl TickCounter {
    pub fn see(&mut self, tick: u64, sim_time_s: f64) {
        if self.last.is_none_or(|last| tick > last) {
            self.ticks += 1;
            self.last = Some(tick);
            self.sim_time_s = sim_time_s;
        }
    }
}

/// Joins the session, drives the granted instruments and returns what was seen; see
/// the [module documentation](self).
pub async fn run_station(mut config: StationConfig) -> Result<StationSummary, StationError> {
    check_rate(
        "pose rate",
        config.pose_rate_hz,
        config.pose_rate_hz.is_finite() && config.pose_rate_hz > 0.0,
        "finite and > 0",
    )?;
    check_rate(
        "haptic rate",
        config.haptic_rate_hz,
        crate::haptics::force_loop::RATE_RANGE_HZ.contains(&config.haptic_rate_hz),
        "between 300 and 4000",
    )?;
    let connection = connect(&config.connect).await?;
    let open = JoinRequest {
        session_id: config.session_id.clone(),
        role: config.role as i32,
        instruments: config.instruments.clone(),
        surface_frame_rate_hz: config.surface_frame_rate_hz,
        client_name: config.client_name.clone(),
    };
    let JoinedStream {
        outgoing,
        mut incoming,
        joined,
    } = join(&connection, open).await?;
    let t0 = Instant::now();
    let scene = joined.scene.clone().unwrap_or_default();
    tracing::info!(
        station_id = joined.station_id,
        session = %joined.session_id,
        granted = ?joined.instruments,
        "joined"
    );

    let mut instruments = Vec::new();
    for name in &joined.instruments {
        let Some(description) = scene.instruments.iter().find(|d| &d.name == name) else {
            return Err(StationError::Protocol(format!(
                "instrument {name:?} was granted but is not in the scene"
            )));
        };
        let path = match &config.gesture {
            Some(gesture) => gesture(&scene, description),
            None => default_press_for(&scene, description),
        };
        let device = ScriptedDevice::new(path, DEVICE_MAX_FORCE_N, 16);
        let loop_config = ForceLoopConfig {
            rate_hz: config.haptic_rate_hz,
            ..ForceLoopConfig::new(trocar(description))
        };
        let (force_loop, inbox, outbox) = ForceLoop::new(loop_config, device)?;
        let clock_offset_s = t0.elapsed().as_secs_f64();
        instruments.push(Instrument {
            name: name.clone(),
            inbox,
            clock_offset_s,
            outbox,
            handle: Some(force_loop.spawn()),
            models: ModelIntake::default(),
            force_n: 0.0,
            max_force_n: 0.0,
            last_pose_sequence: None,
        });
    }
    let by_name: HashMap<String, usize> = instruments
        .iter()
        .enumerate()
        .map(|(i, inst)| (inst.name.clone(), i))
        .collect();

    let mut summary = StationSummary {
        station_id: joined.station_id,
        session_id: joined.session_id.clone(),
        instruments: joined.instruments.clone(),
        end: StationEnd::Duration,
        elapsed_s: 0.0,
        ticks: 0,
        last_tick: joined.tick,
        frames: 0,
        states: 0,
        events: 0,
        errors: BTreeMap::new(),
        poses_sent: 0,
        poses_dropped: 0,
        max_force_n: 0.0,
        latency: LatencySummary::default(),
        per_instrument: Vec::new(),
    };
    let mut ticks = TickCounter::default();
    let mut send_times = SendTimes::new(SEND_TIMES_CAPACITY);
    let mut latency = LatencyHistogram::new();
    let mut sequence: u64 = 0;

    let mut pose_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / config.pose_rate_hz));
    pose_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut progress_tick = tokio::time::interval(PROGRESS_PERIOD);
    progress_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let duration = config.duration;
    let deadline = after(duration);
    tokio::pin!(deadline);
    let stop = when_stopped(config.stop.take());
    tokio::pin!(stop);

    let end = loop {
        tokio::select! {
            biased;
            _ = &mut stop => break StationEnd::Stopped,
            _ = &mut deadline => break StationEnd::Duration,
            message = incoming.message() => match message {
                Ok(Some(message)) => {
                    let Some(kind) = message.kind else { continue };
                    match kind {
                        server_message::Kind::SurfaceFrame(frame) => {
                            summary.frames += 1;
                            ticks.see(frame.tick, frame.sim_time_s);
                        }
                        server_message::Kind::InstrumentState(state) => {
                            summary.states += 1;
                            ticks.see(state.tick, state.sim_time_s);
                            let now = Instant::now();
                            if let Some(&i) = by_name.get(&state.instrument) {
                                let inst = &mut instruments[i];
                                inst.models.take(&state, &mut inst.inbox);
                                inst.force_n = force_magnitude(&state);
                                inst.max_force_n = inst.max_force_n.max(inst.force_n);
                                let new_pose = state
                                    .pose_sequence
                                    .filter(|&s| inst.last_pose_sequence.is_none_or(|last| s > last));
                                if let Some(s) = new_pose {
                                    inst.last_pose_sequence = Some(s);
                                    if let Some(sent) = send_times.take(s) {
                                        latency.record(now - sent);
                                    }
                                }
                            }
                        }
                        server_message::Kind::Event(event) => {
                            summary.events += 1;
                            if let Some(on_event) = config.on_event.as_mut() {
                                on_event(&event);
                            }
                        }
                        server_message::Kind::Error(error) => {
                            tracing::debug!(code = error.code, "station error: {}", error.message);
                            *summary.errors.entry(error_code_name(error.code)).or_default() += 1;
                        }
                        server_message::Kind::Joined(_) => {
                            return Err(StationError::Protocol(
                                "Joined received twice".into(),
                            ));
                        }
                    }
                }
                Ok(None) => break StationEnd::ServerClosed,
                Err(status) => return Err(status.into()),
            },
            _ = pose_tick.tick() => {
                for inst in &mut instruments {
                    let Some(pose) = inst.outbox.latest() else { continue };
                    sequence += 1;
                    let message = StationMessage {
                        kind: Some(station_message::Kind::Pose(v1::DevicePose {
                            instrument: inst.name.clone(),
                            pose: Some(wire::to_pose(&pose.tip, &pose.axis)),
                            device_time_s: inst.clock_offset_s + pose.time,
                            sequence,
                        })),
                    };
                    match outgoing.try_send(message) {
                        Ok(()) => {
                            send_times.record(sequence, Instant::now());
                            summary.poses_sent += 1;
                        }
                        Err(mpsc::error::TrySendError::Full(_)) => summary.poses_dropped += 1,
                        // The request stream was dropped: the call is ending and the
                        // server's stream will say how.
                        Err(mpsc::error::TrySendError::Closed(_)) => {}
                    }
                }
            }
            _ = progress_tick.tick() => {
                if let Some(progress) = &config.progress {
                    let lat = latency.summary();
                    let value = StationProgress {
                        elapsed_s: t0.elapsed().as_secs_f64(),
                        tick: ticks.last.unwrap_or(joined.tick),
                        sim_time_s: ticks.sim_time_s,
                        frames: summary.frames,
                        states: summary.states,
                        events: summary.events,
                        errors: summary.errors.values().sum(),
                        poses_sent: summary.poses_sent,
                        forces_n: instruments.iter().map(|i| (i.name.clone(), i.force_n)).collect(),
                        haptic_rates_hz: instruments
                            .iter_mut()
                            .map(|i| i.handle.as_mut().map_or(0.0, |h| h.stats().rate_hz))
                            .collect(),
                        latency_p50_ms: lat.p50_ms,
                        latency_p99_ms: lat.p99_ms,
                        models_invalid: instruments.iter().map(|i| i.models.invalid).sum(),
                    };
                    progress.send_replace(value);
                }
            }
        }
    };

    if end != StationEnd::ServerClosed {
        let _ = outgoing.try_send(StationMessage {
            kind: Some(station_message::Kind::Leave(Leave {
                reason: match end {
                    StationEnd::Duration => "duration elapsed".into(),
                    _ => "stopped".into(),
                },
            })),
        });
        drop(outgoing);
        // The server ends the stream after Leave; whatever it says meanwhile, or a
        // status it ends with, no longer matters to this run.
        let _ = tokio::time::timeout(LEAVE_GRACE, async {
            while let Ok(Some(_)) = incoming.message().await {}
        })
        .await;
    }

    summary.end = end;
    summary.elapsed_s = t0.elapsed().as_secs_f64();
    summary.ticks = ticks.ticks;
    summary.last_tick = ticks.last.unwrap_or(joined.tick);
    summary.latency = latency.summary();
    for mut inst in instruments {
        let loop_stats = inst
            .handle
            .take()
            .map_or_else(LoopStats::default, |h| h.stop().1);
        summary.max_force_n = summary.max_force_n.max(inst.max_force_n);
        summary.per_instrument.push(InstrumentSummary {
            name: inst.name,
            models_applied: inst.models.applied,
            models_invalid: inst.models.invalid,
            max_force_n: inst.max_force_n,
            loop_stats,
        });
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::*;

    fn state(model: Option<v1::LocalModel>) -> InstrumentState {
        InstrumentState {
            instrument: "left".into(),
            tick: 7,
            local_model: model,
            ..Default::default()
        }
    }

    fn good_model() -> v1::LocalModel {
        let m = LocalModel::free(7, 7.0 / 60.0, Point3::origin(), Vector3::z_axis());
        v1::LocalModel::from(&m)
    }

    #[test]
    fn invalid_and_missing_models_are_counted_and_skipped() {
        let device = ScriptedDevice::fixed(Point3::origin(), Vector3::z_axis(), 1.0, 1);
        let (mut force_loop, mut inbox, _outbox) =
            ForceLoop::new(ForceLoopConfig::new(Point3::new(0.0, 0.0, 0.1)), device).unwrap();
        let mut intake = ModelIntake::default();

        let mut bad = good_model();
        bad.pose.as_mut().unwrap().axis.as_mut().unwrap().z = f64::NAN;
        assert_eq!(intake.take(&state(Some(bad)), &mut inbox), None);
        assert_eq!(intake.take(&state(None), &mut inbox), None);
        assert_eq!(
            intake,
            ModelIntake {
                applied: 0,
                invalid: 2
            }
        );
        force_loop.tick(0.0);
        assert_eq!(
            force_loop.stats().models_received,
            0,
            "nothing reached the loop"
        );

        assert!(
            intake
                .take(&state(Some(good_model())), &mut inbox)
                .is_some()
        );
        assert_eq!(intake.applied, 1);
        force_loop.tick(0.001);
        assert_eq!(force_loop.stats().models_received, 1);
    }

    #[test]
    fn error_codes_are_named_as_in_the_contract() {
        assert_eq!(
            error_code_name(ErrorCode::OutOfOrder as i32),
            "ERROR_CODE_OUT_OF_ORDER"
        );
        assert_eq!(error_code_name(999), "UNKNOWN_999");
    }

    #[test]
    fn ticks_are_counted_once_each() {
        let mut t = TickCounter::default();
        for tick in [3, 3, 4, 4, 2, 5] {
            t.see(tick, tick as f64);
        }
        assert_eq!((t.ticks, t.last), (3, Some(5)));
    }

    #[test]
    fn a_status_keeps_its_code_and_message() {
        let e = StationError::from(tonic::Status::not_found("no session \"x\""));
        assert!(matches!(
            &e,
            StationError::Status { code: tonic::Code::NotFound, message } if message == "no session \"x\""
        ));
    }
}
