//! Recordings written and read back: a scripted simulation through the recorder,
//! files cut short and recovered, files that are not recordings, listings and
//! re-simulation. (A recorded live session is tested beside the session.)

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use laparo_proto::force::wire::to_pose;
use laparo_proto::v1;
use nalgebra::{Point3, Unit};
use prost::Message;

use super::writer::McapSink;
use super::*;
use crate::engine::contact::pose::InstrumentPose;
use crate::engine::scene::Scene;
use crate::engine::simulation::Simulation;
use crate::frame::description::description;
use crate::frame::{Frame, Holder, TickOutputs};

mod chunked;
mod damage;
mod damage_indexed;
mod files;
mod list;
mod lock;
mod read_back;
mod recorder;
mod resim;
mod scene_updates;

/// The default scene's left instrument pushing straight down into the top of the
/// liver, 1 mm a tick from 1 cm above it.
struct Script {
    sim: Simulation,
    outputs: TickOutputs,
    scene: Scene,
    top: Point3<f64>,
    trocar: Point3<f64>,
}

impl Script {
    fn new() -> Self {
        let scene = Scene::default_scene();
        let sim = scene.build().unwrap();
        let (lo, hi) = sim.mesh.bounding_box();
        let top = Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z + 0.01);
        let trocar = sim.instruments[0].trocar;
        Script {
            outputs: TickOutputs::new(sim.instruments.len()),
            sim,
            scene,
            top,
            trocar,
        }
    }

    fn pose(&self, k: u64) -> InstrumentPose {
        let tip = self.top - nalgebra::Vector3::z() * (1e-3 * k as f64);
        InstrumentPose::new(tip, Unit::new_normalize(self.trocar - tip))
    }

    /// The device pose of tick `k`, as a station would send it.
    fn device_pose(&self, k: u64) -> v1::DevicePose {
        let p = self.pose(k);
        v1::DevicePose {
            instrument: self.sim.instruments[0].name.clone(),
            pose: Some(to_pose(&p.tip, &p.axis)),
            device_time_s: k as f64 * 1e-3,
            sequence: k + 1,
        }
    }

    /// Sets tick `k`'s pose, ticks, and returns the frame (held by station 1, with
    /// pose sequence `k + 1`).
    fn tick(&mut self, k: u64) -> Frame {
        self.sim.set_pose(0, Some(self.pose(k)));
        self.sim.tick();
        let held = Holder {
            station: Some(1),
            pose_sequence: Some(k + 1),
        };
        self.outputs.produce(&self.sim, |_| held, |_| {})
    }

    fn header(&self, start: SystemTime) -> SessionHeader {
        SessionHeader {
            session_id: "s7".into(),
            scene_name: self.scene.name.clone(),
            scene_dir: None,
            scene_toml: self.scene.text.clone(),
            start,
            description: description(&self.scene, &self.sim),
        }
    }
}

fn temp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Runs `ticks` ticks of the script through a recorder, with the pose of each tick
/// recorded before it; returns the frames and poses handed over.
fn record_script(path: &Path, ticks: u64) -> (Vec<Arc<Frame>>, Vec<v1::DevicePose>, SessionHeader) {
    record_script_with(path, ticks, Some)
}

/// [`record_script`] with each tick's frame handed over as `keep` makes it: as it
/// is, altered, or not at all (`None`, a frame the recorder lost).
fn record_script_with(
    path: &Path,
    ticks: u64,
    mut keep: impl FnMut(Frame) -> Option<Frame>,
) -> (Vec<Arc<Frame>>, Vec<v1::DevicePose>, SessionHeader) {
    let mut script = Script::new();
    let header = script.header(SystemTime::now());
    let recorder = Recorder::start(path.to_path_buf(), header.clone()).unwrap();
    let (mut frames, mut poses) = (Vec::new(), Vec::new());
    for k in 0..ticks {
        let pose = script.device_pose(k);
        assert_eq!(
            recorder.offer(Item::Pose {
                received: SystemTime::now(),
                pose: pose.clone()
            }),
            None
        );
        poses.push(pose);
        let Some(frame) = keep(script.tick(k)) else {
            continue;
        };
        let frame = Arc::new(frame);
        assert_eq!(
            recorder.offer(Item::Frame {
                frame: frame.clone(),
                wall: SystemTime::now()
            }),
            None
        );
        frames.push(frame);
    }
    recorder.finish().unwrap();
    assert_eq!(
        recorder
            .stats()
            .dropped
            .load(std::sync::atomic::Ordering::Relaxed),
        0
    );
    (frames, poses, header)
}

/// Writes a recording, closing a chunk every `per_chunk` ticks; returns the file
/// size and message count after each chunk, and the finished file's bytes.
fn chunked(path: &Path, ticks: u64, per_chunk: u64) -> (Vec<(u64, u64)>, Vec<u8>) {
    let mut script = Script::new();
    let header = script.header(SystemTime::now());
    let mut sink = McapSink::create(path, &header).unwrap();
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    let mut boundaries = vec![(size(path), sink.messages)];
    for k in 0..ticks {
        sink.write_pose(SystemTime::now(), &script.device_pose(k))
            .unwrap();
        let frame = script.tick(k);
        sink.write_frame(&frame, SystemTime::now()).unwrap();
        if (k + 1) % per_chunk == 0 {
            sink.flush().unwrap();
            boundaries.push((size(path), sink.messages));
        }
    }
    drop(sink.finish().unwrap());
    (boundaries, std::fs::read(path).unwrap())
}

/// Every message of a recording, raw, in file order.
fn raw_messages(path: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), m.log_time, m.data.into_owned())
        })
        .collect()
}
