//! A tick's outputs: its events are exactly the contact changes between consecutive
//! frames, stamped with the tick, and its frame is the simulation read after the step.

use nalgebra::{Point3, Unit, Vector3};

use super::state::{instrument_state, surface_positions};
use super::*;
use crate::engine::contact::pose::InstrumentPose;
use crate::engine::scene::Scene;

/// Whether a contact state is any contact at all.
fn touching(s: &v1::InstrumentState) -> bool {
    s.contact != v1::ContactState::None as i32
}

#[test]
fn events_are_the_contact_changes_between_frames_and_come_with_their_tick() {
    let mut sim = Scene::default_scene().build().unwrap();
    let (lo, hi) = sim.mesh.bounding_box();
    let top = Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z + 0.01);
    let trocar = sim.instruments[0].trocar;
    let n = sim.instruments.len();
    let mut outputs = TickOutputs::new(n);
    let holder = |k: usize| Holder {
        station: (k == 0).then_some(7),
        pose_sequence: (k == 0).then_some(40 + k as u64),
    };
    // Down 1 mm a tick from 1 cm above the top to 2 cm in, then back out.
    let depth = |t: u64| 1e-3 * (if t <= 30 { t } else { 60 - t.min(60) }) as f64;
    let mut previous: Option<Frame> = None;
    let (mut began, mut ended) = (0, 0);
    for t in 0..=64u64 {
        let tip = top - Vector3::z() * depth(t);
        let pose = InstrumentPose::new(tip, Unit::new_normalize(trocar - tip));
        sim.set_pose(0, Some(pose));
        sim.tick();
        let mut events = Vec::new();
        let frame = outputs.produce(&sim, holder, |e| events.push(e));
        // The frame is the simulation as it stands after the step.
        assert_eq!((frame.tick, frame.sim_time), (sim.tick, sim.time));
        assert_eq!(frame.surface, surface_positions(&sim));
        let states: Vec<_> = (0..n)
            .map(|k| instrument_state(&sim, k, holder(k).station, holder(k).pose_sequence))
            .collect();
        assert_eq!(frame.instruments, states);
        // One event per instrument whose contact came or went, in scene order.
        let was = |k: usize| {
            previous
                .as_ref()
                .is_some_and(|p| touching(&p.instruments[k]))
        };
        let changed: Vec<usize> = (0..n)
            .filter(|&k| was(k) != touching(&frame.instruments[k]))
            .collect();
        assert_eq!(events.len(), changed.len(), "tick {}", sim.tick);
        for (e, &k) in events.iter().zip(&changed) {
            let now_in = touching(&frame.instruments[k]);
            let kind = if now_in {
                began += 1;
                v1::EventKind::ContactBegan
            } else {
                ended += 1;
                v1::EventKind::ContactEnded
            };
            assert_eq!(e.kind, kind as i32);
            assert_eq!((e.tick, e.sim_time_s), (frame.tick, frame.sim_time));
            assert_eq!(
                e.instrument.as_deref(),
                Some(sim.instruments[k].name.as_str())
            );
            assert_eq!(e.station_id, holder(k).station);
            // What touches, in words; nothing once nothing does.
            let state = v1::ContactState::try_from(frame.instruments[k].contact).unwrap();
            let words = match state {
                v1::ContactState::Tip => "tip",
                v1::ContactState::Shaft => "shaft",
                v1::ContactState::TipAndShaft => "tip and shaft",
                _ => "",
            };
            assert_eq!(e.detail, words, "tick {}", frame.tick);
            assert_eq!(e.detail.is_empty(), !now_in);
        }
        previous = Some(frame);
    }
    // The push touched the liver and left it again.
    assert!(began >= 1 && ended >= 1, "began {began}, ended {ended}");
}
