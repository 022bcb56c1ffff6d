//! A station's intake waits for the recorder: poses come in faster than a recorder
//! writes only in a burst (a station's queued poses after a network stall), and the
//! recorder's channel, which the mechanics thread must never wait on, is shared
//! with every tick's frame. Holding the next pose back while the channel is past
//! its [`pose_room`](Recorder::pose_room) keeps both: the burst waits in the
//! transport (HTTP/2 flow control reaches the sender), nothing is left out of the
//! recording, and the frames keep the rest of the channel.
//!
//! A recorder that takes nothing off its channel for [`STALLED`] (a disk that
//! stopped) is not waited for: the station's poses go on to the mechanics thread
//! and the recorder leaves out what does not fit, reported as lagging, as before.
//! The station waits again once the recorder has written something.

use std::time::{Duration, Instant};

use crate::recording::recorder::Recorder;

/// How long a recorder may write nothing before stations stop waiting for it. A
/// pose is written in microseconds, so a recorder draining a burst writes
/// thousands of items in this time, even on a machine busy enough to keep its
/// thread off a core for tens of milliseconds; one that wrote none is stalled, and
/// the instrument must not freeze with it longer than this, once.
pub const STALLED: Duration = Duration::from_millis(200);

/// How often a waiting station looks at the recorder again.
const POLL: Duration = Duration::from_millis(1);

/// One station's view of its session's recorder.
#[derive(Debug, Default)]
pub struct RecorderRoom {
    /// While waiting: the recorder's written count last seen, and since when it
    /// has not moved. Kept here, so that a wait cut short (the station's loop
    /// selects over other things too) resumes where it was.
    waiting: Option<(u64, Instant)>,
    /// The recorder's written count when this station last gave up waiting for
    /// it: it is not waited for again until that count moves.
    gave_up_at: Option<u64>,
}

/// What a station's intake sees of its recorder at one look.
#[derive(Clone, Copy, Debug)]
pub struct Look {
    /// Items handed over and not yet written ([`Recorder::backlog`]).
    pub backlog: u64,
    /// The backlog at which poses wait ([`Recorder::pose_room`]).
    pub room: u64,
    /// Items written so far ([`Recorder::processed`]).
    pub processed: u64,
    /// Whether its thread still writes ([`Recorder::is_writing`]).
    pub writing: bool,
}

impl Look {
    fn at(r: &Recorder) -> Self {
        Look {
            backlog: r.backlog(),
            room: r.pose_room(),
            processed: r.processed(),
            writing: r.is_writing(),
        }
    }
}

impl RecorderRoom {
    /// Whether the next pose must wait, given what the recorder looks like `now`:
    /// it waits while the backlog is at or past the room and the recorder has
    /// written something within [`STALLED`].
    pub fn must_wait(&mut self, look: Look, now: Instant) -> bool {
        if look.backlog < look.room || !look.writing || self.gave_up_at == Some(look.processed) {
            self.waiting = None;
            return false;
        }
        self.gave_up_at = None;
        match self.waiting {
            Some((seen, since)) if seen == look.processed => {
                if now.duration_since(since) >= STALLED {
                    (self.waiting, self.gave_up_at) = (None, Some(look.processed));
                    return false;
                }
            }
            _ => self.waiting = Some((look.processed, now)),
        }
        true
    }

    /// Returns once the recorder (if the session has one) has room for a pose, or
    /// once it has written nothing for [`STALLED`] ([`must_wait`](Self::must_wait)).
    /// Cancel-safe: dropped halfway, the next call goes on with the same wait.
    pub async fn wait(&mut self, recorder: Option<&Recorder>) {
        let Some(r) = recorder else {
            return;
        };
        while self.must_wait(Look::at(r), Instant::now()) {
            tokio::time::sleep(POLL).await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look(backlog: u64, processed: u64) -> Look {
        Look {
            backlog,
            room: 2048,
            processed,
            writing: true,
        }
    }

    #[test]
    fn a_draining_recorder_is_waited_for_until_it_has_room() {
        let (mut room, t0) = (RecorderRoom::default(), Instant::now());
        assert!(!room.must_wait(look(2047, 0), t0));
        // Past the room: wait for as long as it keeps writing, however long.
        for k in 0..100u64 {
            let now = t0 + STALLED * (k as u32);
            assert!(room.must_wait(look(4000 - k, k), now), "look {k}");
        }
        assert!(!room.must_wait(look(2047, 100), t0 + STALLED * 100));
    }

    #[test]
    fn a_stalled_recorder_is_waited_for_once_then_not_until_it_writes() {
        let (mut room, t0) = (RecorderRoom::default(), Instant::now());
        let ms = Duration::from_millis;
        assert!(room.must_wait(look(4096, 7), t0));
        assert!(room.must_wait(look(4096, 7), t0 + STALLED - ms(1)));
        // Nothing written for STALLED: the pose goes on.
        assert!(!room.must_wait(look(4096, 7), t0 + STALLED));
        // Still nothing written: not waited for again, however long after.
        assert!(!room.must_wait(look(4096, 7), t0 + STALLED + ms(1)));
        assert!(!room.must_wait(look(4096, 7), t0 + STALLED * 50));
        // It wrote one item: waited for again, and given up on after a new STALLED.
        let t1 = t0 + STALLED * 51;
        assert!(room.must_wait(look(4096, 8), t1));
        assert!(room.must_wait(look(4096, 8), t1 + STALLED - ms(1)));
        assert!(!room.must_wait(look(4096, 8), t1 + STALLED));
    }

    #[test]
    fn a_recorder_that_ended_is_not_waited_for() {
        let mut room = RecorderRoom::default();
        let ended = Look {
            writing: false,
            ..look(4096, 0)
        };
        assert!(!room.must_wait(ended, Instant::now()));
    }
}
