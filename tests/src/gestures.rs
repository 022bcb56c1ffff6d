//! Instrument gestures on the default liver.

use laparo_client::haptics::Trajectory;
use laparo_server::engine::simulation::Simulation;
use nalgebra::{Point3, Unit, Vector3};

/// A probe of the default liver's free front face (+z): the tip approaches along −z,
/// presses in, holds, slides sideways while pressed, holds, and withdraws; the axis
/// always runs from the tip through the instrument's trocar, as a laparoscopic
/// instrument pivots about it.
///
/// Phases, s: `[0, 0.25)` 1 cm in front of the surface; `[0.25, 1.25)` in to `depth`
/// past the surface; `[1.25, 1.75)` held; `[1.75, 2.75)` sliding `slide` along +x;
/// `[2.75, 3.25)` held; `[3.25, 3.75)` back out to 1 cm in front; then still.
#[derive(Clone, Copy, Debug)]
pub struct Probe {
    /// Where the tip starts, 1 cm in front of the surface, m.
    pub start: Point3<f64>,
    /// Depth past the undeformed surface, m.
    pub depth: f64,
    /// Sideways slide while pressed, m.
    pub slide: f64,
    /// The trocar the axis passes through.
    pub trocar: Point3<f64>,
}

/// Duration of a [`Probe`], s.
pub const PROBE_SECONDS: f64 = 4.0;

impl Probe {
    /// A probe of the front face of `sim`'s liver (as it is now) near its middle, by
    /// instrument 0.
    pub fn on_front(sim: &Simulation, depth: f64, slide: f64) -> Self {
        let front = sim
            .mesh
            .surface
            .vertices
            .iter()
            .map(|&v| sim.state.x[v as usize])
            .filter(|p| p.x.abs() < 0.03 && p.y.abs() < 0.02)
            .max_by(|a, b| a.z.total_cmp(&b.z))
            .expect("the default liver has a front face");
        Probe {
            start: front + Vector3::new(-slide / 2.0, 0.0, 0.01),
            depth,
            slide,
            trocar: sim.instruments[0].trocar,
        }
    }

    /// The tip at time `t`, s.
    pub fn tip(&self, t: f64) -> Point3<f64> {
        let ramp = |a: f64, b: f64| ((t - a) / (b - a)).clamp(0.0, 1.0);
        let inward = 0.01 + self.depth;
        let z = -inward * (ramp(0.25, 1.25) - ramp(3.25, 3.75));
        let x = self.slide * ramp(1.75, 2.75);
        self.start + Vector3::new(x, 0.0, z)
    }

    /// The pose at time `t`: the tip and the axis toward the trocar.
    pub fn pose(&self, t: f64) -> (Point3<f64>, Unit<Vector3<f64>>) {
        let tip = self.tip(t);
        (tip, Unit::new_normalize(self.trocar - tip))
    }

    /// The probe as a device trajectory.
    pub fn trajectory(self) -> Trajectory {
        Box::new(move |t| self.pose(t))
    }
}
