//! `Recordings`: what the server's recordings directory holds, and a recording
//! played back as an observe stream.
//!
//! Who may: listing, any caller. Replaying a finished recording, any caller too —
//! trainees review sessions, theirs or an instructor's, which is what recordings
//! are for. A recording still being written is a session going on: watching it is
//! observing, which needs an instructor as `Observe` does.
//!
//! Only regular files directly in the recordings directory are served, never
//! through a symbolic link; files are named relative to the directory in every
//! status, and what comes from files or clients (names, metadata) is escaped
//! ([`printable`]) in statuses and listings.
//!
//! `ListRecordings` gives the files [`crate::recording::list`](fn@crate::recording::list) reads, each with
//! its state: finished, still written by a session of this server (with what its
//! complete chunks hold), or unfinished — cut short by a stopped server, listed
//! with what its complete chunks hold so that a crash does not hide recoverable
//! sessions. A file that cannot be read as a recording — not MCAP, corrupt where
//! the listing looks, of another format version — is left out (and logged): a
//! listing has no place to say why, `Replay` of it says it, and
//! `laparo recordings list --dir` shows it. The listing
//! checks what it reads (header, summary, metadata, the last chunk with a frame); a
//! chunk damaged elsewhere is found by the replay that reaches it.
//!
//! `Replay` ([`Playback::Recorded`]; [`Playback::Resimulate`] sends a re-simulation
//! the same way, see [`super::replay`]): the scene first, then the surface frames,
//! instrument states and events in recorded order, the message of simulated time
//! `t` sent `(t − start_offset_s) / speed` after the stream starts (deadlines
//! counted from one start instant, so nothing drifts). Nothing is skipped: a client
//! slower than the pace slows its own replay down, and the file's bounded read-ahead
//! ([`READ_AHEAD`]) keeps the reading waiting for it, without a thread: the file is
//! read in short bursts on the blocking pool ([`super::replay::feed`]). At most
//! [`super::capacity::Capacity::replays`] replays stream at once; one more is
//! answered `RESOURCE_EXHAUSTED`, and a re-simulated replay of a large scene counts
//! as several ([`super::capacity::replay_weight`]). From an offset, the
//! newest tick at or before it (its surface and instrument states, and the events
//! stamped at the offset) goes first, at once, so that a viewer shows the liver as it
//! was there; earlier ticks and events are not sent. The stream ends with the
//! recording (OK), with `DATA_LOSS` at a damaged chunk, or with `UNAVAILABLE` when
//! the server shuts down.

use std::path::{Component, Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, UNIX_EPOCH};

use laparo_proto::text::{Number, needs_escape, printable};
use laparo_proto::v1;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::auth::{Caller, Role, caller};
use super::capacity::{replay_weight, tetrahedra};
use super::read_status::read_status;
use super::registry::Registry;
use super::replay::{ReadRecorded, ReadResimulated, StillRecording, feed, pace};
use super::stream::OUTBOUND;
use crate::recording::list::{self, FileState};
use crate::recording::{ReadError, Recording};

pub struct RecordingsService {
    pub registry: Arc<Registry>,
    /// What the recordings directory's files were found to hold, by name, size and
    /// modification time; one listing reads at a time ([`list::Lister`]).
    pub lister: Arc<list::Lister>,
    /// How long a replay's client may take none of its messages before the replay
    /// ends and its slot is free (the server's station timeout).
    pub timeout: super::liveness::StationTimeout,
}

/// Fastest replay, times real time: a few minutes of frames in seconds.
pub const MAX_SPEED: f64 = 100.0;
/// Slowest replay, times real time: a minute of session in under two hours.
pub const MIN_SPEED: f64 = 0.01;
/// Decoded messages the reading may be ahead of the stream by.
pub const READ_AHEAD: usize = 32;

/// How a recording is played back (`ReplayRequest.mode`), decided in one place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Playback {
    /// The recorded frames, instrument states and events as they were.
    Recorded,
    /// The recorded poses through a fresh build of the recorded scene
    /// ([`super::replay::ReadResimulated`]).
    Resimulate,
}

impl Playback {
    pub fn from_request(mode: i32) -> Result<Self, Status> {
        match v1::ReplayMode::try_from(mode) {
            Ok(v1::ReplayMode::Unspecified | v1::ReplayMode::Recorded) => Ok(Playback::Recorded),
            Ok(v1::ReplayMode::Resimulate) => Ok(Playback::Resimulate),
            Err(_) => Err(Status::invalid_argument(format!(
                "unknown replay mode {mode}"
            ))),
        }
    }
}

/// A replay's speed factor: absent 1; finite, within [`MIN_SPEED`]..=[`MAX_SPEED`].
pub fn speed(asked: Option<f64>) -> Result<f64, Status> {
    match asked {
        None => Ok(1.0),
        Some(s) if (MIN_SPEED..=MAX_SPEED).contains(&s) => Ok(s),
        Some(s) => Err(Status::invalid_argument(format!(
            "the replay speed must be a finite factor from {MIN_SPEED} to {MAX_SPEED} \
             (got {})",
            Number(s)
        ))),
    }
}

/// A replay's start offset, s: absent 0; finite and ≥ 0 (checked against the
/// recording's duration once it is open).
pub fn start_offset(asked: Option<f64>) -> Result<f64, Status> {
    match asked {
        None => Ok(0.0),
        Some(t) if t.is_finite() && t >= 0.0 => Ok(t),
        Some(t) => Err(Status::invalid_argument(format!(
            "the start offset must be finite and ≥ 0 s (got {})",
            Number(t)
        ))),
    }
}

/// Checks that `name` is a bare `.mcap` file name: no directory part, no `..`, not
/// absolute, so that it names a file of the recordings directory and nothing else;
/// and without control characters, which no recording the server writes has
/// (its names are the session id and the scene name reduced to `[A-Za-z0-9_-]`)
/// and a listing leaves out. The name is echoed escaped ([`printable`]).
pub fn file_name(name: &str) -> Result<&str, Status> {
    let bad = |why: &str| {
        Err(Status::invalid_argument(format!(
            "`{}` is not a recording's file name: {why}",
            printable(name)
        )))
    };
    if name.is_empty() {
        return bad("it is empty");
    }
    if name.contains(['/', '\\', '\0']) {
        return bad("give the bare file name, without a directory");
    }
    if name.chars().any(needs_escape) {
        return bad("it holds control characters");
    }
    let mut components = Path::new(name).components();
    if !matches!(
        (components.next(), components.next()),
        (Some(Component::Normal(_)), None)
    ) {
        return bad("give the bare file name, without a directory");
    }
    if !name.ends_with(".mcap") || name.len() == ".mcap".len() {
        return bad("recordings are `.mcap` files");
    }
    Ok(name)
}

impl RecordingsService {
    fn dir(&self) -> Result<PathBuf, Status> {
        self.registry.recordings.clone().ok_or_else(|| {
            Status::failed_precondition(
                "this server records no sessions (it runs without a recordings directory), \
                 so it has no recordings to list or replay",
            )
        })
    }
}

/// Runs `f` off the async runtime's threads.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, Status> + Send + 'static,
) -> Result<T, Status> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Status::internal(format!("reading recordings failed: {e}")))?
}

/// A listed recording as the contract states it; what comes from the file's
/// metadata is escaped ([`printable`]). `failure`: why a recorder of this server
/// failed to finish it; the caller asks only for a file without its summary.
fn info(
    file: String,
    size_bytes: u64,
    l: &list::Listing,
    failure: Option<String>,
) -> v1::RecordingInfo {
    v1::RecordingInfo {
        file,
        session_id: printable(&l.session_id).into_owned(),
        scene: printable(&l.scene).into_owned(),
        start: Some((UNIX_EPOCH + Duration::from_nanos(l.start_unix_ns)).into()),
        duration_s: l.duration_s,
        size_bytes,
        in_progress: l.state == FileState::InProgress,
        state: match l.state {
            FileState::Complete => v1::RecordingState::Complete,
            FileState::InProgress => v1::RecordingState::InProgress,
            FileState::Unfinished if failure.is_some() => v1::RecordingState::Failed,
            FileState::Unfinished => v1::RecordingState::Unfinished,
        } as i32,
        failure: failure.unwrap_or_default(),
    }
}

/// A recording opened for replay, checked against the request.
struct Opened {
    recording: Recording,
    scene: v1::SceneDescription,
    /// For a recording still being written, how many seconds it held when opened:
    /// the replay ends there, and says so ([`StillRecording`]).
    held_s: Option<f64>,
}

/// How far past a recording's last tick a start offset may be, s: half the
/// millisecond its duration is given to (`laparo replay`, the console and the
/// refusal below print it so). A recording's time is the sum of its ticks, so a
/// 3.4 s recording lasts 3.399999999999993 s, and its printed duration typed back
/// must start its replay (at its last tick) rather than be refused.
const END_SLACK_S: f64 = 0.5e-3;

/// Opens `name` in `dir` for a replay by `caller` from `offset`.
fn open_for_replay(
    registry: &Registry,
    dir: &Path,
    name: &str,
    caller: &Caller,
    offset: f64,
) -> Result<Opened, Status> {
    let path = dir.join(name);
    // The entry itself, not what a link points to: only regular files of the
    // directory are recordings (and they are opened without following a link).
    match std::fs::symlink_metadata(&path) {
        Ok(m) if m.file_type().is_file() => {}
        Ok(_) => return Err(Status::not_found(format!("no recording `{name}`"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Status::not_found(format!("no recording `{name}`")));
        }
        Err(e) => {
            return Err(Status::failed_precondition(format!(
                "cannot read recording `{name}`: {}",
                printable(&e.to_string())
            )));
        }
    }
    let status = |e: ReadError| read_status(name, &e);
    let (recording, state) = list::open(&path, |p| registry.is_recording(p)).map_err(status)?;
    match state {
        FileState::Complete => {}
        FileState::InProgress if caller.role == Role::Instructor => {}
        FileState::InProgress => {
            return Err(Status::permission_denied(format!(
                "`{name}` is a session still going on: watching it needs an instructor \
                 token, as observing does; `{}` is a trainee",
                caller.name
            )));
        }
        FileState::Unfinished => {
            let why = match registry.recorder_failure(&path) {
                Some(failure) => format!(
                    "its recorder failed while the session ran ({failure}); `laparo \
                     recordings recover` completes what was written"
                ),
                None => "its server stopped while recording it; `laparo recordings \
                         recover` completes it"
                    .into(),
            };
            return Err(Status::failed_precondition(format!(
                "recording `{name}` ends without its summary: {why}"
            )));
        }
    }
    let duration = recording.duration_s().map_err(status)?;
    if offset > duration + END_SLACK_S {
        return Err(Status::out_of_range(format!(
            "the start offset {} s is past the end of `{name}`, which lasts {duration:.3} s",
            Number(offset),
        )));
    }
    let scene = recording.scene().map_err(status)?;
    let held_s = (state == FileState::InProgress).then_some(duration);
    Ok(Opened {
        recording,
        scene,
        held_s,
    })
}

#[tonic::async_trait]
impl v1::recordings_server::Recordings for RecordingsService {
    type ReplayStream = ReceiverStream<Result<v1::ObserveMessage, Status>>;

    async fn list_recordings(
        &self,
        request: Request<v1::ListRecordingsRequest>,
    ) -> Result<Response<v1::ListRecordingsResponse>, Status> {
        caller(&request)?;
        let dir = self.dir()?;
        let registry = self.registry.clone();
        let lister = self.lister.clone();
        let listed_dir = dir.clone();
        let listed = blocking(move || {
            lister
                .list_at_most(&dir, list::MAX_LISTED_FILES, |p| registry.is_recording(p))
                .map_err(|e| {
                    tracing::warn!(dir = %dir.display(), "cannot read the recordings directory: {e}");
                    // Not the directory's path: clients know no server paths.
                    Status::failed_precondition(format!(
                        "cannot read the recordings directory: {e}"
                    ))
                })
        })
        .await?;
        let (listed, left_out) = listed;
        let mut recordings = Vec::new();
        // What cannot be listed is logged once a version of the file, not at every
        // listing: the console lists every 2 s, so each bad file otherwise wrote a
        // line every 2 s for each page open.
        for l in listed {
            if l.file.chars().any(needs_escape) {
                // Not a name the server writes, nor one `Replay` takes.
                if l.fresh {
                    tracing::warn!(file = %printable(&l.file), "not listed: its name holds control characters");
                }
                continue;
            }
            match &l.entry {
                Ok(e) => {
                    let failure = (e.state == FileState::Unfinished)
                        .then(|| self.registry.recorder_failure(&listed_dir.join(&l.file)))
                        .flatten();
                    recordings.push(info(l.file, l.size_bytes, e, failure))
                }
                Err(e) if l.fresh => {
                    tracing::warn!(file = %printable(&l.file), "not listed: {}", printable(&e.to_string()))
                }
                Err(_) => {}
            }
        }
        Ok(Response::new(v1::ListRecordingsResponse {
            recordings,
            left_out: u32::try_from(left_out).unwrap_or(u32::MAX),
        }))
    }

    async fn replay(
        &self,
        request: Request<v1::ReplayRequest>,
    ) -> Result<Response<Self::ReplayStream>, Status> {
        let caller = caller(&request)?;
        let r = request.into_inner();
        super::limits::check_name("file", &r.file)?;
        let name = file_name(&r.file)?.to_string();
        let speed = speed(r.speed)?;
        let offset = start_offset(r.start_offset_s)?;
        let playback = Playback::from_request(r.mode)?;
        let dir = self.dir()?;
        // Held until both the reading and the pacing have ended: a client that goes
        // ends the pacing at once, but a reading burst on the blocking pool (a
        // re-simulated tick of a large scene takes a good part of a second) runs to
        // its end; the slot is the limit on that work too.
        let mut slot = self.registry.replays.take()?;
        let registry = self.registry.clone();
        let opened = {
            let name = name.clone();
            blocking(move || open_for_replay(&registry, &dir, &name, &caller, offset)).await?
        };
        if playback == Playback::Resimulate {
            // Re-simulating builds the recorded scene: a large one counts as several.
            let tets = tetrahedra(&opened.scene);
            let more = replay_weight(tets) - 1;
            self.registry.replays.take_more(&mut slot, more, tets)?;
        }
        let slot = Arc::new(slot);
        let (tx, rx) = mpsc::channel(OUTBOUND);
        let scene = v1::ObserveMessage {
            kind: Some(v1::observe_message::Kind::Scene(opened.scene)),
        };
        let _ = tx.try_send(Ok(scene));
        let (feed_tx, feed_rx) = mpsc::channel(READ_AHEAD);
        let recording = Arc::new(opened.recording);
        let reading = slot.clone();
        let scene_dir = self.registry.catalog.dir.clone();
        let held_s = opened.held_s;
        match playback {
            Playback::Recorded => tokio::spawn(async move {
                let reader = ReadRecorded::new(recording, name.clone(), offset);
                feed(StillRecording::new(reader, name, held_s), feed_tx).await;
                drop(reading);
            }),
            Playback::Resimulate => tokio::spawn(async move {
                let reader = ReadResimulated::new(recording, name.clone(), offset, scene_dir);
                feed(StillRecording::new(reader, name, held_s), feed_tx).await;
                drop(reading);
            }),
        };
        let shutdown = self.registry.shutting_down();
        let stall = self.timeout.duration();
        tokio::spawn(async move {
            pace(feed_rx, tx, speed, shutdown, stall).await;
            drop(slot);
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}

#[cfg(test)]
mod tests {
    use tonic::Code;

    use super::*;

    #[test]
    fn only_bare_recording_names_speeds_in_range_and_offsets_from_zero_pass() {
        for ok in ["s1-default-1764000000.mcap", "a b.mcap", "..x.mcap"] {
            assert_eq!(file_name(ok).unwrap(), ok);
        }
        for bad in [
            "",
            ".",
            "..",
            "../a.mcap",
            "/abs.mcap",
            "a/b.mcap",
            "a\\b.mcap",
            "./a.mcap",
            ".mcap",
            "notes.txt",
            "a.mcap\0",
        ] {
            assert_eq!(
                file_name(bad).unwrap_err().code(),
                Code::InvalidArgument,
                "{bad:?}"
            );
        }
        assert_eq!(speed(None).unwrap(), 1.0);
        for ok in [MIN_SPEED, 0.5, 20.0, MAX_SPEED] {
            assert_eq!(speed(Some(ok)).unwrap(), ok);
        }
        for bad in [
            0.0,
            -1.0,
            MIN_SPEED / 2.0,
            MAX_SPEED * 1.01,
            f64::NAN,
            f64::INFINITY,
        ] {
            assert_eq!(speed(Some(bad)).unwrap_err().code(), Code::InvalidArgument);
        }
        // A number far out of range is echoed short, not in its 301 digits.
        let status = speed(Some(1e300)).unwrap_err();
        assert!(status.message().ends_with("(got 1e300)"), "{status:?}");
        assert_eq!(start_offset(None).unwrap(), 0.0);
        assert_eq!(start_offset(Some(2.5)).unwrap(), 2.5);
        for bad in [-1e-9, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(start_offset(Some(bad)).is_err());
        }
        let status = start_offset(Some(-1e300)).unwrap_err();
        assert!(status.message().ends_with("(got -1e300)"), "{status:?}");
        assert_eq!(
            Playback::from_request(v1::ReplayMode::Unspecified as i32).unwrap(),
            Playback::Recorded
        );
        assert_eq!(
            Playback::from_request(v1::ReplayMode::Resimulate as i32).unwrap(),
            Playback::Resimulate
        );
        assert!(Playback::from_request(7).is_err());
    }
}
