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
