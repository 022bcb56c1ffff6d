//! A station pressing the default liver, and what to read off its stream.

use std::time::Duration;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;

use crate::server::{StationStream, pose};

/// The front point of the rest surface (the default liver's free +z face), m.
pub fn front(joined: &v1::Joined) -> [f64; 3] {
    let f = laparo_client::gestures::front(joined.scene.as_ref().unwrap());
    [f.x, f.y, f.z]
}

/// Streams poses of `instrument` pressing along −z at `x_offset` beside the front
/// point: from 1.5 cm out to 8 mm in over 0.5 s, then held, 100 poses a second.
pub fn press(station: &StationStream, instrument: &'static str, front: [f64; 3], x_offset: f64) {
    let tx = station.tx.clone();
    tokio::spawn(async move {
        for k in 1..=400u64 {
            let s = (k as f64 / 50.0).min(1.0);
            let z = front[2] + 0.015 - 0.023 * s;
            let tip = [front[0] + x_offset, front[1], z];
            if tx
                .send(pose(instrument, tip, [0.0, 0.0, 1.0], k))
                .await
                .is_err()
            {
                return;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    });
}

pub fn state_of<'a>(m: &'a v1::ServerMessage, instrument: &str) -> Option<&'a v1::InstrumentState> {
    match &m.kind {
        Some(Kind::InstrumentState(s)) if s.instrument == instrument => Some(s),
        _ => None,
    }
}

/// Floods `station` with up to 10⁶ poses of `instrument` at `tip` (sequence numbers
/// from `first_sequence`, each send bounded by `send_wait`) until the server closes
/// the stream, and returns how many `RATE_LIMITED` errors it answered and the code
/// the stream closed with (`Ok` for a clean end). Panics if the stream is still open
/// after `close_wait`.
pub async fn flood_until_closed(
    station: &mut StationStream,
    instrument: &'static str,
    tip: [f64; 3],
    first_sequence: u64,
    send_wait: Duration,
    close_wait: Duration,
) -> (u64, tonic::Code) {
    let tx = station.tx.clone();
    let sender = tokio::spawn(async move {
        for k in 0..1_000_000u64 {
            let message = pose(instrument, tip, [0.0, 0.0, 1.0], first_sequence + k);
            match tokio::time::timeout(send_wait, tx.send(message)).await {
                Ok(Ok(())) => {}
                _ => return,
            }
        }
    });
    let closed = tokio::time::timeout(close_wait, async {
        let mut limited = 0u64;
        loop {
            match station.rx.message().await {
                Ok(Some(v1::ServerMessage {
                    kind: Some(Kind::Error(e)),
                })) if e.code == v1::ErrorCode::RateLimited as i32 => limited += 1,
                Ok(Some(_)) => {}
                Ok(None) => return (limited, tonic::Code::Ok),
                Err(status) => return (limited, status.code()),
            }
        }
    })
    .await;
    sender.abort();
    closed.expect("the stream was never closed")
}
