//! Sessions started whole, mechanics thread and recorder included.

use std::time::Duration;

use laparo_proto::force::wire::to_pose;
use laparo_proto::v1;
use nalgebra::{Point3, Unit, Vector3};

use super::*;
use crate::engine::contact::pose::InstrumentPose;
use crate::recording::Recording;
use crate::recording::list::{self, FileState};

mod halt;
mod recording;
mod slow;

fn temp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Waits until the session has ticked `n` times.
fn wait_ticks(session: &Session, n: u64) {
    while session
        .stats
        .tick
        .load(std::sync::atomic::Ordering::Relaxed)
        < n
    {
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The device pose of tick `k` of the session's left instrument pushing straight
/// down into the top of the liver, 1 mm a tick from 1 cm above it, as a station
/// would send it.
fn device_pose(session: &Session, k: u64) -> v1::DevicePose {
    let sim = session.scene.build().unwrap();
    let (lo, hi) = sim.mesh.bounding_box();
    let top = Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z + 0.01);
    let tip = top - Vector3::z() * (1e-3 * k as f64);
    let p = InstrumentPose::new(tip, Unit::new_normalize(sim.instruments[0].trocar - tip));
    v1::DevicePose {
        instrument: sim.instruments[0].name.clone(),
        pose: Some(to_pose(&p.tip, &p.axis)),
        device_time_s: k as f64 * 1e-3,
        sequence: k + 1,
    }
}
