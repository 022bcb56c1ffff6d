//! The `Station.Join` stream of one station: joining (the open message, then
//! `Joined`), the server's messages one by one, and leaving.

use std::time::Instant;

use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::Streaming;

use super::{LEAVE_GRACE, OUTGOING_QUEUE, StationError};
use crate::connect::Connection;
use crate::proto::v1::{
    JoinRequest, Joined, Leave, ServerMessage, StationMessage, server_message, station_message,
};

/// An open `Join` stream after `Joined`: the queue of station messages (at most
/// [`OUTGOING_QUEUE`] waiting) and the server's stream.
pub(crate) struct Link {
    /// Station messages to the server.
    pub outgoing: mpsc::Sender<StationMessage>,
    incoming: Streaming<ServerMessage>,
    /// What the server answered the join with.
    pub joined: Joined,
    /// When the server's last message came.
    heard: Instant,
}

impl Link {
    /// Opens a `Join` stream with `open` and waits for `Joined`; any other first
    /// message, or none, is a protocol error, and so is a `Joined` that does not
    /// grant every instrument claimed ([`check_granted`]). A refused join (an
    /// instrument unknown, taken or not the caller's, or no instrument on a trainee
    /// token) is the server's status, as [`StationError::Status`].
    pub async fn join(connection: &Connection, open: JoinRequest) -> Result<Link, StationError> {
        let claimed = open.instruments.clone();
        let (outgoing, rx) = mpsc::channel(OUTGOING_QUEUE);
        outgoing
            .try_send(StationMessage {
                kind: Some(station_message::Kind::Open(open)),
            })
            .expect("a new channel has room for the first message");
        let mut incoming = connection
            .station()
            .join(ReceiverStream::new(rx))
            .await?
            .into_inner();
        match incoming.message().await? {
            Some(ServerMessage {
                kind: Some(server_message::Kind::Joined(joined)),
            }) => {
                check_granted(&claimed, &joined)?;
                Ok(Link {
                    outgoing,
                    incoming,
                    joined,
                    heard: Instant::now(),
                })
            }
            Some(other) => Err(StationError::Protocol(format!(
                "expected Joined as the first server message, got {:?}",
                other.kind.as_ref().map(kind_name)
            ))),
            None => Err(StationError::Protocol(
                "the server ended the stream before Joined".into(),
            )),
        }
    }

    /// The server's next message; `None` when it ended the stream normally, a gRPC
    /// status it ended the stream with as [`StationError::Status`]. Cancel-safe: a
    /// message is never lost when the future is dropped unfinished.
    pub async fn next(&mut self) -> Result<Option<ServerMessage>, StationError> {
        match self.incoming.message().await {
            Ok(message) => {
                self.heard = Instant::now();
                Ok(message)
            }
            Err(status) => Err(StationError::after_silence(status, self.heard.elapsed())),
        }
    }

    /// Sends `Leave` with `reason` and waits up to [`LEAVE_GRACE`] for the server to
    /// end the stream; whatever it says meanwhile, or a status it ends with, no
    /// longer matters.
    pub async fn leave(self, reason: String) {
        let Link {
            outgoing,
            mut incoming,
            ..
        } = self;
        let _ = outgoing.try_send(StationMessage {
            kind: Some(station_message::Kind::Leave(Leave { reason })),
        });
        drop(outgoing);
        let _ = tokio::time::timeout(LEAVE_GRACE, async {
            while let Ok(Some(_)) = incoming.message().await {}
        })
        .await;
    }
}

/// Checks that `joined` grants exactly the instruments `claimed`, in their order:
/// the contract grants a join whole or refuses it with a status, so anything else
/// is a server breaking the protocol (a station would drive devices for
/// instruments it does not hold).
pub(crate) fn check_granted(claimed: &[String], joined: &Joined) -> Result<(), StationError> {
    if joined.instruments == claimed {
        Ok(())
    } else {
        Err(StationError::Protocol(format!(
            "claimed instruments {claimed:?} but Joined granted {:?}",
            joined.instruments
        )))
    }
}

/// The name of a server message kind, for errors.
pub(crate) fn kind_name(kind: &server_message::Kind) -> &'static str {
    match kind {
        server_message::Kind::Joined(_) => "Joined",
        server_message::Kind::SurfaceFrame(_) => "SurfaceFrame",
        server_message::Kind::InstrumentState(_) => "InstrumentState",
        server_message::Kind::Event(_) => "Event",
        server_message::Kind::Error(_) => "StationError",
    }
}
