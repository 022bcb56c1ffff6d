//! A recording played back as an observe stream: a [`Reader`] reads timed messages
//! in short bursts on the blocking pool, [`feed`] passes them through a bounded
//! channel without holding a thread, and [`pace`] sends each at its simulated time
//! divided by the speed.
//!
//! Two feeds, one per [`super::recordings::Playback`]:
//! - [`ReadRecorded`]: the frames, instrument states and events as recorded;
//! - [`ReadResimulated`]: the recorded poses through a fresh build of the recorded
//!   scene ([`crate::recording::Resimulation`]), sending the new frames and
//!   instrument states, the contact events they give, and the recorded events that
//!   do not come from the physics (stations joining and leaving, rejected input,
//!   the recorder's reports). Each tick's messages are made by
//!   [`crate::frame::TickOutputs`], as the live session made them, and sent in the
//!   order the session wrote them. With the same build and scene it sends what
//!   `ReadRecorded` sends; with another it shows what would have happened.
//!
//! Both start at an offset the same way ([`FromOffset`]).

use std::sync::Arc;
use std::time::Duration;

use laparo_proto::text::printable;
use laparo_proto::v1;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;
use tonic::Status;

use super::read_status::read_status;
use super::stream::{Item, Wrap};
use crate::recording::reader::Stamped;
use crate::recording::{MeshFiles, ReadError, Recorded, Recording, ResimError, Resimulation};
use crate::session::closing::closed;

/// A message to send at `at_s` of simulated time after the replay's start offset.
pub struct Timed {
    pub at_s: f64,
    pub message: v1::ObserveMessage,
}

/// Messages a reader read in one burst, to be sent before the next.
type Burst = Vec<Result<Timed, Status>>;

/// Where a reader puts what it reads.
struct Feed<'a> {
    out: &'a mut Burst,
}

impl Feed<'_> {
    fn send(&mut self, at_s: f64, item: Item) -> bool {
        if let Some(message) = v1::ObserveMessage::wrap(item) {
            self.out.push(Ok(Timed { at_s, message }));
        }
        true
    }

    fn fail(&mut self, status: Status) {
        self.out.push(Err(status));
    }
}

/// Messages read in one burst: a few ticks of a recording (each tick is a surface
/// frame and the instruments' states), so that a burst holds its blocking thread
/// for a fraction of a millisecond to a few milliseconds (a re-simulated tick is
/// a mechanics step) and its memory stays a few frames.
pub const BURST_MESSAGES: usize = 16;

/// Recorded messages a burst reads at most, sent or not, and ticks a re-simulated
/// burst steps at most, recorded or stepped through where the recorder lost frames
/// (see `step_to`). Before a start offset nothing is sent, so without these a
/// first burst read (or re-simulated) everything up to the offset on one blocking
/// thread, deaf to a client that had gone: a re-simulated replay of a large scene
/// cancelled at once went on for 40 s. Between bursts [`feed`] looks whether the
/// stream is still wanted.
pub const BURST_READS: usize = 1024;
pub const BURST_TICKS: usize = 16;

/// A replay's reading, done in bursts on the blocking pool ([`feed`]).
pub trait Reader: Send + 'static {
    /// Reads the next messages into `out` (about [`BURST_MESSAGES`]; a re-simulated
    /// tick goes in whole); `false` once the recording is read (or failed, the
    /// failure last in `out`).
    fn read(&mut self, out: &mut Burst) -> bool;
}

/// Reads `reader` onto `feed` in bursts: each burst on a blocking thread, then
/// its messages sent without one, waiting for the paced stream as long as it
/// takes. A slow replay therefore holds no thread while its client is paced, and
/// any number of them leave the blocking pool to listing and other replays. Ends
/// when the reader does or the stream is gone.
pub async fn feed(mut reader: impl Reader, feed: mpsc::Sender<Result<Timed, Status>>) {
    loop {
        if feed.is_closed() {
            return;
        }
        let burst = tokio::task::spawn_blocking(move || {
            let mut out = Vec::with_capacity(BURST_MESSAGES);
            let more = reader.read(&mut out);
            (reader, out, more)
        })
        .await;
        let Ok((back, out, more)) = burst else {
            return;
        };
        for m in out {
            if feed.send(m).await.is_err() {
                return;
            }
        }
        if !more {
            return;
        }
        reader = back;
    }
}

/// The messages of a recording, owned (kept between bursts).
type Messages = Box<dyn Iterator<Item = Result<Stamped<Recorded>, ReadError>> + Send>;

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

    /// Takes the message of simulated time `t`.
    fn pass(&mut self, t: f64, item: Item, out: &mut Feed) -> bool {
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
    fn flush(&mut self, out: &mut Feed) -> bool {
        self.held.drain(..).all(|item| out.send(0.0, item))
    }
}

/// The recording's frames, instrument states and events from `offset` on, decoded
/// a burst at a time, until the file ends or a message does not read (the stream
/// then ends with its status).
pub struct ReadRecorded {
    messages: Messages,
    gate: FromOffset,
    name: String,
}

impl ReadRecorded {
    pub fn new(recording: Arc<Recording>, name: String, offset: f64) -> Self {
        ReadRecorded {
            messages: Box::new(recording.into_messages()),
            gate: FromOffset::new(offset),
            name,
        }
    }
}

impl Reader for ReadRecorded {
    fn read(&mut self, burst: &mut Burst) -> bool {
        let mut out = Feed { out: burst };
        let mut reads = 0;
        while out.out.len() < BURST_MESSAGES && reads < BURST_READS {
            reads += 1;
            let Some(m) = self.messages.next() else {
                self.gate.flush(&mut out);
                return false;
            };
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    out.fail(read_status(&self.name, &e));
                    return false;
                }
            };
            let (t, item) = match m.message {
                Recorded::Scene(_) | Recorded::Pose(_) => continue,
                Recorded::Surface(f) => (f.sim_time_s, Item::Surface(f)),
                Recorded::Instrument(s) => (s.sim_time_s, Item::State(s)),
                Recorded::Event(e) => (e.sim_time_s, Item::Event(e)),
            };
            self.gate.pass(t, item, &mut out);
        }
        true
    }
}

/// A replay's reading, told whether its recording was still being written when
/// it was opened (`held_s`: the seconds it held then; `None`: a finished one).
///
/// A file still being written is read as it stood when the replay opened it: its
/// complete chunks then. Its end is not the session's, so a replay that reaches it
/// ends with `OUT_OF_RANGE` ("reading past the end of a file that may grow", as
/// gRPC describes the code), naming what it played and what to do for the rest,
/// where a finished recording's replay ends OK. A failure the reader ends with is
/// sent as it is.
pub struct StillRecording<R> {
    reader: R,
    name: String,
    held_s: Option<f64>,
}

impl<R: Reader> StillRecording<R> {
    pub fn new(reader: R, name: String, held_s: Option<f64>) -> Self {
        StillRecording {
            reader,
            name,
            held_s,
        }
    }
}

impl<R: Reader> Reader for StillRecording<R> {
    fn read(&mut self, out: &mut Burst) -> bool {
        if self.reader.read(out) {
            return true;
        }
        if let Some(held_s) = self.held_s
            && !matches!(out.last(), Some(Err(_)))
        {
            out.push(Err(Status::out_of_range(format!(
                "the replay played `{}` up to {held_s:.2} s, where it stood when the \
                 replay began: its session was still being recorded; replay it again \
                 for what came since, or observe the session live",
                printable(&self.name),
            ))));
        }
        false
    }
}

/// Whether a recorded event came from the physics (and is derived again by a
/// re-simulation) rather than from the people and machinery around it.
fn from_physics(e: &v1::Event) -> bool {
    e.kind == v1::EventKind::ContactBegan as i32 || e.kind == v1::EventKind::ContactEnded as i32
}

/// The recording re-simulated (see the module documentation) from `offset` on, a
/// burst at a time as [`ReadRecorded`] reads. Every tick before the offset is
/// simulated too (the physics needs them) but not sent. A scene that no longer
/// builds or a mesh that is not the recorded one ends the stream with
/// `FAILED_PRECONDITION`. The scene is built in the first burst.
pub struct ReadResimulated {
    recording: Arc<Recording>,
    run: Option<Resimulation>,
    messages: Messages,
    gate: FromOffset,
    name: String,
    /// The server's scene directory, where the recorded scene's mesh is read
    /// ([`MeshFiles::Served`]).
    scene_dir: Option<std::path::PathBuf>,
    /// The recorded tick (and its time) the run is stepping to: a burst that fills
    /// on the way leaves the rest of the way to the next.
    pending: Option<(u64, f64)>,
}

/// Steps `run` toward recorded tick `tick` (at `at_s` s), sending each step's
/// messages through `gate` in the order a session writes a tick (its contact
/// events, then the surface and every instrument's state), until it is reached
/// (`true`) or `ticks`, the burst's steps so far, reaches [`BURST_TICKS`]
/// (`false`): a recording whose frames lie many ticks apart (a recorder that fell
/// behind) is stepped a burst at a time like any other, deaf to no client and
/// holding a few frames.
fn step_to(
    run: &mut Resimulation,
    tick: u64,
    at_s: f64,
    gate: &mut FromOffset,
    out: &mut Feed<'_>,
    ticks: &mut usize,
) -> Result<bool, ResimError> {
    run.run_to(tick, at_s, |stepped| {
        let frame = stepped.frame;
        let t = frame.sim_time;
        let surface = v1::SurfaceFrame {
            tick: frame.tick,
            sim_time_s: frame.sim_time,
            positions: frame.surface,
        };
        let items = (stepped.events.into_iter().map(Item::Event))
            .chain([Item::Surface(surface)])
            .chain(frame.instruments.into_iter().map(Item::State));
        for item in items {
            gate.pass(t, item, out);
        }
        *ticks += 1;
        *ticks < BURST_TICKS
    })?;
    Ok(run.sim().tick >= tick)
}

impl ReadResimulated {
    /// Re-simulates `recording` (served as `name`) from `offset` s, its scene's
    /// mesh read inside `scene_dir`, the server's scene directory, or, without
    /// one, from the meshes built in ([`MeshFiles::Served`]).
    pub fn new(
        recording: Arc<Recording>,
        name: String,
        offset: f64,
        scene_dir: Option<std::path::PathBuf>,
    ) -> Self {
        ReadResimulated {
            messages: Box::new(recording.clone().into_messages()),
            recording,
            run: None,
            gate: FromOffset::new(offset),
            name,
            scene_dir,
            pending: None,
        }
    }

    /// Why the recording cannot be re-simulated, with the server's scene directory
    /// and the recorded one (server paths, none of the client's business) said as
    /// `<scene directory>`.
    fn cannot(&self, e: ResimError) -> Status {
        let mut why = e.to_string();
        let dirs = [
            self.scene_dir.as_ref(),
            self.recording.meta().scene_dir.as_ref(),
        ];
        for dir in dirs.into_iter().flatten() {
            why = why.replace(&*dir.to_string_lossy(), "<scene directory>");
        }
        Status::failed_precondition(format!("`{}` cannot be re-simulated: {why}", self.name))
    }
}

impl Reader for ReadResimulated {
    fn read(&mut self, burst: &mut Burst) -> bool {
        let mut out = Feed { out: burst };
        let mut run = match self.run.take() {
            Some(run) => run,
            None => match Resimulation::new(
                &self.recording,
                self.recording.meta(),
                MeshFiles::Served(self.scene_dir.as_deref()),
            ) {
                Ok(run) => run,
                Err(e) => {
                    out.fail(self.cannot(e));
                    return false;
                }
            },
        };
        let (mut reads, mut ticks) = (0, 0);
        loop {
            if let Some((tick, at_s)) = self.pending {
                match step_to(&mut run, tick, at_s, &mut self.gate, &mut out, &mut ticks) {
                    Ok(true) => self.pending = None,
                    Ok(false) => break,
                    Err(e) => {
                        out.fail(self.cannot(e));
                        return false;
                    }
                }
            }
            if !(out.out.len() < BURST_MESSAGES && reads < BURST_READS && ticks < BURST_TICKS) {
                break;
            }
            reads += 1;
            let Some(m) = self.messages.next() else {
                self.gate.flush(&mut out);
                return false;
            };
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    out.fail(read_status(&self.name, &e));
                    return false;
                }
            };
            match m.message {
                Recorded::Event(e) if !from_physics(&e) => {
                    self.gate.pass(e.sim_time_s, Item::Event(e), &mut out);
                }
                Recorded::Surface(f) => self.pending = Some((f.tick, f.sim_time_s)),
                _ => {}
            }
        }
        self.run = Some(run);
        true
    }
}

/// Sends `feed`'s messages at their times divided by `speed` after now, until the
/// feed ends (the stream then ends OK), the client goes, the client takes none of
/// them for `stall` (the stream then ends: a replay that nobody reads held its
/// `--max-replays` slot for ever, and 64 of them, any token's, refused everyone
/// else's), or the server shuts down (the stream then ends with `UNAVAILABLE`, as
/// live streams do).
pub async fn pace(
    mut feed: mpsc::Receiver<Result<Timed, Status>>,
    tx: mpsc::Sender<Result<v1::ObserveMessage, Status>>,
    speed: f64,
    mut shutdown: watch::Receiver<Option<String>>,
    stall: Duration,
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
            // The queue stayed full: the client took nothing for the whole wait.
            _ = tokio::time::sleep(stall) => return,
        }
    }
}
