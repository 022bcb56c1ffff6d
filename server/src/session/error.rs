//! Why a session does not start.

use crate::engine::scene::SceneError;

/// A session that could not start: its scene does not build, or a thread of its
/// own could not be started (the machine is out of threads or memory).
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("cannot start the {thread} thread: {source}")]
    Spawn {
        /// The thread's name: `mechanics` or `recorder`.
        thread: &'static str,
        source: std::io::Error,
    },
}
