//! What a station or observer stream sends: the session's frames at the rate the
//! client asked for, its events, and the end of the session.

use std::sync::Arc;

use laparo_proto::text::Number;
use laparo_proto::v1;
use tokio::sync::{broadcast, mpsc, watch};
use tonic::Status;

use crate::session::Session;

/// One outgoing item, before it is wrapped in the stream's message type. Held only
/// on its way into a message, so its size is that message's.
#[allow(clippy::large_enum_variant)]
pub enum Item {
    Surface(v1::SurfaceFrame),
    State(v1::InstrumentState),
    Event(v1::Event),
    Error(v1::StationError),
}

/// A stream's message type.
pub trait Wrap: Send + 'static {
    fn wrap(item: Item) -> Option<Self>
    where
        Self: Sized;
}

impl Wrap for v1::ServerMessage {
    fn wrap(item: Item) -> Option<Self> {
        use v1::server_message::Kind;
        Some(v1::ServerMessage {
            kind: Some(match item {
                Item::Surface(f) => Kind::SurfaceFrame(f),
                Item::State(s) => Kind::InstrumentState(s),
                Item::Event(e) => Kind::Event(e),
                Item::Error(e) => Kind::Error(e),
            }),
        })
    }
}

impl Wrap for v1::ObserveMessage {
    fn wrap(item: Item) -> Option<Self> {
        use v1::observe_message::Kind;
        Some(v1::ObserveMessage {
            kind: Some(match item {
                Item::Surface(f) => Kind::SurfaceFrame(f),
                Item::State(s) => Kind::InstrumentState(s),
                Item::Event(e) => Kind::Event(e),
                // Observers send nothing, so nothing of theirs is rejected.
                Item::Error(_) => return None,
            }),
        })
    }
}

/// Messages a client may fall behind by before frames are skipped for it.
pub const OUTBOUND: usize = 64;

/// The frame rate a client gets: what it asked for, at most the mechanics rate.
pub fn frame_rate(asked: Option<f64>, mechanics_hz: f64) -> Result<f64, Status> {
    match asked {
        None => Ok(mechanics_hz),
        Some(r) if r.is_finite() && r > 0.0 => Ok(r.min(mechanics_hz)),
        Some(r) => Err(Status::invalid_argument(format!(
            "the frame rate must be finite and > 0 Hz (got {})",
            Number(r)
        ))),
    }
}

/// When a stream sends the instruments' states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum States {
    /// With each surface frame, at the stream's frame rate: an observer draws them
    /// with the surface.
    WithSurfaces,
    /// Every tick, whatever the surface frame rate: a station's force loop renders
    /// from the local model a state carries, and needs it at the mechanics rate (a
    /// station at `--frame-rate 1` got one model a second, its force up to a
    /// second old).
    EveryTick,
}

/// Sends the session's frames (at `rate_hz`), events, and its end, until the client
/// goes, `done` fires, or the session closes (then the stream ends with
/// `UNAVAILABLE` and the reason). Frames go with `try_send`: a client that does not
/// keep up skips frames; the mechanics thread never waits for it.
pub async fn pump<M: Wrap>(
    session: Arc<Session>,
    tx: mpsc::Sender<Result<M, Status>>,
    rate_hz: f64,
    states: States,
    mut done: watch::Receiver<bool>,
) {
    let mut frames = session.frames();
    let mut events = session.events();
    let mut closing = session.closing();
    let period = 1.0 / rate_hz;
    let mut next_time = f64::NEG_INFINITY;
    let send = |item: Item| M::wrap(item).map(Ok);
    let closed = closing.borrow_and_update().clone();
    if let Some(reason) = closed {
        let _ = tx
            .send(Err(Status::unavailable(format!(
                "session closed: {reason}"
            ))))
            .await;
        return;
    }
    loop {
        tokio::select! {
            // The session's end first: when it closes, the station's reader stops too
            // and `done` fires at the same moment; the client must still get the
            // status that says why.
            biased;
            _ = closing.changed() => {
                let reason: String = closing.borrow().clone().unwrap_or_default();
                let status = Err(Status::unavailable(format!("session closed: {reason}")));
                let _ = send_unless_done(&tx, status, &mut done).await;
                break;
            }
            changed = frames.changed() => {
                if changed.is_err() {
                    break;
                }
                let frame = frames.borrow_and_update().clone();
                // Half a tick of slack so a rate equal to the mechanics rate skips none.
                let surface_due =
                    frame.sim_time + 0.5 / session.scene.mechanics.rate_hz >= next_time;
                if !surface_due && states == States::WithSurfaces {
                    continue;
                }
                if surface_due {
                    next_time = frame.sim_time.max(next_time + period);
                    let surface = v1::SurfaceFrame {
                        tick: frame.tick,
                        sim_time_s: frame.sim_time,
                        positions: frame.surface.clone(),
                    };
                    let Some(m) = send(Item::Surface(surface)) else { continue };
                    if tx.try_send(m).is_err() {
                        if tx.is_closed() { break; }
                        continue;
                    }
                }
                for state in &frame.instruments {
                    if let Some(m) = send(Item::State(state.clone())) {
                        let _ = tx.try_send(m);
                    }
                }
            }
            event = events.recv() => match event {
                Ok(e) => {
                    if let Some(m) = send(Item::Event(e))
                        && !send_unless_done(&tx, m, &mut done).await
                    {
                        break;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    let error = v1::StationError {
                        code: v1::ErrorCode::Unspecified as i32,
                        message: format!("{n} events skipped: this stream fell behind"),
                        sequence: None,
                        instrument: None,
                    };
                    if let Some(m) = send(Item::Error(error)) {
                        let _ = tx.try_send(m);
                    }
                }
                Err(broadcast::error::RecvError::Closed) => break,
            },
            _ = done.changed() => {
                let closed = closing.borrow().clone();
                if let Some(reason) = closed {
                    let _ = tx.send(Err(Status::unavailable(format!("session closed: {reason}")))).await;
                }
                break;
            }
            _ = tx.closed() => break,
        }
    }
}

/// Sends `message`, waiting for room, unless the stream is done first (a station
/// found gone or evicted: its client may never take another message, and this
/// task must not wait for it for ever). Whether it was sent.
///
/// The send is tried first: when a session closes, its station's reader stops and
/// `done` fires at once, and a queue with room must still take the status that
/// says why (an unbiased choice dropped it now and then).
async fn send_unless_done<M>(
    tx: &mpsc::Sender<Result<M, Status>>,
    message: Result<M, Status>,
    done: &mut watch::Receiver<bool>,
) -> bool {
    tokio::select! {
        biased;
        sent = tx.send(message) => sent.is_ok(),
        _ = done.wait_for(|d| *d) => false,
    }
}

#[cfg(test)]
mod tests {
    use tonic::Code;

    use super::frame_rate;

    #[test]
    fn a_frame_rate_is_at_most_the_mechanics_rate_and_a_bad_one_is_echoed_short() {
        assert_eq!(frame_rate(None, 60.0).unwrap(), 60.0);
        assert_eq!(frame_rate(Some(30.0), 60.0).unwrap(), 30.0);
        assert_eq!(frame_rate(Some(1e300), 60.0).unwrap(), 60.0);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                frame_rate(Some(bad), 60.0).unwrap_err().code(),
                Code::InvalidArgument
            );
        }
        let status = frame_rate(Some(-1e300), 60.0).unwrap_err();
        assert!(status.message().ends_with("(got -1e300)"), "{status:?}");
    }
}
