//! Scene errors.

use crate::engine::mesh::MeshError;

/// Why a scene could not be read or built. Each variant names the scene and where in
/// it the fault is.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file itself: `message` says what is wrong in words that follow the
    /// file's name ("cannot read: …", "is a directory, not a regular file").
    #[error("{scene}: {message}")]
    Io { scene: String, message: String },
    /// TOML syntax, an unknown key, or a value of the wrong type.
    /// `path` is empty when the fault is not under a key (a key written twice, a
    /// field missing at the top level): then it is not printed.
    #[error(
        "{scene}:{line}: {at}{message}",
        line = line.map_or(String::from("?"), |l| l.to_string()),
        at = if path.is_empty() { String::new() } else { format!("`{path}`: ") }
    )]
    Parse {
        scene: String,
        path: String,
        line: Option<usize>,
        message: String,
    },
    /// A value out of its range, or inconsistent with the rest of the scene.
    #[error("{scene}: `{path}`: {message}")]
    Invalid {
        scene: String,
        path: String,
        message: String,
    },
    #[error("{scene}: mesh: {source}")]
    Mesh {
        scene: String,
        #[source]
        source: MeshError,
    },
}
