//! The intake of server messages, shared by the station and each station of a load
//! run: every message of the `Join` stream is counted here once, its tick noted, the
//! pose-to-state latency measured, and what is left for the caller passed on as a
//! [`Received`].
//!
//! Latency: when an `InstrumentState` of a granted instrument carries a
//! `pose_sequence` newer than any before for that instrument, the latency is now −
//! the send time of that sequence ([`Poses::sent_at`]); older or repeated sequences
//! (the server keeps the newest pose a tick) measure nothing.

use std::collections::BTreeMap;
use std::time::Instant;

use super::StationError;
use super::poses::Poses;
use crate::latency::LatencyHistogram;
use crate::proto::force::wire;
use crate::proto::v1::{ErrorCode, Event, InstrumentState, ServerMessage, server_message};

/// A server message once counted: what the caller may still act on, borrowed from
/// the message.
#[derive(Debug)]
pub(crate) enum Received<'m> {
    /// A surface frame.
    Frame,
    /// An instrument state; `index` is the place of its instrument among the granted
    /// ones, `None` for an instrument this station does not hold.
    State {
        index: Option<usize>,
        state: &'m InstrumentState,
    },
    /// An event of the session.
    Event(&'m Event),
    /// A station error, counted by code.
    Error,
    /// A message without kind.
    Nothing,
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

/// What a station has received so far.
pub(crate) struct Intake {
    granted: Vec<String>,
    last_pose_sequence: Vec<Option<u64>>,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received (all instruments).
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Station errors received, by code name.
    pub errors: BTreeMap<String, u64>,
    /// Mechanics ticks seen in frames and states.
    pub ticks: TickCounter,
    /// Pose-to-state latency of the granted instruments.
    pub latency: LatencyHistogram,
}

impl Intake {
    /// Nothing received yet, by a station granted `granted`.
    pub fn new(granted: &[String]) -> Self {
        Intake {
            granted: granted.to_vec(),
            last_pose_sequence: vec![None; granted.len()],
            frames: 0,
            states: 0,
            events: 0,
            errors: BTreeMap::new(),
            ticks: TickCounter::default(),
            latency: LatencyHistogram::new(),
        }
    }

    /// Counts `message` and passes on what is left of it; a second `Joined` is a
    /// protocol error.
    pub fn take<'m>(
        &mut self,
        message: &'m ServerMessage,
        poses: &mut Poses,
    ) -> Result<Received<'m>, StationError> {
        let Some(kind) = &message.kind else {
            return Ok(Received::Nothing);
        };
        Ok(match kind {
            server_message::Kind::SurfaceFrame(frame) => {
                self.frames += 1;
                self.ticks.see(frame.tick, frame.sim_time_s);
                Received::Frame
            }
            server_message::Kind::InstrumentState(state) => {
                self.states += 1;
                self.ticks.see(state.tick, state.sim_time_s);
                let now = Instant::now();
                let index = self.granted.iter().position(|n| *n == state.instrument);
                if let Some(i) = index {
                    let last = &mut self.last_pose_sequence[i];
                    let new_pose = state
                        .pose_sequence
                        .filter(|&s| last.is_none_or(|last| s > last));
                    if let Some(s) = new_pose {
                        *last = Some(s);
                        if let Some(sent) = poses.sent_at(s) {
                            self.latency.record(now - sent);
                        }
                    }
                }
                Received::State { index, state }
            }
            server_message::Kind::Event(event) => {
                self.events += 1;
                Received::Event(event)
            }
            server_message::Kind::Error(error) => {
                tracing::debug!(code = error.code, "station error: {}", error.message);
                *self.errors.entry(error_code_name(error.code)).or_default() += 1;
                Received::Error
            }
            server_message::Kind::Joined(_) => {
                return Err(StationError::Protocol("Joined received twice".into()));
            }
        })
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
