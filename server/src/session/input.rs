//! Device poses from stations: checked, rate-limited, and handed to the mechanics
//! thread through a latest-value slot per instrument.

use laparo_proto::force::wire;
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
                "tip ({}, {}, {}) m is outside the workspace [{:?} .. {:?}]",
                tip.x,
                tip.y,
                tip.z,
                workspace.min.coords.as_slice(),
                workspace.max.coords.as_slice()
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
mod tests {
    use super::*;

    fn workspace() -> Workspace {
        Workspace {
            min: Point3::new(-1.0, -1.0, -1.0),
            max: Point3::new(1.0, 1.0, 1.0),
        }
    }

    fn pose(tip: [f64; 3], axis: [f64; 3], sequence: u64) -> v1::DevicePose {
        v1::DevicePose {
            instrument: "left".into(),
            pose: Some(v1::Pose {
                tip: Some(v1::Vec3 {
                    x: tip[0],
                    y: tip[1],
                    z: tip[2],
                }),
                axis: Some(v1::Vec3 {
                    x: axis[0],
                    y: axis[1],
                    z: axis[2],
                }),
            }),
            device_time_s: 0.0,
            sequence,
        }
    }

    #[test]
    fn bad_poses_are_rejected_with_their_code() {
        let w = workspace();
        let ok = check_pose(&pose([0.1, 0.0, 0.0], [0.0, 0.0, 1.0], 5), &w, Some(4));
        assert!(ok.is_ok());
        let code = |p: &v1::DevicePose, last| check_pose(p, &w, last).unwrap_err().code;
        assert_eq!(
            code(&pose([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
            ErrorCode::InvalidPose
        );
        assert_eq!(
            code(&pose([0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 1.0], 1), None),
            ErrorCode::InvalidPose
        );
        assert_eq!(
            code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1), None),
            ErrorCode::InvalidPose
        );
        assert_eq!(
            code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 2.0], 1), None),
            ErrorCode::InvalidPose
        );
        assert_eq!(
            code(&pose([5.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
            ErrorCode::OutOfWorkspace
        );
        assert_eq!(
            code(&pose([1e300, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
            ErrorCode::OutOfWorkspace
        );
        assert_eq!(
            code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 4), Some(4)),
            ErrorCode::OutOfOrder
        );
        let mut missing = pose([0.0; 3], [0.0, 0.0, 1.0], 1);
        missing.pose = None;
        assert_eq!(code(&missing, None), ErrorCode::InvalidPose);
    }

    #[test]
    fn the_rate_limit_admits_its_rate_and_its_burst() {
        let mut limit = RateLimit::new(100.0, 10.0);
        // A burst of 10 at once, then nothing until tokens come back.
        assert_eq!((0..20).filter(|_| limit.admit(0.0)).count(), 10);
        // 1 s at 1 kHz: 100 admitted (the rate), the rest refused.
        let admitted = (1..=1000)
            .filter(|&k| limit.admit(k as f64 / 1000.0))
            .count();
        assert!((99..=101).contains(&admitted), "{admitted}");
    }
}
