//! A recording played back as an observe stream: a reading thread feeds timed
//! messages through a bounded channel, and [`pace`] sends each at its simulated
//! time divided by the speed.
//!
//! Two feeds, one per [`super::recordings::Playback`]:
//! - [`read_recorded`]: the frames, instrument states and events as recorded;
//! - [`read_resimulated`]: the recorded poses through a fresh build of the recorded
//!   scene ([`crate::recording::Resimulation`]), sending the new frames and
//!   instrument states, the contact events they give, and the recorded events that
//!   do not come from the physics (stations joining and leaving, rejected input,
//!   the recorder's reports). Each tick's messages are made by
//!   [`crate::frame::TickOutputs`], as the live session made them, and sent in the
//!   order the session wrote them. With the same build and scene it sends what
//!   `read_recorded` sends; with another it shows what would have happened.
//!
//! Both start at an offset the same way ([`FromOffset`]).

use std::time::Duration;

use laparo_proto::v1;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;
use tonic::Status;

use super::read_status::read_status;
use super::stream::{Item, Wrap};
use crate::recording::{Recorded, Recording, ResimError, Resimulation};
use crate::session::closing::closed;

/// A message to send at `at_s` of simulated time after the replay's start offset.
pub struct Timed {
    pub at_s: f64,
    pub message: v1::ObserveMessage,
}

/// Where a feed sends: `false` once the stream is gone.
struct Feed<'a> {
    feed: &'a mpsc::Sender<Result<Timed, Status>>,
}

impl Feed<'_> {
    fn send(&self, at_s: f64, item: Item) -> bool {
        match v1::ObserveMessage::wrap(item) {
            Some(message) => self.feed.blocking_send(Ok(Timed { at_s, message })).is_ok(),
            None => true,
        }
    }

    fn fail(&self, status: Status) {
        let _ = self.feed.blocking_send(Err(status));
    }
}

/// What comes before a replay's start offset is held back: of it, only the newest
/// tick at or before the offset (its surface and instrument states) and the events
/// stamped exactly at the offset go out, at once, when the first message past the
/// offset comes (or the recording ends), so that a viewer shows the liver as it was
/// there; earlier ticks and events are not sent. Later messages go at their time
/// after the offset.
struct FromOffset {
    offset: f64,
    held: Vec<Item>,
    held_tick: Option<u64>,
    before: bool,
}

impl FromOffset {
    fn new(offset: f64) -> Self {
        FromOffset {
            offset,
            held: Vec::new(),
            held_tick: None,
            before: offset > 0.0,
        }
    }

    /// Takes the message of simulated time `t`; `false` once the stream is gone.
    fn pass(&mut self, t: f64, item: Item, out: &Feed) -> bool {
        if self.before {
            if t <= self.offset {
                match &item {
                    Item::Surface(f) => {
                        self.held.retain(|i| matches!(i, Item::Event(_)));
                        self.held_tick = Some(f.tick);
                        self.held.push(item);
                    }
                    Item::State(s) if self.held_tick == Some(s.tick) => self.held.push(item),
                    Item::Event(_) if t == self.offset => self.held.push(item),
                    _ => {}
                }
                return true;
            }
            self.before = false;
            if !self.flush(out) {
                return false;
            }
        }
        out.send(t - self.offset, item)
    }

    /// Sends what is still held (a recording that ended at or before the offset).
    fn flush(&mut self, out: &Feed) -> bool {
        self.held.drain(..).all(|item| out.send(0.0, item))
    }
}

/// The recording's frames, instrument states and events from `offset` on, decoded
/// one at a time onto `feed` (bounded: this waits for the stream), until the file
/// ends, a message does not read (the stream then ends with its status) or the
/// stream is gone. Runs on a blocking thread.
pub fn read_recorded(
    recording: Recording,
    name: &str,
    offset: f64,
    feed: mpsc::Sender<Result<Timed, Status>>,
) {
    let out = Feed { feed: &feed };
    let mut gate = FromOffset::new(offset);
    for m in recording.messages() {
        let m = match m {
            Ok(m) => m,
            Err(e) => return out.fail(read_status(name, &e)),
        };
        let (t, item) = match m.message {
            Recorded::Scene(_) | Recorded::Pose(_) => continue,
            Recorded::Surface(f) => (f.sim_time_s, Item::Surface(f)),
            Recorded::Instrument(s) => (s.sim_time_s, Item::State(s)),
            Recorded::Event(e) => (e.sim_time_s, Item::Event(e)),
        };
        if !gate.pass(t, item, &out) {
            return;
        }
    }
    gate.flush(&out);
}

/// Whether a recorded event came from the physics (and is derived again by a
/// re-simulation) rather than from the people and machinery around it.
fn from_physics(e: &v1::Event) -> bool {
    e.kind == v1::EventKind::ContactBegan as i32 || e.kind == v1::EventKind::ContactEnded as i32
}

/// The recording re-simulated (see the module documentation) from `offset` on, onto
/// `feed` as [`read_recorded`] does. Every tick before the offset is simulated too
/// (the physics needs them) but not sent. A scene that no longer builds or a mesh
/// that is not the recorded one ends the stream with `FAILED_PRECONDITION`.
pub fn read_resimulated(
    recording: Recording,
    name: &str,
    offset: f64,
    feed: mpsc::Sender<Result<Timed, Status>>,
) {
    let out = Feed { feed: &feed };
    // The scene's folder is a server path, none of the client's business.
    let scene_dir = recording.meta().scene_dir.clone();
    let cannot = |e: ResimError| {
        let mut why = e.to_string();
        if let Some(dir) = &scene_dir {
            why = why.replace(&*dir.to_string_lossy(), "<scene directory>");
        }
        Status::failed_precondition(format!("`{name}` cannot be re-simulated: {why}"))
    };
    let mut run = match Resimulation::new(&recording, recording.meta(), None) {
        Ok(run) => run,
        Err(e) => return out.fail(cannot(e)),
    };
    let mut gate = FromOffset::new(offset);
    for m in recording.messages() {
        let m = match m {
            Ok(m) => m,
            Err(e) => return out.fail(read_status(name, &e)),
        };
        let tick = match m.message {
            Recorded::Event(e) if !from_physics(&e) => {
                if !gate.pass(e.sim_time_s, Item::Event(e), &out) {
                    return;
                }
                continue;
            }
            Recorded::Surface(f) => f.tick,
            _ => continue,
        };
        let sent = run.run_to(tick, |stepped| {
            // The order a session writes a tick in: its contact events, then the
            // surface and every instrument's state.
            let frame = stepped.frame;
            let t = frame.sim_time;
            let surface = v1::SurfaceFrame {
                tick: frame.tick,
                sim_time_s: frame.sim_time,
                positions: frame.surface,
            };
            let mut items = (stepped.events.into_iter().map(Item::Event))
                .chain([Item::Surface(surface)])
                .chain(frame.instruments.into_iter().map(Item::State));
            items.all(|item| gate.pass(t, item, &out))
        });
        match sent {
            Ok(true) => {}
            Ok(false) => return,
            Err(e) => return out.fail(cannot(e)),
        }
    }
    gate.flush(&out);
}

/// Sends `feed`'s messages at their times divided by `speed` after now, until the
/// feed ends (the stream then ends OK), the client goes, or the server shuts down
/// (the stream then ends with `UNAVAILABLE`, as live streams do).
pub async fn pace(
    mut feed: mpsc::Receiver<Result<Timed, Status>>,
    tx: mpsc::Sender<Result<v1::ObserveMessage, Status>>,
    speed: f64,
    mut shutdown: watch::Receiver<Option<String>>,
) {
    let start = Instant::now();
    let ended = |reason: String| Status::unavailable(format!("replay ended: {reason}"));
    loop {
        let next = tokio::select! {
            biased;
            reason = closed(&mut shutdown) => {
                let _ = tx.send(Err(ended(reason))).await;
                return;
            }
            _ = tx.closed() => return,
            next = feed.recv() => next,
        };
        let Timed { at_s, message } = match next {
            None => return,
            Some(Err(status)) => {
                let _ = tx.send(Err(status)).await;
                return;
            }
            Some(Ok(timed)) => timed,
        };
        let due = Duration::try_from_secs_f64((at_s / speed).max(0.0))
            .ok()
            .and_then(|d| start.checked_add(d));
        let wait = async {
            match due {
                Some(due) => tokio::time::sleep_until(due).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            biased;
            reason = closed(&mut shutdown) => {
                let _ = tx.send(Err(ended(reason))).await;
                return;
            }
            _ = tx.closed() => return,
            _ = wait => {}
        }
        tokio::select! {
            biased;
            reason = closed(&mut shutdown) => {
                let _ = tx.send(Err(ended(reason))).await;
                return;
            }
            sent = tx.send(Ok(message)) => if sent.is_err() {
                return;
            },
        }
    }
}
