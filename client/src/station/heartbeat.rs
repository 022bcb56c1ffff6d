//! Telling the server the station is still there when it has no pose to send.
//!
//! The server releases the instruments of a station that sends nothing for its
//! station timeout (5 s unless configured, 0.5 s at least). A station sends poses
//! at hundreds of hertz while it drives, but one that claims no instrument, or
//! whose poses cannot be queued, sends none: it then sends a `Heartbeat` every
//! [`HEARTBEAT_PERIOD`] in which it queued nothing else.

use std::time::Duration;

use tokio::sync::mpsc;
use tokio::time::{Interval, MissedTickBehavior};

use super::Poses;
use crate::proto::v1::{Heartbeat as HeartbeatMessage, StationMessage, station_message};

/// How often a station with nothing else to send says it is there: half the
/// server's shortest station timeout (0.5 s), so that even there a beat lost or
/// late on the network does not cost the station its instruments; a twentieth of
/// the default 5 s. Four small messages a second cost nothing beside poses at
/// hundreds of hertz.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_millis(250);

/// The heartbeat of one station.
pub(crate) struct Heartbeat {
    tick: Interval,
    /// Poses queued when the last period began.
    sent_before: u64,
}

impl Heartbeat {
    pub fn new() -> Self {
        let mut tick = tokio::time::interval(HEARTBEAT_PERIOD);
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        Heartbeat {
            tick,
            sent_before: 0,
        }
    }

    /// Completes at the end of each period.
    pub async fn due(&mut self) {
        self.tick.tick().await;
    }

    /// At the end of a period: a heartbeat if no pose was queued during it.
    pub fn beat(&mut self, poses: &Poses, outgoing: &mpsc::Sender<StationMessage>) {
        if poses.sent == self.sent_before {
            let _ = outgoing.try_send(StationMessage {
                kind: Some(station_message::Kind::Heartbeat(HeartbeatMessage {})),
            });
        }
        self.sent_before = poses.sent;
    }
}
