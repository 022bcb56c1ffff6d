//! The recorder thread: owns a session's [`McapSink`] and is fed through a bounded
//! channel, so that writing, compressing and disk stalls never reach the mechanics
//! thread.
//!
//! The session side only ever calls [`Recorder::offer`], which never waits: when
//! the channel is full the item is left out, counted in [`RecorderStats::dropped`],
//! and the first drop of a lagging spell comes back as a [`Report`] for the session
//! to publish as `EVENT_KIND_RECORDER_LAGGING`; the recorder thread also writes a
//! lagging event into the file where the gap is, so a reviewer sees it. When the
//! file cannot be created or written (unwritable directory, disk full) the thread
//! stops, counts the error and the next offer reports it once
//! (`EVENT_KIND_RECORDER_ERROR`); the session goes on unrecorded.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Instant, SystemTime};

use laparo_proto::v1;

use super::writer::{FLUSH_INTERVAL, McapSink, SessionHeader};
use crate::frame::Frame;

/// Items the channel holds: several seconds of ticks and poses at the rates a scene
/// and a station reach; a tick's frame is an `Arc`, so a full channel is small.
pub const CHANNEL_CAPACITY: usize = 4096;

/// The share of the channel poses may fill: past it, a station's intake waits for
/// the recorder (`service/recorder_room.rs`). A station sends at most its pose
/// budget at once (10,000 poses after a 5 s stall, under the default limits), more
/// than the whole channel; the mechanics thread never waits, so what poses leave
/// free is what keeps its frames: half the channel is two seconds of ticks at
/// 1 kHz with events.
pub const POSE_SHARE: f64 = 0.5;

/// Something to record.
#[derive(Debug)]
pub enum Item {
    /// A pose the station service accepted, with when it was received.
    Pose {
        received: SystemTime,
        pose: v1::DevicePose,
    },
    /// One tick's frame, with when it was published; encoded on the recorder
    /// thread.
    Frame { frame: Arc<Frame>, wall: SystemTime },
    /// An event of the session, with when it happened.
    Event { event: v1::Event, wall: SystemTime },
}

impl Item {
    fn describe(&self) -> String {
        match self {
            Item::Pose { pose, .. } => format!("pose {} of `{}`", pose.sequence, pose.instrument),
            Item::Frame { frame, .. } => format!("frame of tick {}", frame.tick),
            Item::Event { event, .. } => format!("event at tick {}", event.tick),
        }
    }
}

/// What [`Recorder::offer`] asks the session to tell its clients.
#[derive(Clone, Debug, PartialEq)]
pub enum Report {
    /// The channel was full: the item described was left out of the recording.
    Lagging { dropped_total: u64, detail: String },
    /// The recorder stopped on an error; nothing more is recorded.
    Failed { error: String },
}

impl Report {
    pub fn kind(&self) -> v1::EventKind {
        match self {
            Report::Lagging { .. } => v1::EventKind::RecorderLagging,
            Report::Failed { .. } => v1::EventKind::RecorderError,
        }
    }

    /// The event telling the session's clients, at tick `tick` (`sim_time_s`).
    pub fn event(&self, tick: u64, sim_time_s: f64) -> v1::Event {
        v1::Event {
            tick,
            sim_time_s,
            kind: self.kind() as i32,
            station_id: None,
            instrument: None,
            detail: self.detail(),
        }
    }

    /// The event's detail.
    pub fn detail(&self) -> String {
        match self {
            Report::Lagging {
                dropped_total,
                detail,
            } => format!(
                "the recorder fell behind: {detail} left out of the recording \
                 ({dropped_total} items left out so far)"
            ),
            Report::Failed { error } => {
                format!("the recorder stopped: {error}; the session goes on unrecorded")
            }
        }
    }
}

/// What stopped a recorder; each names the file and the cause (an MCAP I/O error
/// with its sources, so that a full disk says so).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RecorderError {
    #[error("cannot create {file}: {cause}")]
    Create { file: String, cause: String },
    #[error("cannot write {file}: {cause}")]
    Write { file: String, cause: String },
    #[error("cannot finish {file}: {cause}")]
    Finish { file: String, cause: String },
}

/// Counters of a recorder, readable while it runs.
#[derive(Debug, Default)]
pub struct RecorderStats {
    /// Items handed to the recorder thread.
    pub sent: AtomicU64,
    /// Items left out because the channel was full.
    pub dropped: AtomicU64,
    /// Errors that stopped the recorder (0 or 1).
    pub errors: AtomicU64,
    /// Messages written to the file.
    pub written: AtomicU64,
    /// Items taken off the channel and written.
    pub processed: AtomicU64,
    /// Most items waiting in the channel, seen when one was handed over.
    pub max_backlog: AtomicU64,
    /// Longest time from a frame's publication to its being written, µs: how far
    /// behind the live session the file has been.
    pub max_lag_us: AtomicU64,
}

/// State the recorder thread shares with the session side.
#[derive(Debug, Default)]
struct Shared {
    stats: RecorderStats,
    error: Mutex<Option<RecorderError>>,
    /// Whether the file was created.
    created: AtomicBool,
    /// Whether the thread has ended: the file is finished, or failed.
    ended: AtomicBool,
}

impl Shared {
    /// Whether the thread has not ended: the file has no summary and footer yet.
    fn is_writing(&self) -> bool {
        !self.ended.load(Ordering::Acquire)
    }

    /// The error that stopped the recorder, if any.
    fn failure(&self) -> Option<RecorderError> {
        self.error.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

/// Whether a recorder still writes its file, and why it failed
/// ([`Recorder::watch`]).
#[derive(Clone, Debug)]
pub struct RecorderWatch {
    path: PathBuf,
    shared: Arc<Shared>,
}

impl RecorderWatch {
    /// The recording's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// As [`Recorder::is_writing`].
    pub fn is_writing(&self) -> bool {
        self.shared.is_writing()
    }

    /// As [`Recorder::error`].
    pub fn error(&self) -> Option<String> {
        self.shared.failure().map(|e| e.to_string())
    }
}

/// Least time between two lagging reports, ms: a recorder that keeps falling
/// behind and catching up is reported once a second, not once a tick.
const LAG_REPORT_INTERVAL_MS: u64 = 1000;

enum Msg {
    Item(Item),
    Finish,
}

/// A session's recorder: the sending side of the channel and the thread's handle.
pub struct Recorder {
    tx: SyncSender<Msg>,
    /// Items the channel holds.
    capacity: usize,
    path: PathBuf,
    shared: Arc<Shared>,
    created: Instant,
    /// ms since `created` of the last lagging report, plus one; 0: never.
    last_lag_report: AtomicU64,
    /// Inside a spell of drops already reported.
    lagging: AtomicBool,
    error_reported: AtomicBool,
    finished: AtomicBool,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl Recorder {
    /// Starts recording to `path` (created anew) on a thread of its own. Fails only
    /// when the thread cannot start: a file that cannot be created is reported
    /// through [`offer`](Self::offer) like any later error.
    pub fn start(path: PathBuf, header: SessionHeader) -> std::io::Result<Self> {
        Self::with_capacity(path, header, CHANNEL_CAPACITY)
    }

    /// [`start`](Self::start) with a channel of `capacity` items.
    pub fn with_capacity(
        path: PathBuf,
        header: SessionHeader,
        capacity: usize,
    ) -> std::io::Result<Self> {
        let (tx, rx) = sync_channel(capacity);
        let shared = Arc::new(Shared::default());
        let thread = {
            let (shared, path) = (shared.clone(), path.clone());
            std::thread::Builder::new()
                .name("recorder".into())
                .spawn(move || {
                    run(&path, &header, &rx, &shared);
                    shared.ended.store(true, Ordering::Release);
                })?
        };
        Ok(Recorder {
            tx,
            capacity,
            path,
            shared,
            created: Instant::now(),
            last_lag_report: AtomicU64::new(0),
            lagging: AtomicBool::new(false),
            error_reported: AtomicBool::new(false),
            finished: AtomicBool::new(false),
            thread: Mutex::new(Some(thread)),
        })
    }

    /// Hands `item` to the recorder thread without waiting. `Some` when the
    /// session should tell its clients something (see [`Report`]).
    pub fn offer(&self, item: Item) -> Option<Report> {
        if self.finished.load(Ordering::Relaxed) {
            return None;
        }
        let stats = &self.shared.stats;
        match self.tx.try_send(Msg::Item(item)) {
            Ok(()) => {
                let sent = stats.sent.fetch_add(1, Ordering::Relaxed) + 1;
                let backlog = sent.saturating_sub(stats.processed.load(Ordering::Relaxed));
                stats.max_backlog.fetch_max(backlog, Ordering::Relaxed);
                self.lagging.store(false, Ordering::Relaxed);
                None
            }
            Err(TrySendError::Full(Msg::Item(item))) => {
                let dropped_total = stats.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                if self.lagging.swap(true, Ordering::Relaxed) {
                    return None;
                }
                let now = self.created.elapsed().as_millis() as u64 + 1;
                let last = self.last_lag_report.load(Ordering::Relaxed);
                if last != 0 && now - last < LAG_REPORT_INTERVAL_MS {
                    return None;
                }
                self.last_lag_report.store(now, Ordering::Relaxed);
                Some(Report::Lagging {
                    dropped_total,
                    detail: item.describe(),
                })
            }
            Err(_) => {
                if self.error_reported.swap(true, Ordering::Relaxed) {
                    return None;
                }
                Some(Report::Failed {
                    error: self
                        .error()
                        .unwrap_or_else(|| "the recorder thread ended".into()),
                })
            }
        }
    }

    /// The recording's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A handle on whether this recorder still writes its file and why it failed,
    /// that outlives the recorder and keeps none of its buffers: the server keeps
    /// it to tell a listing which files a recorder of its own failed to finish.
    pub fn watch(&self) -> RecorderWatch {
        RecorderWatch {
            path: self.path.clone(),
            shared: self.shared.clone(),
        }
    }

    /// Whether the file is still being written: the thread has not ended, so the
    /// file has no summary and footer yet. False once it is finished or failed.
    pub fn is_writing(&self) -> bool {
        self.shared.is_writing()
    }

    /// Whether the file was created (it may have failed later).
    pub fn created_file(&self) -> bool {
        self.shared.created.load(Ordering::Relaxed)
    }

    /// Items handed over and not yet written: what waits in the channel, and the
    /// one being written.
    pub fn backlog(&self) -> u64 {
        let stats = &self.shared.stats;
        let processed = stats.processed.load(Ordering::Relaxed);
        stats.sent.load(Ordering::Relaxed).saturating_sub(processed)
    }

    /// Items written so far: while it grows, the recorder is draining its channel.
    pub fn processed(&self) -> u64 {
        self.shared.stats.processed.load(Ordering::Relaxed)
    }

    /// The backlog at which stations hold their poses back
    /// ([`POSE_SHARE`] of the channel), so that a burst of poses leaves the rest
    /// to the ticks' frames and events, which are never held back.
    pub fn pose_room(&self) -> u64 {
        (self.capacity as f64 * POSE_SHARE) as u64
    }

    pub fn stats(&self) -> &RecorderStats {
        &self.shared.stats
    }

    /// What a client arriving now should be told: that the recorder stopped, that
    /// items were left out, both or nothing. Live streams were told when it
    /// happened; a station or observer joining later learns it from this.
    pub fn standing_reports(&self) -> Vec<Report> {
        let mut out = Vec::new();
        let dropped_total = self.shared.stats.dropped.load(Ordering::Relaxed);
        if dropped_total > 0 {
            out.push(Report::Lagging {
                dropped_total,
                detail: "earlier items were".into(),
            });
        }
        if let Some(error) = self.error() {
            out.push(Report::Failed { error });
        }
        out
    }

    /// The error that stopped the recorder, if any, as clients are told it.
    pub fn error(&self) -> Option<String> {
        self.failure().map(|e| e.to_string())
    }

    /// The error that stopped the recorder, if any.
    pub fn failure(&self) -> Option<RecorderError> {
        self.shared.failure()
    }

    /// Writes what the channel holds, then the file's summary and footer, and waits
    /// for the thread. Later offers are ignored. Idempotent. Returns the error that
    /// stopped the recorder, if any.
    pub fn finish(&self) -> Result<(), RecorderError> {
        if !self.finished.swap(true, Ordering::Relaxed) {
            // Waits while the channel is full: closing is not on the tick's path.
            let _ = self.tx.send(Msg::Finish);
        }
        let thread = self.thread.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(t) = thread {
            let _ = t.join();
        }
        self.failure().map_or(Ok(()), Err)
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// An error and the errors that caused it, outermost first: an MCAP I/O error
/// alone says only that writing failed, its source says the disk is full. The MCAP
/// I/O error's own words ("I/O error from writing, or reading a compression
/// stream") are left out: they name no cause, and a file that cannot be created was
/// neither written nor read.
pub(crate) fn with_causes(e: &(dyn std::error::Error + 'static)) -> String {
    let (mut text, mut cause) = match (e.downcast_ref::<mcap::McapError>(), e.source()) {
        (Some(mcap::McapError::Io(_)), Some(source)) => (source.to_string(), source.source()),
        _ => (e.to_string(), e.source()),
    };
    while let Some(c) = cause {
        let c_text = c.to_string();
        if !text.contains(&c_text) {
            text = format!("{text}: {c_text}");
        }
        cause = c.source();
    }
    text
}

/// The thread: create the file, write items as they come, close a chunk at least
/// every [`FLUSH_INTERVAL`], finish on [`Msg::Finish`] or when the sender is gone.
fn run(path: &Path, header: &SessionHeader, rx: &Receiver<Msg>, shared: &Shared) {
    // The file's name alone: the message goes to clients, which know no server
    // paths.
    let file = path
        .file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy()
        .into_owned();
    let fail = |error: fn(String, String) -> RecorderError,
                e: &(dyn std::error::Error + 'static)| {
        let error = error(file.clone(), with_causes(e));
        tracing::error!(session = %header.session_id, "recorder: {error}");
        shared.stats.errors.fetch_add(1, Ordering::Relaxed);
        *shared.error.lock().unwrap_or_else(|e| e.into_inner()) = Some(error);
    };
    let create = |file, cause| RecorderError::Create { file, cause };
    let write = |file, cause| RecorderError::Write { file, cause };
    let finish = |file, cause| RecorderError::Finish { file, cause };
    let mut sink = match McapSink::create(path, header) {
        Ok(sink) => sink,
        Err(e) => return fail(create, &e),
    };
    shared.created.store(true, Ordering::Relaxed);
    let mut seen_dropped = 0;
    let mut last = (0u64, 0.0f64);
    loop {
        let item = match rx.recv_timeout(FLUSH_INTERVAL) {
            Ok(Msg::Item(item)) => Some(item),
            Ok(Msg::Finish) | Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => None,
        };
        let written = sink.messages;
        let result = (|| {
            if let Some(item) = item {
                match &item {
                    Item::Frame { frame, .. } => last = (frame.tick, frame.sim_time),
                    Item::Event { event, .. } => last = (event.tick, event.sim_time_s),
                    Item::Pose { .. } => {}
                }
                let dropped = shared.stats.dropped.load(Ordering::Relaxed);
                if dropped > seen_dropped {
                    let gap = v1::Event {
                        tick: last.0,
                        sim_time_s: last.1,
                        kind: v1::EventKind::RecorderLagging as i32,
                        station_id: None,
                        instrument: None,
                        detail: format!(
                            "{} items left out of the recording before this point",
                            dropped - seen_dropped
                        ),
                    };
                    seen_dropped = dropped;
                    sink.write_event(&gap, SystemTime::now())?;
                }
                match &item {
                    Item::Pose { received, pose } => sink.write_pose(*received, pose)?,
                    Item::Frame { frame, wall } => {
                        sink.write_frame(frame, *wall)?;
                        let lag = wall.elapsed().map_or(0, |d| d.as_micros() as u64);
                        shared.stats.max_lag_us.fetch_max(lag, Ordering::Relaxed);
                    }
                    Item::Event { event, wall } => sink.write_event(event, *wall)?,
                }
                shared.stats.processed.fetch_add(1, Ordering::Relaxed);
            }
            sink.flush_if_due()
        })();
        shared
            .stats
            .written
            .fetch_add(sink.messages - written, Ordering::Relaxed);
        if let Err(e) = result {
            return fail(write, &e);
        }
    }
    let result = sink.finish().and_then(|file: File| Ok(file.sync_all()?));
    if let Err(e) = result {
        fail(finish, &e);
    }
}
