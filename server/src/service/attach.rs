//! Stations for clients without bidirectional streams: `Station.Attach` opens a
//! station exactly as `Station.Join`'s `open` does and streams what Join streams,
//! after a first message carrying the station's handle; `Station.SendPoses` hands
//! poses to that station's receive loop, the same loop Join's messages go through
//! (checks, pose-rate limit, `StationError`s, abuse limit). gRPC-web, the browser
//! console's protocol, has only unary and server-streaming calls.
//!
//! The handle is 128 bits from the operating system's random source: it cannot be
//! guessed, and it is only honoured for the caller (the token's identity) that
//! attached. A wrong caller and an unknown handle get the same `NOT_FOUND`, so
//! that a handle's existence is not told to anyone else.

use std::collections::HashMap;
use std::pin::Pin;
use std::sync::Mutex;

use laparo_proto::v1;
use tokio::sync::mpsc;
use tokio_stream::{Stream, StreamExt};
use tonic::Status;

use super::auth::Caller;
use super::liveness::Outbound;

/// Poses one `SendPoses` call may carry: a browser sends a few per animation
/// frame; 64 is a quarter second at the default 250 Hz pose rate.
pub const MAX_POSES_PER_CALL: usize = 64;
/// Messages waiting for a station's receive loop; beyond, `SendPoses` is
/// `RESOURCE_EXHAUSTED` (the loop reads far faster than a station may send).
pub const QUEUE: usize = 256;
/// Stations attached at once, on the whole server: the table of handles is
/// bounded whatever the callers do.
pub const MAX_ATTACHED: usize = 4096;

/// The stream Attach answers with.
pub type AttachStream = Pin<Box<dyn Stream<Item = Result<v1::AttachMessage, Status>> + Send>>;

/// The stations opened by Attach, by handle, at most `limit` of them
/// ([`MAX_ATTACHED`] unless the server is configured otherwise).
pub struct Attachments {
    by_handle: Mutex<HashMap<String, Attachment>>,
    limit: usize,
}

impl Default for Attachments {
    fn default() -> Self {
        Attachments::with_limit(MAX_ATTACHED)
    }
}

struct Attachment {
    caller: Caller,
    queue: mpsc::Sender<v1::StationMessage>,
}

impl Attachments {
    /// No station attached yet; at most `limit` at once.
    pub fn with_limit(limit: usize) -> Self {
        Attachments {
            by_handle: Mutex::default(),
            limit,
        }
    }

    /// A new handle for `caller`'s station and the queue its messages arrive on.
    pub fn attach(
        &self,
        caller: Caller,
    ) -> Result<(String, mpsc::Receiver<v1::StationMessage>), Status> {
        let handle = new_handle()?;
        let (queue, rx) = mpsc::channel(QUEUE);
        let mut map = self.lock();
        if map.len() >= self.limit {
            return Err(Status::resource_exhausted(format!(
                "{} stations are attached already (server limit MAX_ATTACHED)",
                self.limit
            )));
        }
        map.insert(handle.clone(), Attachment { caller, queue });
        Ok((handle, rx))
    }

    /// Forgets a handle: its station has ended.
    pub fn detach(&self, handle: &str) {
        self.lock().remove(handle);
    }

    /// Queues a request's poses (and its leave) for the station it names; the
    /// number of poses queued.
    pub fn send(&self, caller: &Caller, request: v1::SendPosesRequest) -> Result<u32, Status> {
        super::limits::check_name("handle", &request.handle)?;
        if request.poses.len() > MAX_POSES_PER_CALL {
            return Err(Status::invalid_argument(format!(
                "{} poses in one call, over the limit of {MAX_POSES_PER_CALL} (MAX_POSES_PER_CALL)",
                request.poses.len()
            )));
        }
        let queue = {
            let map = self.lock();
            match map.get(&request.handle) {
                Some(a) if a.caller == *caller => a.queue.clone(),
                _ => {
                    return Err(Status::not_found(
                        "no attached station of this caller has this handle",
                    ));
                }
            }
        };
        let mut queued = 0u32;
        // A call with nothing in it is the station's heartbeat: a page whose
        // instruments do not move (a hidden tab draws no frames, so samples no
        // poses) stays a station while it calls.
        let heartbeat = (request.poses.is_empty() && !request.leave)
            .then(|| v1::station_message::Kind::Heartbeat(v1::Heartbeat::default()));
        let leave = request
            .leave
            .then(|| v1::station_message::Kind::Leave(v1::Leave::default()));
        let messages = request
            .poses
            .into_iter()
            .map(v1::station_message::Kind::Pose)
            .chain(leave)
            .chain(heartbeat);
        for kind in messages {
            let is_pose = matches!(kind, v1::station_message::Kind::Pose(_));
            match queue.try_send(v1::StationMessage { kind: Some(kind) }) {
                Ok(()) => queued += u32::from(is_pose),
                Err(mpsc::error::TrySendError::Full(_)) => {
                    return Err(Status::resource_exhausted(format!(
                        "the station's queue ({QUEUE} messages) is full after {queued} poses of this call"
                    )));
                }
                Err(mpsc::error::TrySendError::Closed(_)) => {
                    return Err(Status::not_found("the station has ended"));
                }
            }
        }
        Ok(queued)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Attachment>> {
        // The map is left consistent by every holder; a panic elsewhere does not
        // make it unusable.
        self.by_handle.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// 128 random bits as 32 lowercase hex digits.
fn new_handle() -> Result<String, Status> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| Status::internal(format!("no random source for a handle: {e}")))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The Attach stream: the handle first, then the station's messages.
pub fn stream(handle: String, outbound: Outbound<v1::ServerMessage>) -> AttachStream {
    let first = v1::AttachMessage {
        kind: Some(v1::attach_message::Kind::Attached(v1::Attached { handle })),
    };
    let rest = outbound.map(|m| {
        m.map(|m| v1::AttachMessage {
            kind: Some(v1::attach_message::Kind::Message(m)),
        })
    });
    Box::pin(tokio_stream::once(Ok(first)).chain(rest))
}

#[cfg(test)]
mod tests;
