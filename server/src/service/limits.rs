//! Length limits on every string a client sends, checked at the edge before the
//! string reaches a session, an event, a log line or a recording.
//!
//! Without them one client can make every event it causes (a join, a leave, a
//! close) as large as a gRPC body allows, and each event is copied to every
//! observer and into the recording. The limits are in bytes of UTF-8 and stated in
//! the `.proto` comments of each field.

use tonic::Status;

/// Names and ids: `client_name`, `session_id`, instrument and scene names,
/// recording file names. 256 bytes hold any name a person or a generator gives; a
/// scene's name and its instruments' are held to the same when it loads.
pub const MAX_NAME_BYTES: usize = crate::engine::scene::limits::MAX_NAME_BYTES;

/// Free text a person writes: the `reason` of `CloseSession` and of a `Leave`.
pub const MAX_REASON_BYTES: usize = 1024;

/// Instruments a single join may name: more than a scene ever has.
pub const MAX_INSTRUMENTS: usize = 64;

/// Stations (joined or attached, watching or holding instruments) in one session at
/// once. Each is sent every frame and every event, and each join is an event to
/// all the others: with no bound, 4,000 watching stations made the session's
/// `SessionInfo` larger than a client reads (5 MB) and its events grow with the
/// square of the count. A lab's session has a few stations and an instructor.
pub const MAX_STATIONS_PER_SESSION: usize = 64;

/// Observers (`Observe` streams) of one session at once: each is sent every
/// frame; a class watching one session is far fewer. With no bound, one
/// connection opened 2,000 observers that never read (0.2–1 MB each, the
/// session's ticks slowing for the copying).
pub const MAX_OBSERVERS_PER_SESSION: u32 = 64;

/// Streams one HTTP/2 connection may have open at once (its
/// `SETTINGS_MAX_CONCURRENT_STREAMS`): a station opens one or two, a command-line
/// tool one, a console page speaks HTTP/1.1. With no bound one connection opened
/// 6,000 streams. A stream the server has ended because its client stopped
/// reading keeps what HTTP/2 had buffered for it (about 200–350 kB, measured)
/// until the client reads or the connection closes, since a status cannot pass
/// the data queued before it; 32 streams bound that to about 11 MB a connection.
pub const MAX_STREAMS_PER_CONNECTION: u32 = 32;

/// `INVALID_ARGUMENT` naming `field` and `limit` when `value` is longer than `limit` bytes.
pub fn check_len(field: &str, value: &str, limit: usize) -> Result<(), Status> {
    if value.len() > limit {
        return Err(Status::invalid_argument(format!(
            "{field} is {} bytes, over the limit of {limit} bytes",
            value.len()
        )));
    }
    Ok(())
}

/// [`check_len`] with [`MAX_NAME_BYTES`].
pub fn check_name(field: &str, value: &str) -> Result<(), Status> {
    check_len(field, value, MAX_NAME_BYTES)
}

/// [`check_len`] with [`MAX_REASON_BYTES`].
pub fn check_reason(field: &str, value: &str) -> Result<(), Status> {
    check_len(field, value, MAX_REASON_BYTES)
}

/// Every name in `values` within [`MAX_NAME_BYTES`], and at most [`MAX_INSTRUMENTS`] of them.
pub fn check_names(field: &str, values: &[String]) -> Result<(), Status> {
    if values.len() > MAX_INSTRUMENTS {
        return Err(Status::invalid_argument(format!(
            "{field} has {} entries, over the limit of {MAX_INSTRUMENTS}",
            values.len()
        )));
    }
    values.iter().try_for_each(|v| check_name(field, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_at_the_limit_passes_and_one_byte_more_is_refused_naming_the_field() {
        assert!(check_name("client_name", &"a".repeat(MAX_NAME_BYTES)).is_ok());
        let e = check_name("client_name", &"a".repeat(MAX_NAME_BYTES + 1)).unwrap_err();
        assert_eq!(e.code(), tonic::Code::InvalidArgument);
        assert!(e.message().contains("client_name"));
        assert!(e.message().contains("256"));
    }

    #[test]
    fn the_limit_counts_bytes_not_characters() {
        // 'é' is two bytes of UTF-8.
        assert!(check_name("scene", &"é".repeat(MAX_NAME_BYTES / 2)).is_ok());
        assert!(check_name("scene", &"é".repeat(MAX_NAME_BYTES / 2 + 1)).is_err());
    }

    #[test]
    fn too_many_instruments_are_refused() {
        let many = vec!["grasper".to_string(); MAX_INSTRUMENTS + 1];
        let e = check_names("instruments", &many).unwrap_err();
        assert!(e.message().contains("instruments"));
        assert!(check_names("instruments", &many[..MAX_INSTRUMENTS]).is_ok());
    }
}
