//! A trainee station: joins a session, drives its instruments with simulated devices
//! through force loops, and measures what it receives.
//!
//! [`run_station`] goes through named steps:
//!
//! 1. join (`link`): open a `Station.Join` stream claiming the configured
//!    instruments and wait for `Joined`;
//! 2. start (`instruments`): for each instrument granted, a
//!    [`ForceLoop`](crate::haptics::ForceLoop) on its own thread with a
//!    [`ScriptedDevice`](crate::haptics::ScriptedDevice) following the configured gesture (by
//!    default [`default_press`](crate::gestures::default_press) on the rest-surface
//!    vertex nearest the instrument's trocar);
//! 3. run, in one tokio task, until the configured duration has elapsed, the stop
//!    future completes, or the server ends the stream:
//!    - intake of server messages (`intake`): every message counted, the
//!      `local_model` of every `InstrumentState` of its instruments turned into a
//!      [`LocalModel`](crate::proto::force::LocalModel) and written to that loop's
//!      [`ModelInbox`](crate::haptics::ModelInbox) (a missing or invalid model is
//!      counted and skipped: the loop keeps blending the last good one), and the
//!      pose-to-state latency measured;
//!    - sending poses (`poses`): every `1/pose_rate_hz` s, each loop's newest
//!      device pose as a `DevicePose`, numbered by one increasing sequence shared by
//!      all the station's instruments;
//!    - progress: a [`StationProgress`] on a watch channel every
//!      [`PROGRESS_PERIOD`], for live display;
//!    - a `Heartbeat` (`heartbeat`) at the end of every [`HEARTBEAT_PERIOD`] in
//!      which no pose was queued, so that the server does not take a station with
//!      nothing to send for a station gone;
//! 4. leave: unless the server ended the stream, send `Leave` and let the server
//!    end it; then stop the force loops and sum up.
//!
//! The server ending the stream normally (for example after `SESSION_CLOSING`) is
//! said in the summary; a gRPC status it ends with is returned as
//! [`StationError::Status`]. A load run ([`crate::load`]) goes through the same
//! join, intake, sending and leaving for each of its stations.

use std::future::Future;
use std::pin::Pin;
use std::time::{Duration, Instant};

use tokio::time::MissedTickBehavior;

use crate::connect::{CALL_TIMEOUT, connect};
use crate::haptics::Trajectory;
use crate::proto::v1::{self, InstrumentDescription, JoinRequest, SceneDescription};

mod config;
pub(crate) mod heartbeat;
pub(crate) mod instruments;
pub(crate) mod intake;
pub(crate) mod link;
pub(crate) mod poses;
mod report;

#[cfg(test)]
mod tests;

pub(crate) use config::check_rate;
pub use config::{StationConfig, StationError};
pub use heartbeat::HEARTBEAT_PERIOD;
pub(crate) use heartbeat::Heartbeat;
pub use instruments::ModelIntake;
pub(crate) use intake::{Intake, Received, TickCounter, force_magnitude};
pub(crate) use link::Link;
pub(crate) use poses::{Poses, Sent};
pub use report::{InstrumentSummary, StationEnd, StationProgress, StationSummary};

use instruments::Instrument;

/// Default rate at which device poses are sent, Hz.
pub const DEFAULT_POSE_RATE_HZ: f64 = 250.0;

/// The pose rates a station sends at, Hz: from one pose every 10 s (a heartbeat
/// keeps a slower station alive anyway) to 100 kHz, a hundred times a haptic
/// device's rate.
pub const POSE_RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 0.1..=100_000.0;
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

/// Runs `call` for at most `limit`; past it, the server did not answer `what`.
pub(crate) async fn answered<T>(
    what: &'static str,
    limit: Duration,
    call: impl Future<Output = Result<T, StationError>>,
) -> Result<T, StationError> {
    tokio::time::timeout(limit, call)
        .await
        .map_err(|_| StationError::NoAnswer { what, after: limit })?
}

/// How long a call may wait: [`CALL_TIMEOUT`], or less if the run's `duration`
/// (counted from `started`) ends sooner.
pub(crate) fn call_limit(started: Instant, duration: Option<Duration>) -> Duration {
    duration.map_or(CALL_TIMEOUT, |d| {
        d.saturating_sub(started.elapsed())
            .min(CALL_TIMEOUT)
            .max(Duration::from_millis(1))
    })
}

/// Joins the session, drives the granted instruments and returns what was seen; see
/// the [module documentation](self). The configured duration bounds the whole run,
/// connecting and joining included.
pub async fn run_station(mut config: StationConfig) -> Result<StationSummary, StationError> {
    config.check_rates()?;
    let started = Instant::now();
    let connection = connect(&config.connect.within(config.duration)).await?;
    let open = JoinRequest {
        session_id: config.session_id.clone(),
        role: config.role as i32,
        instruments: config.instruments.clone(),
        surface_frame_rate_hz: config.surface_frame_rate_hz,
        client_name: config.client_name.clone(),
    };
    let mut link = answered(
        "the join",
        call_limit(started, config.duration),
        Link::join(&connection, open),
    )
    .await?;
    let t0 = Instant::now();
    let joined = link.joined.clone();
    let scene = joined.scene.clone().unwrap_or_default();
    tracing::info!(
        station_id = joined.station_id,
        session = %joined.session_id,
        granted = ?joined.instruments,
        "joined"
    );
    let mut instruments = Instrument::start_all(
        &joined.instruments,
        &scene,
        config.gesture.as_ref(),
        config.haptic_rate_hz,
        t0,
    )?;
    let mut intake = Intake::new(&joined.instruments);
    let mut poses = Poses::new();

    let pose_rate_hz = sending_rate(config.pose_rate_hz, joined.max_pose_rate_hz);
    if pose_rate_hz < config.pose_rate_hz {
        tracing::warn!(
            "the server admits {pose_rate_hz} poses a second per instrument: sending at that \
             rate, not {}",
            config.pose_rate_hz
        );
    }
    let mut pose_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / pose_rate_hz));
    pose_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut progress_tick = tokio::time::interval(PROGRESS_PERIOD);
    progress_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut heartbeat = Heartbeat::new();
    let deadline = after(config.duration.map(|d| d.saturating_sub(started.elapsed())));
    tokio::pin!(deadline);
    let stop = when_stopped(config.stop.take());
    tokio::pin!(stop);

    let end = loop {
        tokio::select! {
            biased;
            _ = &mut stop => break StationEnd::Stopped,
            _ = &mut deadline => break StationEnd::Duration,
            message = link.next() => match message? {
                Some(message) => match intake.take(&message, &mut poses)? {
                    Received::State { index: Some(i), state } => instruments[i].take(state),
                    Received::Event(event) => {
                        if let Some(on_event) = config.on_event.as_mut() {
                            on_event(event);
                        }
                    }
                    _ => {}
                },
                None => break StationEnd::ServerClosed,
            },
            _ = pose_tick.tick() => {
                for instrument in &mut instruments {
                    instrument.send_pose(&mut poses, &link.outgoing);
                }
            }
            _ = heartbeat.due() => heartbeat.beat(&poses, &link.outgoing),
            _ = progress_tick.tick() => {
                if let Some(progress) = &config.progress {
                    progress.send_replace(progress_of(t0, &joined, &intake, &poses, &mut instruments));
                }
            }
        }
    };

    if end != StationEnd::ServerClosed {
        let reason = match end {
            StationEnd::Duration => "duration elapsed",
            _ => "stopped",
        };
        link.leave(reason.into()).await;
    }
    let sent = Sending {
        poses: &poses,
        rate_hz: pose_rate_hz,
    };
    Ok(summary_of(end, t0, &joined, intake, sent, instruments))
}

/// The rate a station sends poses at: the one configured, or the server's
/// `Joined.max_pose_rate_hz` if that is lower. A station above the limit would
/// empty its burst allowance in a few seconds, then have poses refused and lose its
/// stream. A limit of 0 (a server that does not state one), or one that is not a
/// positive finite number, leaves the configured rate.
///
/// The result is kept within [`POSE_RATE_RANGE_HZ`], whatever the server states:
/// its period, `1 / rate`, is then a time a timer can hold.
pub fn sending_rate(configured_hz: f64, server_limit_hz: f64) -> f64 {
    let rate = if server_limit_hz.is_finite() && server_limit_hz > 0.0 {
        configured_hz.min(server_limit_hz)
    } else {
        configured_hz
    };
    rate.clamp(*POSE_RATE_RANGE_HZ.start(), *POSE_RATE_RANGE_HZ.end())
}

/// Progress: the live figures of the station.
fn progress_of(
    t0: Instant,
    joined: &v1::Joined,
    intake: &Intake,
    poses: &Poses,
    instruments: &mut [Instrument],
) -> StationProgress {
    let latency = intake.latency.summary();
    StationProgress {
        elapsed_s: t0.elapsed().as_secs_f64(),
        tick: intake.ticks.last.unwrap_or(joined.tick),
        sim_time_s: intake.ticks.sim_time_s,
        frames: intake.frames,
        states: intake.states,
        events: intake.events,
        errors: intake.errors.values().sum(),
        poses_sent: poses.sent,
        forces_n: instruments
            .iter()
            .map(|i| (i.name.clone(), i.force_n))
            .collect(),
        haptic_rates_hz: instruments.iter_mut().map(|i| i.haptic_rate_hz()).collect(),
        latency_p50_ms: latency.p50_ms,
        latency_p99_ms: latency.p99_ms,
        models_invalid: instruments.iter().map(|i| i.models_invalid()).sum(),
    }
}

/// What the station sent: its pose counters and the rate it sent at.
struct Sending<'a> {
    poses: &'a Poses,
    rate_hz: f64,
}

/// The end: the force loops stopped, what the station saw summed up. Poses dropped
/// are those the full queue refused; once the request stream is gone, the server's
/// stream says how the call ends.
fn summary_of(
    end: StationEnd,
    t0: Instant,
    joined: &v1::Joined,
    intake: Intake,
    sent: Sending<'_>,
    instruments: Vec<Instrument>,
) -> StationSummary {
    let elapsed_s = t0.elapsed().as_secs_f64();
    let per_instrument: Vec<InstrumentSummary> =
        instruments.into_iter().map(Instrument::stop).collect();
    StationSummary {
        station_id: joined.station_id,
        session_id: joined.session_id.clone(),
        instruments: joined.instruments.clone(),
        end,
        elapsed_s,
        ticks: intake.ticks.ticks,
        last_tick: intake.ticks.last.unwrap_or(joined.tick),
        frames: intake.frames,
        states: intake.states,
        events: intake.events,
        errors: intake.errors,
        poses_sent: sent.poses.sent,
        pose_rate_hz: sent.rate_hz,
        poses_dropped: sent.poses.full,
        max_force_n: per_instrument
            .iter()
            .map(|i| i.max_force_n)
            .fold(0.0, f64::max),
        latency: intake.latency.summary(),
        per_instrument,
    }
}
