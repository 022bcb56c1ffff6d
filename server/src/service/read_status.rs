//! The gRPC status of a recording that cannot be read: shared by the `Recordings`
//! service, which opens a recording, and the replay feeds, which read it on.

use tonic::Status;

use crate::recording::ReadError;

/// The status a recording that cannot be read gets (the error names the file).
pub fn read_status(name: &str, e: &ReadError) -> Status {
    match e {
        ReadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            Status::not_found(format!("no recording `{name}`"))
        }
        ReadError::Corrupt { .. } | ReadError::Decode { .. } => Status::data_loss(e.to_string()),
        ReadError::Io { .. }
        | ReadError::NotMcap { .. }
        | ReadError::Truncated { .. }
        | ReadError::NotARecording { .. }
        | ReadError::UnsupportedVersion { .. } => Status::failed_precondition(e.to_string()),
    }
}
