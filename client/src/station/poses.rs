//! Sending device poses: one increasing sequence number over all the station's
//! instruments, the send time of each remembered for the pose-to-state latency.

use std::time::Instant;

use nalgebra::{Point3, Unit, Vector3};
use tokio::sync::mpsc;

use super::SEND_TIMES_CAPACITY;
use crate::latency::SendTimes;
use crate::proto::force::wire;
use crate::proto::v1::{DevicePose, StationMessage, station_message};

/// What became of a pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Sent {
    /// Queued for the server.
    Queued,
    /// Dropped: the outgoing queue was full (a queued pose is a stale pose).
    Full,
    /// Dropped: the request stream is gone; the call is ending and the server's
    /// stream says how.
    Closed,
}

/// The station's outgoing poses.
pub(crate) struct Poses {
    sequence: u64,
    send_times: SendTimes,
    /// Poses queued.
    pub sent: u64,
    /// Poses dropped because the queue was full.
    pub full: u64,
    /// Poses dropped because the request stream was gone.
    pub closed: u64,
}

impl Poses {
    /// No pose sent yet; the send times of the last [`SEND_TIMES_CAPACITY`] kept.
    pub fn new() -> Self {
        Poses {
            sequence: 0,
            send_times: SendTimes::new(SEND_TIMES_CAPACITY),
            sent: 0,
            full: 0,
            closed: 0,
        }
    }

    /// Numbers the pose of `instrument` (tip, axis, device time in s) with the next
    /// sequence number and queues it without waiting.
    pub fn send(
        &mut self,
        outgoing: &mpsc::Sender<StationMessage>,
        instrument: &str,
        tip: &Point3<f64>,
        axis: &Unit<Vector3<f64>>,
        device_time_s: f64,
    ) -> Sent {
        self.sequence += 1;
        let message = StationMessage {
            kind: Some(station_message::Kind::Pose(DevicePose {
                instrument: instrument.to_owned(),
                pose: Some(wire::to_pose(tip, axis)),
                device_time_s,
                sequence: self.sequence,
            })),
        };
        match outgoing.try_send(message) {
            Ok(()) => {
                self.send_times.record(self.sequence, Instant::now());
                self.sent += 1;
                Sent::Queued
            }
            Err(mpsc::error::TrySendError::Full(_)) => {
                self.full += 1;
                Sent::Full
            }
            Err(mpsc::error::TrySendError::Closed(_)) => {
                self.closed += 1;
                Sent::Closed
            }
        }
    }

    /// When the pose numbered `sequence` was sent, once; `None` if it was not, or
    /// is too old to be remembered.
    pub fn sent_at(&mut self, sequence: u64) -> Option<Instant> {
        self.send_times.take(sequence)
    }
}
