//! The gRPC status of a recording that cannot be read: shared by the `Recordings`
//! service, which opens a recording, and the replay feeds, which read it on.

use laparo_proto::text::printable;
use tonic::Status;

use crate::recording::ReadError;

/// The status a recording that cannot be read gets. The error names the file
/// relative to the directory; what it quotes of the file (a version, a topic) is
/// escaped ([`printable`]).
pub fn read_status(name: &str, e: &ReadError) -> Status {
    let text = || printable(&e.to_string()).into_owned();
    match e {
        ReadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            Status::not_found(format!("no recording `{}`", printable(name)))
        }
        ReadError::Corrupt { .. } | ReadError::Decode { .. } => Status::data_loss(text()),
        ReadError::Io { .. }
        | ReadError::NotMcap { .. }
        | ReadError::Truncated { .. }
        | ReadError::NotARecording { .. }
        | ReadError::CutBeforeDescription { .. }
        | ReadError::NameNotText { .. }
        | ReadError::UnsupportedVersion { .. } => Status::failed_precondition(text()),
    }
}
