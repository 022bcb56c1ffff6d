//! A session whose simulation produced a value that is not finite, or a surface
//! beyond any physical place, stops its output.
//!
//! Scenes are range-checked so that a tick stays finite (`engine::scene::limits`); this
//! is the last guard. Each tick, before anything is published or recorded, the frame's
//! surface positions (f32, so a finite f64 too large for f32 counts too) and every
//! instrument's local model and force are checked — a pass over data the frame holds
//! anyway, no allocation. A surface position beyond ±[`MAX_COORDINATE_M`] halts too:
//! a scene's mesh is refused unless it lies within that range, so tissue found
//! beyond it was thrown there by the simulation (a shaft forced through the liver
//! once flung a vertex 55 km), and frames of it would mean nothing to a trainee.
//! The first fault halts the simulation: the tick's frame is neither sent nor
//! recorded (its contact events, which carry only the tick and its time, are already
//! out), a `SIMULATION_HALTED` event says what and when (to the streams and the
//! recording), `SessionInfo.simulation_error` keeps it, and the thread waits for the
//! session to close (or idle out) without ticking, so that the recording holds only
//! finite frames and is finished as usual.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use laparo_proto::v1;

use super::mechanics::Mechanics;
use crate::engine::scene::limits::{MAX_COORDINATE_M, out_of_place};

/// How often a halted session looks at its stop flag and idle timeout.
const HALTED_POLL: Duration = Duration::from_millis(20);

/// The first value of a tick's output that is not finite, named for the event: a
/// surface position (packed f32 triples) or an instrument's local model or force; or
/// the first surface position beyond ±[`MAX_COORDINATE_M`].
pub fn first_fault(surface: &[f32], instruments: &[v1::InstrumentState]) -> Option<String> {
    if let Some(i) = surface.iter().position(|&v| out_of_place(f64::from(v))) {
        let beyond = if surface[i].is_finite() {
            format!(
                ", beyond the ±{MAX_COORDINATE_M} m a scene's mesh must lie in: the tissue \
                 was thrown out of any physical place"
            )
        } else {
            String::new()
        };
        return Some(format!(
            "surface vertex {} has position component {} = {}{beyond}",
            i / 3,
            ["x", "y", "z"][i % 3],
            surface[i]
        ));
    }
    for s in instruments {
        if let Some(what) = instrument_fault(s) {
            return Some(format!("instrument `{}`: {what}", s.instrument));
        }
    }
    None
}

/// The first part of an instrument's state that is not finite, named (a message
/// a trainee and an instructor read: not the state's Debug form).
fn instrument_fault(s: &v1::InstrumentState) -> Option<String> {
    let vec3 = |v: &Option<v1::Vec3>| v.as_ref().is_none_or(|v| finite(&[v.x, v.y, v.z]));
    let pose = |p: &Option<v1::Pose>| p.as_ref().is_none_or(|p| vec3(&p.tip) && vec3(&p.axis));
    let plane = |p: &Option<v1::LocalPlane>| {
        p.as_ref()
            .is_none_or(|p| vec3(&p.normal) && vec3(&p.anchor) && p.stiffness_n_per_m.is_finite())
    };
    let first_bad = |parts: &[(&str, bool)]| {
        parts
            .iter()
            .find(|(_, ok)| !ok)
            .map(|(what, _)| what.to_string())
    };
    if let Some(m) = &s.local_model {
        let bad = first_bad(&[
            ("pose", pose(&m.pose)),
            ("tip plane", plane(&m.tip_plane)),
            ("shaft plane", plane(&m.shaft_plane)),
            (
                "Young's modulus",
                m.young_modulus_pa.is_none_or(f64::is_finite),
            ),
        ]);
        if let Some(what) = bad {
            return Some(format!("local model's {what} is not finite"));
        }
    }
    if let Some(f) = &s.force {
        let bad = first_bad(&[
            ("force", vec3(&f.force)),
            ("torque", vec3(&f.torque)),
            ("axial force", f.axial_n.is_finite()),
            ("force magnitude", f.magnitude_n.is_finite()),
        ]);
        if let Some(what) = bad {
            return Some(format!("{what} is not finite"));
        }
    }
    if !pose(&s.pose) {
        return Some("pose is not finite".into());
    }
    None
}

fn finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

impl Mechanics {
    /// Halts the simulation on `fault` (see the module notes) and waits, without
    /// ticking, until the session closes, is dropped, or idles out.
    pub(super) fn halt(&mut self, fault: String, mut idle_since: Option<Instant>) {
        let detail = format!(
            "the simulation stopped at tick {}: {fault}; this tick was not sent or recorded",
            self.sim.tick
        );
        tracing::error!(tick = self.sim.tick, "{detail}");
        let _ = self.stats.simulation_error.set(detail.clone());
        let event = v1::Event {
            tick: self.sim.tick,
            sim_time_s: self.sim.time,
            kind: v1::EventKind::SimulationHalted as i32,
            station_id: None,
            instrument: None,
            detail,
        };
        super::broadcast_event(self.recorder.as_deref(), &self.events, event);
        while !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(HALTED_POLL);
            if !self.check_idle(&mut idle_since, Instant::now()) {
                break;
            }
        }
    }
}
