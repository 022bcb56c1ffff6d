//! A tick that produces a value that is not finite is neither published nor recorded;
//! the session says why (event, `SessionInfo.simulation_error`) and its recording
//! stays readable.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Weak};
use std::time::SystemTime;

use laparo_proto::v1;
use tokio::sync::{broadcast, watch};

use crate::engine::scene::Scene;
use crate::engine::scene::limits::MAX_COORDINATE_M;
use crate::frame::Frame;
use crate::frame::description::description;
use crate::recording::{Recorder, Recording, SessionHeader};
use crate::session::mechanics::{Mechanics, spawn};
use crate::session::{SessionStats, first_fault};

fn state(force: [f64; 3]) -> v1::InstrumentState {
    v1::InstrumentState {
        instrument: "left".into(),
        force: Some(v1::Force {
            force: Some(v1::Vec3 {
                x: force[0],
                y: force[1],
                z: force[2],
            }),
            ..Default::default()
        }),
        ..Default::default()
    }
}

#[test]
fn the_first_non_finite_or_far_flung_value_of_a_frame_is_named() {
    assert_eq!(
        first_fault(&[0.0, 1.0, 2.0], &[state([1.0, 0.0, 0.0])]),
        None
    );
    let surface = first_fault(&[0.0, 1.0, 2.0, 3.0, f32::INFINITY, 5.0], &[]).unwrap();
    assert!(
        surface.contains("surface vertex 1") && surface.contains("y"),
        "{surface}"
    );
    // Finite, but beyond the range a scene's mesh must lie in.
    let bound = MAX_COORDINATE_M as f32;
    assert_eq!(first_fault(&[bound, -bound, 0.0], &[]), None);
    let thrown = first_fault(&[0.0, 0.0, 0.0, 1.0, 2.0, -2.0 * bound], &[]).unwrap();
    assert!(
        thrown.contains("surface vertex 1") && thrown.contains("z") && thrown.contains("beyond"),
        "{thrown}"
    );
    let force = first_fault(&[0.0; 3], &[state([0.0, f64::NAN, 0.0])]).unwrap();
    assert!(
        force.contains("`left`") && force.contains("force"),
        "{force}"
    );
    let model = v1::InstrumentState {
        local_model: Some(v1::LocalModel {
            tip_plane: Some(v1::LocalPlane {
                stiffness_n_per_m: f64::INFINITY,
                ..Default::default()
            }),
            ..Default::default()
        }),
        ..state([0.0; 3])
    };
    // Named in words, not the state's Debug form.
    let model = first_fault(&[], &[model]).unwrap();
    assert_eq!(
        model, "instrument `left`: local model's tip plane is not finite",
        "{model}"
    );
    assert_eq!(force, "instrument `left`: force is not finite");
}

#[test]
fn a_non_finite_tick_halts_the_session_and_its_recording_stays_finite() {
    let scene = Scene::default_scene();
    let mut sim = scene.build().unwrap();
    // A free surface vertex (held ones are put back on their targets).
    let v = *sim
        .mesh
        .surface
        .vertices
        .iter()
        .find(|v| sim.fixed.binary_search(v).is_err())
        .unwrap() as usize;
    sim.state.x[v].x = f64::NAN;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("halted.mcap");
    let header = SessionHeader {
        session_id: "s1".into(),
        scene_name: scene.name.clone(),
        scene_toml: scene.text.clone(),
        scene_dir: None,
        start: SystemTime::now(),
        description: description(&scene, &sim),
    };
    let recorder = Arc::new(Recorder::start(path.clone(), header).unwrap());
    let (frames_tx, frames) = watch::channel(Arc::new(Frame::default()));
    let (events, mut events_rx) = broadcast::channel(64);
    let stats = Arc::new(SessionStats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let thread = spawn(Mechanics {
        sim,
        inputs: Vec::new(),
        frames: frames_tx,
        events,
        stats: stats.clone(),
        stop: stop.clone(),
        // No session: once halted, the thread ends as a dropped session's would.
        session: Weak::new(),
        recorder: Some(recorder),
    })
    .unwrap();
    let halted = loop {
        match events_rx.blocking_recv() {
            Ok(e) if e.kind == v1::EventKind::SimulationHalted as i32 => break e,
            Ok(_) => continue,
            Err(e) => panic!("no SIMULATION_HALTED event: {e}"),
        }
    };
    assert_eq!(halted.tick, 1);
    assert!(
        halted.detail.contains("surface vertex"),
        "{}",
        halted.detail
    );
    assert_eq!(stats.simulation_error.get(), Some(&halted.detail));
    thread.join().unwrap();
    assert_eq!(
        frames.borrow().tick,
        0,
        "the non-finite tick was not published"
    );

    let recording = Recording::open(&path).unwrap();
    assert!(recording.is_complete());
    let surfaces = recording.surfaces().unwrap();
    assert!(
        surfaces
            .iter()
            .all(|s| s.message.positions.iter().all(|p| p.is_finite()))
    );
    assert!(surfaces.is_empty(), "the only tick was not finite");
    let recorded = recording.events().unwrap();
    assert!(
        recorded
            .iter()
            .any(|e| e.message.kind == v1::EventKind::SimulationHalted as i32),
        "the halt is in the recording"
    );
}
