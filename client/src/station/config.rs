//! What a station is asked to do, and why it could not.

use std::time::Duration;

use tokio::sync::watch;

use laparo_proto::text::Number;

use super::{
    DEFAULT_POSE_RATE_HZ, EventSink, GestureFn, POSE_RATE_RANGE_HZ, StationProgress, StopSignal,
};
use crate::connect::{ConnectConfig, ConnectError};
use crate::haptics::ConfigError;
use crate::haptics::force_loop::{DEFAULT_RATE_HZ, RATE_RANGE_HZ};
use crate::proto::v1::Role;

/// What [`run_station`](super::run_station) does.
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
    /// The gesture of each instrument; `None` for
    /// [`default_press_for`](crate::gestures::default_press_for).
    pub gesture: Option<GestureFn>,
    /// Receives a [`StationProgress`] every [`PROGRESS_PERIOD`](super::PROGRESS_PERIOD).
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
            haptic_rate_hz: DEFAULT_RATE_HZ,
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
    /// The server ended the call with a gRPC status (named as the gRPC
    /// specification spells it, as the contract's comments do: `NOT_FOUND`).
    #[error(
        "the server answered {}: {message}",
        crate::connect::failure::code_name(*code)
    )]
    Status { code: tonic::Code, message: String },
    /// The connection broke under the call (the server died, closed it, or stopped
    /// answering); says which, in words.
    #[error("lost the connection to the server: {0}")]
    Lost(String),
    /// The server did not answer a call in time.
    #[error("the server did not answer {what} within {} s", after.as_secs_f64())]
    NoAnswer { what: &'static str, after: Duration },
    /// The server broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A rate out of range.
    #[error("{field} = {} Hz is out of range (expected {expected})", Number(*value))]
    Rate {
        field: &'static str,
        value: f64,
        expected: String,
    },
    /// More stations asked for than the session has room for.
    #[error(
        "{asked} more stations do not fit session `{session}`: it takes at most {max} at once \
         and has {connected}"
    )]
    NoRoom {
        session: String,
        asked: usize,
        connected: usize,
        max: u32,
    },
    /// The force loop configuration was refused.
    #[error(transparent)]
    ForceLoop(#[from] ConfigError),
}

impl From<tonic::Status> for StationError {
    /// A status the server sent as [`StationError::Status`]; one made on this side
    /// because the transport failed as [`StationError::Lost`].
    fn from(status: tonic::Status) -> Self {
        if let Some(words) = crate::connect::failure::lost(&status) {
            return StationError::Lost(words);
        }
        StationError::Status {
            code: status.code(),
            message: status.message().to_owned(),
        }
    }
}

impl StationError {
    /// The error of a stream that failed with `status` after hearing nothing from
    /// the server for `silent` ([`crate::connect::failure::lost_after`]).
    pub fn after_silence(status: tonic::Status, silent: std::time::Duration) -> Self {
        match crate::connect::failure::lost_after(&status, silent) {
            Some(words) => StationError::Lost(words),
            None => status.into(),
        }
    }
}

/// Checks that `value` lies within `range`; out of it, the error names `field` and
/// the range, written from the range itself so that the words cannot drift from the
/// check.
pub(crate) fn check_rate(
    field: &'static str,
    value: f64,
    range: &std::ops::RangeInclusive<f64>,
) -> Result<(), StationError> {
    if range.contains(&value) {
        Ok(())
    } else {
        Err(StationError::Rate {
            field,
            value,
            expected: format!(
                "between {} and {}",
                Number(*range.start()),
                Number(*range.end())
            ),
        })
    }
}

impl StationConfig {
    /// Checks the rates: the pose rate within [`POSE_RATE_RANGE_HZ`], the haptic
    /// rate within the force loop's range.
    pub(super) fn check_rates(&self) -> Result<(), StationError> {
        check_rate("pose rate", self.pose_rate_hz, &POSE_RATE_RANGE_HZ)?;
        check_rate("haptic rate", self.haptic_rate_hz, &RATE_RANGE_HZ)
    }
}
