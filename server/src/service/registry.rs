//! The scenes a server offers and the sessions it runs.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use laparo_proto::text::printable;
use tokio::sync::watch;
use tonic::Status;

use super::capacity::{
    Capacity, ReplaySlots, session_weight, tetrahedra, too_large_a_session, too_many_sessions,
};
use super::catalog::SceneCatalog;
use super::recorders::Recorders;
use crate::engine::scene::Scene;
use crate::recording::space;
use crate::session::{Closing, Session, SessionConfig, SessionError};

/// A session being started, counted (as its weight, the second field) until it is
/// in the map (or failed).
struct Starting<'a>(&'a AtomicUsize, usize);

impl Drop for Starting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(self.1, Ordering::AcqRel);
    }
}

/// Every session of the server.
pub struct Registry {
    pub catalog: SceneCatalog,
    sessions: Mutex<BTreeMap<String, Arc<Session>>>,
    next: AtomicU64,
    /// Default idle timeout of new sessions.
    pub idle_timeout: Option<Duration>,
    /// Where sessions are recorded; `None`: this server records nothing.
    pub recordings: Option<PathBuf>,
    /// The free space a new recording needs there, bytes
    /// ([`space::MIN_FREE_BYTES`] unless [`with_min_free`](Self::with_min_free)).
    min_free: u64,
    /// The recorders of this server's sessions, until their files are finished, and
    /// the files they failed to finish.
    recorders: Recorders,
    /// Whether the server is shutting down, and why.
    shutdown: Closing,
    /// How often each caller may join a station.
    pub joins: super::join_rate::JoinRate,
    /// Most sessions open at once.
    max_sessions: usize,
    /// Sessions being started, each counted as its [`session_weight`] against
    /// [`Registry::max_sessions`].
    starting: AtomicUsize,
    /// The tetrahedra of each scene, once a session of it was asked for.
    sizes: Mutex<HashMap<String, usize>>,
    /// The replays streaming now, and their limit.
    pub replays: ReplaySlots,
}

impl Registry {
    pub fn new(
        catalog: SceneCatalog,
        idle_timeout: Option<Duration>,
        recordings: Option<PathBuf>,
    ) -> Self {
        Registry {
            catalog,
            sessions: Mutex::new(BTreeMap::new()),
            next: AtomicU64::new(1),
            idle_timeout,
            recordings,
            min_free: space::MIN_FREE_BYTES,
            recorders: Recorders::default(),
            shutdown: Closing::new(),
            joins: Default::default(),
            max_sessions: usize::MAX,
            starting: AtomicUsize::new(0),
            sizes: Mutex::new(HashMap::new()),
            replays: ReplaySlots::new(usize::MAX >> 4),
        }
    }

    /// A new recording needs `bytes` free on the recordings' file system.
    pub fn with_min_free(mut self, bytes: u64) -> Self {
        self.min_free = bytes;
        self
    }

    /// These limits on sessions and replays (by default a registry has none).
    pub fn with_capacity(mut self, capacity: Capacity) -> Self {
        self.max_sessions = capacity.sessions;
        self.replays = ReplaySlots::new(capacity.replays);
        self
    }

    /// Counts a session of scene `name` (`tets` tetrahedra) about to start against
    /// the limit, as [`session_weight`] sessions, or refuses it.
    fn reserve(&self, name: &str, tets: usize) -> Result<Starting<'_>, Status> {
        let weight = session_weight(tets);
        let mut map = self.map();
        map.retain(|_, s| !s.is_closed());
        let open = open_weight(&map) + self.starting.load(Ordering::Acquire);
        if open + weight > self.max_sessions {
            return Err(if weight > 1 {
                too_large_a_session(name, tets, weight, open, self.max_sessions)
            } else {
                too_many_sessions(self.max_sessions)
            });
        }
        self.starting.fetch_add(weight, Ordering::AcqRel);
        Ok(Starting(&self.starting, weight))
    }

    /// The tetrahedra of scene `name` as built, read from its mesh the first time
    /// (the mesh alone, not the model) and remembered: scenes do not change while
    /// the server runs.
    fn tetrahedra_of(&self, name: &str, scene: &Scene) -> Result<usize, Status> {
        let known = self.sizes_map().get(name).copied();
        if let Some(tets) = known {
            return Ok(tets);
        }
        // Not under the lock: a large mesh takes a second or more to read.
        let tets = tokio::task::block_in_place(|| scene.load_mesh())
            .map_err(|e| {
                Status::failed_precondition(format!("scene `{name}` does not build: {e}"))
            })?
            .tets
            .len();
        self.sizes_map().insert(name.to_string(), tets);
        Ok(tets)
    }

    fn sizes_map(&self) -> MutexGuard<'_, HashMap<String, usize>> {
        self.sizes.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Whether a session of this server is still writing the recording at `path`,
    /// which then has no summary and footer yet.
    pub fn is_recording(&self, path: &Path) -> bool {
        self.recorders.is_recording(path)
    }

    /// Why a session's recorder failed to finish the recording at `path`, if one of
    /// this server's did (see `recorders`).
    pub fn recorder_failure(&self, path: &Path) -> Option<String> {
        self.recorders.failure(path)
    }

    /// Resolves to the reason once the server is shutting down.
    pub fn shutting_down(&self) -> watch::Receiver<Option<String>> {
        self.shutdown.watch()
    }

    fn map(&self) -> MutexGuard<'_, BTreeMap<String, Arc<Session>>> {
        self.sessions.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Starts a session of scene `name`, recorded if `record` says so (absent: as
    /// the scene declares) and the server records.
    pub fn create(
        &self,
        name: &str,
        idle_timeout: Option<Duration>,
        record: Option<bool>,
    ) -> Result<Arc<Session>, Status> {
        let scene = self
            .catalog
            .scenes
            .get(name)
            .ok_or_else(|| Status::not_found(format!("no scene `{}`", printable(name))))?
            .clone();
        let tets = self.tetrahedra_of(name, &scene)?;
        let reserved = self.reserve(name, tets)?;
        let id = format!("s{}", self.next.fetch_add(1, Ordering::Relaxed));
        let record = record.unwrap_or(scene.recording.enabled);
        let config = SessionConfig {
            idle_timeout,
            recordings: self.recordings.clone().filter(|_| record),
        };
        if let Some(dir) = &config.recordings {
            self.room_for_recording(dir, name)?;
        }
        // Building a scene reads its mesh and assembles the model: not on the
        // async runtime's threads.
        let session = tokio::task::block_in_place(|| Session::start(id.clone(), scene, &config))
            .map_err(|e| match e {
                SessionError::Scene(e) => {
                    Status::failed_precondition(format!("scene `{name}` does not build: {e}"))
                }
                // Out of threads or memory: the server, not the scene, is at fault,
                // and a later try may succeed.
                SessionError::Spawn { .. } => {
                    Status::unavailable(format!("cannot start a session of scene `{name}`: {e}"))
                }
            })?;
        if let Some(recorder) = session.recorder_watch() {
            self.recorders.add(recorder);
        }
        self.map().insert(id, session.clone());
        drop(reserved);
        tracing::info!(session = %session.id, scene = name, "session created");
        Ok(session)
    }

    /// Whether `dir` can take a new recording (see [`space`]): a directory, refused
    /// `FAILED_PRECONDITION` naming `--recordings` if not, whose file system has
    /// room, refused `RESOURCE_EXHAUSTED` naming the limit if not. A file system
    /// that cannot be asked is left to the recorder, which says what fails.
    fn room_for_recording(&self, dir: &Path, scene: &str) -> Result<(), Status> {
        if let Err(what) = space::usable_dir(dir) {
            return Err(Status::failed_precondition(format!(
                "cannot record a session of scene `{}`: the server's recordings \
                 directory (--recordings) {what}; its operator must mend it, or \
                 create the session with record false",
                printable(scene),
            )));
        }
        let Ok(free) = space::free_bytes(dir) else {
            return Ok(());
        };
        if free >= self.min_free {
            return Ok(());
        }
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        Err(Status::resource_exhausted(format!(
            "cannot record a session of scene `{}`: the recordings directory's file \
             system has {:.1} MiB free, under the {:.1} MiB a new recording needs \
             (MIN_FREE_BYTES); free some space, or create the session with record \
             false",
            printable(scene),
            mib(free),
            mib(self.min_free)
        )))
    }

    /// The open session `id`.
    pub fn get(&self, id: &str) -> Result<Arc<Session>, Status> {
        let mut map = self.map();
        match map.get(id) {
            Some(s) if !s.is_closed() => Ok(s.clone()),
            Some(_) => {
                map.remove(id);
                Err(Status::not_found(format!(
                    "session `{}` is closed",
                    printable(id)
                )))
            }
            None => Err(Status::not_found(format!("no session `{}`", printable(id)))),
        }
    }

    /// Open sessions, dropping the closed ones.
    pub fn list(&self) -> Vec<Arc<Session>> {
        let mut map = self.map();
        map.retain(|_, s| !s.is_closed());
        map.values().cloned().collect()
    }

    /// Closes and forgets session `id`, once its mechanics thread has stopped and its
    /// recording is finished (a tick at most, and the recording's footer).
    pub fn close(&self, id: &str, reason: &str) -> Result<Arc<Session>, Status> {
        let session = self
            .map()
            .remove(id)
            .ok_or_else(|| Status::not_found(format!("no session `{}`", printable(id))))?;
        session.close(reason);
        tokio::task::block_in_place(|| session.join());
        Ok(session)
    }

    /// Closes every session (shutdown) and waits for their mechanics threads;
    /// streams not tied to a session (replays) end too.
    pub fn close_all(&self, reason: &str) {
        self.shutdown.close(reason);
        let all: Vec<_> = std::mem::take(&mut *self.map()).into_values().collect();
        for s in &all {
            s.close(reason);
        }
        // One deadline for all: shutdown waits at most MECHANICS_JOIN_TIMEOUT in all.
        let deadline = std::time::Instant::now() + crate::session::MECHANICS_JOIN_TIMEOUT;
        for s in &all {
            s.join_until(deadline);
        }
    }
}

/// The open sessions, each counted as its scene's [`session_weight`].
fn open_weight(map: &BTreeMap<String, Arc<Session>>) -> usize {
    map.values()
        .map(|s| session_weight(tetrahedra(&s.description)))
        .sum()
}
