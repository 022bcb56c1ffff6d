//! The recorders of this server's sessions: which files they still write, and which
//! they failed to finish while their session ran.
//!
//! A file without its summary and footer is one of three things to a listing: being
//! written (in progress), left by a server that stopped mid-session (unfinished), or
//! left by a recorder of this server that failed — the disk full, the file too large,
//! a write refused — while its session went on unrecorded. Told by the file alone the
//! last two look the same, and a listing called a file "its server stopped" while
//! that server was answering it. The table keeps a [`RecorderWatch`] for every
//! recorder until its thread ends; one that ended with an error is remembered by
//! path with that error.
//!
//! Bounds: one watch a session still recording (the sessions' own bound), and at
//! most [`MAX_REMEMBERED_FAILURES`] failures, the oldest forgotten first (a file
//! whose failure was forgotten reads as unfinished, which `laparo recordings
//! recover` completes the same way).

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::recording::RecorderWatch;
use crate::recording::list::MAX_LISTED_FILES;

/// Most failed recordings remembered: as many as a listing answers, so a listing of
/// a directory that holds nothing but failed files names every failure. Each entry
/// is a path and a sentence (a few hundred bytes; paths are at most 4 KiB).
pub const MAX_REMEMBERED_FAILURES: usize = MAX_LISTED_FILES;

/// The recorders of the server's sessions (see the module notes).
#[derive(Debug, Default)]
pub struct Recorders {
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    /// Recorders whose threads had not ended when last looked at.
    watching: Vec<RecorderWatch>,
    /// Files a recorder failed to finish, with why; a listing asks for each file
    /// without its summary, up to 2,048 a listing.
    failed: HashMap<PathBuf, String>,
    /// The keys of `failed`, oldest first, for forgetting.
    order: VecDeque<PathBuf>,
}

impl Recorders {
    /// Starts watching a session's recorder.
    pub fn add(&self, watch: RecorderWatch) {
        let mut inner = self.lock();
        inner.sweep();
        inner.watching.push(watch);
    }

    /// Whether a recorder of this server still writes the file at `path`, which then
    /// has no summary and footer yet.
    pub fn is_recording(&self, path: &Path) -> bool {
        let mut inner = self.lock();
        inner.sweep();
        inner.watching.iter().any(|w| w.path() == path)
    }

    /// Why a recorder of this server failed to finish the file at `path`, if one did.
    pub fn failure(&self, path: &Path) -> Option<String> {
        let mut inner = self.lock();
        inner.sweep();
        inner.failed.get(path).cloned()
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Inner {
    /// Forgets the recorders whose threads ended, remembering those that failed.
    fn sweep(&mut self) {
        let (failed, order) = (&mut self.failed, &mut self.order);
        self.watching.retain(|w| {
            if w.is_writing() {
                return true;
            }
            if let Some(why) = w.error() {
                let path = w.path().to_path_buf();
                if failed.insert(path.clone(), why).is_none() {
                    order.push_back(path);
                }
                if order.len() > MAX_REMEMBERED_FAILURES
                    && let Some(oldest) = order.pop_front()
                {
                    failed.remove(&oldest);
                }
            }
            false
        });
    }
}

#[cfg(test)]
mod tests {
    use std::time::SystemTime;

    use super::*;
    use crate::engine::scene::Scene;
    use crate::frame::description::description;
    use crate::recording::{Recorder, SessionHeader};

    fn header() -> SessionHeader {
        let scene = Scene::default_scene();
        let sim = scene.build().unwrap();
        SessionHeader {
            session_id: "s1".into(),
            scene_name: scene.name.clone(),
            scene_dir: None,
            scene_toml: scene.text.clone(),
            start: SystemTime::now(),
            description: description(&scene, &sim),
        }
    }

    /// A recorder whose file cannot be created, ended: it fails at once.
    fn failed(path: PathBuf, header: &SessionHeader) -> RecorderWatch {
        let recorder = Recorder::start(path, header.clone()).unwrap();
        assert!(recorder.finish().is_err());
        recorder.watch()
    }

    #[test]
    fn a_failed_recorder_is_remembered_with_why_and_a_finished_one_forgotten() {
        let dir = tempfile::tempdir().unwrap();
        let header = header();
        let table = Recorders::default();

        let ok = Recorder::start(dir.path().join("ok.mcap"), header.clone()).unwrap();
        table.add(ok.watch());
        assert!(table.is_recording(&dir.path().join("ok.mcap")));
        ok.finish().unwrap();
        assert!(!table.is_recording(&dir.path().join("ok.mcap")));
        assert_eq!(table.failure(&dir.path().join("ok.mcap")), None);

        let lost = dir.path().join("no-such-dir").join("lost.mcap");
        table.add(failed(lost.clone(), &header));
        assert!(!table.is_recording(&lost));
        let why = table.failure(&lost).expect("its failure is remembered");
        assert!(
            why.contains("lost.mcap") && !why.contains("no-such-dir"),
            "{why}"
        );
    }

    #[test]
    fn failures_past_the_bound_forget_the_oldest() {
        let header = header();
        let table = Recorders::default();
        let path = |k: usize| PathBuf::from(format!("/nonexistent-laparo-dir/{k}.mcap"));
        for k in 0..=MAX_REMEMBERED_FAILURES {
            table.add(failed(path(k), &header));
        }
        // The last one is swept in by the next question.
        assert!(table.failure(&path(MAX_REMEMBERED_FAILURES)).is_some());
        assert_eq!(table.failure(&path(0)), None, "the oldest is forgotten");
        assert!(table.failure(&path(1)).is_some());
        let inner = table.lock();
        assert_eq!(inner.failed.len(), MAX_REMEMBERED_FAILURES);
        assert_eq!(inner.order.len(), MAX_REMEMBERED_FAILURES);
    }
}
