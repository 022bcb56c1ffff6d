//! A station's intake waits for the recorder: poses come in faster than a recorder
//! writes only in a burst (a station's queued poses after a network stall), and the
//! recorder's channel, which the mechanics thread must never wait on, is shared
//! with every tick's frame. Holding the next pose back while the channel is past
//! its [`pose_room`](Recorder::pose_room) keeps both: the burst waits in the
//! transport (HTTP/2 flow control reaches the sender), nothing is left out of the
//! recording, and the frames keep the rest of the channel.
//!
//! The live session comes before its recording. A recorder that writes fewer than
//! [`MIN_WRITES`] items in [`WINDOW`] (a disk that stopped or crawls) is not waited
//! for: the station's poses go on to the mechanics thread and the recorder leaves
//! out what does not fit, reported as lagging, as before. The station waits for it
//! again only once it has caught up, its backlog under half the room: waiting on a
//! recorder that cannot keep up would hold the instrument to the disk's pace and,
//! past `--station-timeout`, cut the station for not being read.

use std::time::{Duration, Instant};

use crate::recording::recorder::Recorder;

/// The span over which a waited-for recorder must write [`MIN_WRITES`] items. A
/// station is read at least once a window while it waits, well within the
/// shortest `--station-timeout` (0.5 s).
pub const WINDOW: Duration = Duration::from_millis(200);

/// Items a recorder must write in a [`WINDOW`] to be waited for: 500 a second, half
/// what one station at 1 kHz sends alone. A pose is written in microseconds, so a
/// recorder draining a burst writes tens of thousands in a window, even on a
/// machine busy enough to keep its thread off a core for tens of milliseconds.
pub const MIN_WRITES: u64 = 100;

/// How often a waiting station looks at the recorder again.
const POLL: Duration = Duration::from_millis(1);

/// One station's view of its session's recorder.
#[derive(Debug, Default)]
pub struct RecorderRoom {
    /// While the backlog is above half the room: the recorder's written count at
    /// the start of the current [`WINDOW`], and when it started. Kept here, so that
    /// a wait cut short (the station's loop selects over other things too) resumes
    /// where it was.
    waiting: Option<(u64, Instant)>,
    /// Whether this station gave up waiting for the recorder, until it catches up.
    gave_up: bool,
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
    /// while the backlog is at or past the room, and the recorder has written at
    /// least [`MIN_WRITES`] items in each [`WINDOW`] since its backlog passed half
    /// the room. Windows run on while the backlog stays above half the room, so a
    /// recorder that crawls (a few items a window) is given up on as one that
    /// stopped is, though each pose waits only for its next item.
    pub fn must_wait(&mut self, look: Look, now: Instant) -> bool {
        if !look.writing || look.backlog < look.room / 2 {
            (self.waiting, self.gave_up) = (None, false);
            return false;
        }
        if self.gave_up {
            return false;
        }
        let (start, since) = *self.waiting.get_or_insert((look.processed, now));
        if now.duration_since(since) >= WINDOW {
            if look.processed - start < MIN_WRITES {
                (self.waiting, self.gave_up) = (None, true);
                return false;
            }
            self.waiting = Some((look.processed, now));
        }
        look.backlog >= look.room
    }

    /// Returns once the recorder (if the session has one) has room for a pose, or
    /// once it writes too slowly to be waited for ([`must_wait`](Self::must_wait)).
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

    const ROOM: u64 = 2048;

    fn look(backlog: u64, processed: u64) -> Look {
        Look {
            backlog,
            room: ROOM,
            processed,
            writing: true,
        }
    }

    #[test]
    fn a_draining_recorder_is_waited_for_until_it_has_room() {
        let (mut room, t0) = (RecorderRoom::default(), Instant::now());
        assert!(!room.must_wait(look(ROOM - 1, 0), t0));
        // Past the room: waited for as long as it writes enough, however long.
        for k in 0..100u64 {
            let now = t0 + WINDOW * (k as u32);
            assert!(
                room.must_wait(look(ROOM + 50, k * MIN_WRITES), now),
                "look {k}"
            );
        }
        assert!(!room.must_wait(look(ROOM - 1, 100 * MIN_WRITES), t0 + WINDOW * 100));
    }

    #[test]
    fn a_stalled_or_crawling_recorder_is_waited_for_a_window_then_not_until_it_catches_up() {
        let ms = Duration::from_millis;
        for writes in [0, MIN_WRITES - 1] {
            let (mut room, t0) = (RecorderRoom::default(), Instant::now());
            assert!(room.must_wait(look(4096, 7), t0));
            assert!(room.must_wait(look(4096, 7 + writes), t0 + WINDOW - ms(1)));
            // Too few written in the window: the pose goes on.
            assert!(!room.must_wait(look(4096, 7 + writes), t0 + WINDOW));
            // Not waited for again while it lags, even if it writes again.
            assert!(!room.must_wait(look(4096, 7 + writes + 5000), t0 + WINDOW * 2));
            assert!(!room.must_wait(look(ROOM, 7 + writes + 9000), t0 + WINDOW * 3));
            // Caught up (under half the room): waited for again when it lags again.
            assert!(!room.must_wait(look(ROOM / 2 - 1, 20_000), t0 + WINDOW * 4));
            let t1 = t0 + WINDOW * 5;
            assert!(room.must_wait(look(ROOM, 20_000), t1));
            assert!(!room.must_wait(look(ROOM, 20_000 + writes), t1 + WINDOW));
        }
    }

    #[test]
    fn a_recorder_crawling_at_the_room_is_given_up_on_within_a_window() {
        // One item written every 50 ms: each pose would wait for the next item,
        // and the backlog hovers at the room.
        let (mut room, t0) = (RecorderRoom::default(), Instant::now());
        let step = Duration::from_millis(50);
        let mut waits = 0;
        for k in 0..20u32 {
            let now = t0 + step * k;
            if room.must_wait(look(ROOM, k.into()), now) {
                waits += 1;
                assert!(
                    now.duration_since(t0) < WINDOW + step,
                    "still waiting at {k}"
                );
            }
            assert!(!room.must_wait(look(ROOM - 1, k.into()), now));
        }
        assert!(waits > 0 && room.gave_up);
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
