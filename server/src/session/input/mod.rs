//! Device poses from stations: checked, rate-limited, and handed to the mechanics
//! thread through a latest-value slot per instrument.

use laparo_proto::force::wire;
use laparo_proto::text::Number;
use laparo_proto::v1;
use laparo_proto::v1::ErrorCode;
use nalgebra::Point3;

use crate::engine::contact::InstrumentPose;

/// A pose the mechanics thread applies at its next tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseIn {
    pub pose: InstrumentPose,
    /// The station's sequence number of the pose.
    pub sequence: u64,
    /// The station that sent it.
    pub station: u64,
}

/// What the mechanics thread finds in an instrument's pose slot at a tick.
///
/// The slot keeps its value until it is overwritten, so the mechanics applies the
/// same newest value every tick: a held pose keeps the instrument where the station
/// put it, and a withdrawal keeps it out of the body until a station sends a pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Slot {
    /// No station has driven the instrument since the session started: it stays
    /// where the scene put it (out of the body).
    #[default]
    Untouched,
    /// The newest pose a station sent.
    Pose(PoseIn),
    /// The station holding the instrument left: the instrument is taken out of the
    /// body (`Simulation::set_pose(k, None)`), so that the vertices it held are
    /// let go and the tissue relaxes, and it has no holder.
    Withdrawn,
}

/// A rejected pose: the error code the station is told and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejection {
    pub code: ErrorCode,
    pub message: String,
}

impl Rejection {
    fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Rejection {
            code,
            message: message.into(),
        }
    }
}

/// Where a tip can be: the liver's bounding box grown by the longest instrument. A
/// tip outside it is a unit or frame mistake (millimetres for metres, say), not a
/// gesture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Workspace {
    pub min: Point3<f64>,
    pub max: Point3<f64>,
}

impl Workspace {
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }
}

/// `(x, y, z)`, each coordinate short whatever the number a station sent
/// ([`Number`]: `1e300`, not 301 digits).
fn written(p: &Point3<f64>) -> String {
    format!("({}, {}, {})", Number(p.x), Number(p.y), Number(p.z))
}

/// Checks a device pose: a pose that is there and finite, a unit axis (within
/// [`wire::UNIT_TOLERANCE`]), a tip inside the workspace, a sequence number above the
/// last accepted one.
pub fn check_pose(
    msg: &v1::DevicePose,
    workspace: &Workspace,
    last_sequence: Option<u64>,
) -> Result<InstrumentPose, Rejection> {
    let (tip, axis) = wire::pose(msg.pose.as_ref())
        .map_err(|e| Rejection::new(ErrorCode::InvalidPose, e.to_string()))?;
    if !workspace.contains(&tip) {
        return Err(Rejection::new(
            ErrorCode::OutOfWorkspace,
            format!(
                "tip {} m is outside the workspace {} .. {} m",
                written(&tip),
                written(&workspace.min),
                written(&workspace.max)
            ),
        ));
    }
    if let Some(last) = last_sequence
        && msg.sequence <= last
    {
        return Err(Rejection::new(
            ErrorCode::OutOfOrder,
            format!("sequence {} is not above {last}", msg.sequence),
        ));
    }
    Ok(InstrumentPose::new(tip, axis))
}

/// How long a network stall the pose rate limit absorbs (s): the server stopped
/// for 3 s, a 0.3 s stall at 1 kHz and a 1 s stall at 250 Hz all fit with room.
///
/// A station at a steady rate `r` below the limit `R` saves `R − r` tokens a
/// second while it waits for the network; after a stall of `T` s its queued
/// `r·T` poses arrive at once. A bucket of `R·STALL_WINDOW_S` tokens admits them
/// whenever `T ≤ STALL_WINDOW_S·R/r` (10 s for 1 kHz under a 2 kHz limit), so a
/// burst after a stall is never a rejection: it is a network fact, and the
/// newest of its poses wins the latest-value slot. Sustained abuse at a rate
/// `a > R` empties the bucket in `R·STALL_WINDOW_S/(a − R)` s and is then refused
/// at `a − R` poses a second, which closes the stream.
pub const STALL_WINDOW_S: f64 = 5.0;

/// The bucket size for a pose rate `rate_hz`: [`STALL_WINDOW_S`] of its poses.
pub fn stall_burst(rate_hz: f64) -> f64 {
    rate_hz * STALL_WINDOW_S
}

/// A token bucket: `rate` tokens a second, at most `burst` saved up.
#[derive(Clone, Copy, Debug)]
pub struct RateLimit {
    rate: f64,
    burst: f64,
    tokens: f64,
    last: Option<f64>,
}

impl RateLimit {
    pub fn new(rate_hz: f64, burst: f64) -> Self {
        RateLimit {
            rate: rate_hz,
            burst,
            tokens: burst,
            last: None,
        }
    }

    /// The same bucket on a clock started `seconds` later: its times, `now` as
    /// [`admit`](Self::admit) takes it, are that much smaller. A bucket handed from
    /// one station to the next keeps what its tokens were.
    pub fn rebased(mut self, seconds: f64) -> Self {
        self.last = self.last.map(|t| t - seconds);
        self
    }

    /// Whether a message at time `now` (s, monotonic) is within the limit.
    pub fn admit(&mut self, now: f64) -> bool {
        if let Some(last) = self.last {
            self.tokens = (self.tokens + (now - last).max(0.0) * self.rate).min(self.burst);
        }
        self.last = Some(now);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests;
