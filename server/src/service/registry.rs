//! The scenes a server offers and the sessions it runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::time::Duration;

use laparo_proto::v1;
use tokio::sync::watch;
use tonic::Status;

use crate::engine::scene::Scene;
use crate::recording::Recorder;
use crate::session::{Session, SessionConfig};

/// The embedded default scene and the `.toml` files of a directory, by name.
#[derive(Debug, Default)]
pub struct SceneCatalog {
    pub scenes: BTreeMap<String, Scene>,
    /// Files of the directory that are not offered, and why: they do not read or
    /// parse (regular files of at most `MAX_SCENE_BYTES`, inside the directory), or
    /// repeat a name already offered. `ListScenes` reports them beside the scenes.
    pub unavailable: Vec<v1::SceneProblem>,
}

impl SceneCatalog {
    /// The default scene, and every `*.toml` in `dir`, in file-name order. A file that
    /// does not load is left out, logged and kept in [`unavailable`](Self::unavailable),
    /// so that one broken file neither hides the others nor stops the server; a name
    /// already offered (by the default scene or an earlier file) keeps the first, with
    /// a warning naming both files. Only an unreadable directory is an error.
    pub fn load(dir: Option<&Path>) -> Result<Self, String> {
        let mut catalog = SceneCatalog::default();
        let default = Scene::default_scene();
        catalog.scenes.insert(default.name.clone(), default);
        let Some(dir) = dir else {
            return Ok(catalog);
        };
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        for f in files {
            let file = f
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            let problem = match Scene::load_served(&f, dir) {
                Ok(scene) => match catalog.scenes.get(&scene.name) {
                    None => {
                        catalog.scenes.insert(scene.name.clone(), scene);
                        continue;
                    }
                    Some(first) => v1::SceneProblem {
                        error: format!(
                            "a scene named `{}` is already offered by {}; keeping that one",
                            scene.name, first.source
                        ),
                        name: scene.name,
                        file,
                    },
                },
                Err(e) => v1::SceneProblem {
                    name: String::new(),
                    file,
                    error: e.to_string(),
                },
            };
            tracing::warn!(file = %f.display(), "scene not offered: {}", problem.error);
            catalog.unavailable.push(problem);
        }
        Ok(catalog)
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
    /// The recorders of this server's sessions, until their files are finished.
    recorders: Mutex<Vec<Weak<Recorder>>>,
    /// `Some(reason)` once the server is shutting down.
    shutdown: watch::Sender<Option<String>>,
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
            recorders: Mutex::new(Vec::new()),
            shutdown: watch::channel(None).0,
        }
    }

    /// The recorders still writing, forgetting the others.
    fn writing(&self) -> Vec<Arc<Recorder>> {
        let mut recorders = self.recorders.lock().unwrap_or_else(|e| e.into_inner());
        let mut writing = Vec::new();
        recorders.retain(|w| match w.upgrade() {
            Some(r) if r.is_writing() => {
                writing.push(r);
                true
            }
            // Dropped or ended: its file is finished (or failed for good).
            _ => false,
        });
        writing
    }

    /// Whether a session of this server is still writing the recording at `path`,
    /// which then has no summary and footer yet.
    pub fn is_recording(&self, path: &Path) -> bool {
        self.writing().iter().any(|r| r.path() == path)
    }

    /// Resolves to the reason once the server is shutting down.
    pub fn shutting_down(&self) -> watch::Receiver<Option<String>> {
        self.shutdown.subscribe()
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
            .ok_or_else(|| Status::not_found(format!("no scene `{name}`")))?
            .clone();
        let id = format!("s{}", self.next.fetch_add(1, Ordering::Relaxed));
        let record = record.unwrap_or(scene.recording.enabled);
        let config = SessionConfig {
            idle_timeout,
            recordings: self.recordings.clone().filter(|_| record),
        };
        // Building a scene reads its mesh and assembles the model: not on the
        // async runtime's threads.
        let session = tokio::task::block_in_place(|| Session::start(id.clone(), scene, &config))
            .map_err(|e| {
                Status::failed_precondition(format!("scene `{name}` does not build: {e}"))
            })?;
        if let Some(recorder) = session.recorder_weak() {
            let mut recorders = self.recorders.lock().unwrap_or_else(|e| e.into_inner());
            recorders.retain(|w| w.upgrade().is_some_and(|r| r.is_writing()));
            recorders.push(recorder);
        }
        self.map().insert(id, session.clone());
        tracing::info!(session = %session.id, scene = name, "session created");
        Ok(session)
    }

    /// The open session `id`.
    pub fn get(&self, id: &str) -> Result<Arc<Session>, Status> {
        let mut map = self.map();
        match map.get(id) {
            Some(s) if !s.is_closed() => Ok(s.clone()),
            Some(_) => {
                map.remove(id);
                Err(Status::not_found(format!("session `{id}` is closed")))
            }
            None => Err(Status::not_found(format!("no session `{id}`"))),
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
            .ok_or_else(|| Status::not_found(format!("no session `{id}`")))?;
        session.close(reason);
        tokio::task::block_in_place(|| session.join());
        Ok(session)
    }

    /// Closes every session (shutdown) and waits for their mechanics threads;
    /// streams not tied to a session (replays) end too.
    pub fn close_all(&self, reason: &str) {
        self.shutdown.send_replace(Some(reason.to_string()));
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
