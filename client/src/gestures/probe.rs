//! A probe of the liver's free front face (+z): the tip approaches along −z, presses
//! in, holds, slides sideways while pressed, holds, and withdraws; the axis always
//! runs from the tip through the instrument's trocar.

use nalgebra::{Point3, Unit, Vector3};

use super::surface::front_middle;
use crate::haptics::Trajectory;

/// Duration of a [`Probe`], s.
pub const PROBE_SECONDS: f64 = 4.0;

/// How far in front of the surface the probe starts and ends, m.
pub const PROBE_STANDOFF_M: f64 = 0.01;

/// The phases of a [`Probe`], in order: each one's name and start, s. Each lasts until
/// the next starts; the last, until [`PROBE_SECONDS`].
pub const PROBE_PHASES: [(&str, f64); 7] = [
    ("stand-off", 0.0),
    ("press", 0.25),
    ("hold", 1.25),
    ("slide", 1.75),
    ("hold slid", 2.75),
    ("withdraw", 3.25),
    ("still", 3.75),
];

/// When phase `k` of [`PROBE_PHASES`] starts, s.
const fn phase(k: usize) -> f64 {
    PROBE_PHASES[k].1
}

/// A probe of the front face, through the phases of [`PROBE_PHASES`]: a stand-off
/// [`PROBE_STANDOFF_M`] in front of the surface; a press in to `depth` past the
/// surface; a hold; a slide of `slide` along +x; a hold; a withdrawal back out to the
/// start; then still.
#[derive(Clone, Copy, Debug)]
pub struct Probe {
    /// Where the tip starts, [`PROBE_STANDOFF_M`] in front of the surface, m.
    pub start: Point3<f64>,
    /// Depth past the undeformed surface, m.
    pub depth: f64,
    /// Sideways slide while pressed, m.
    pub slide: f64,
    /// The trocar the axis passes through.
    pub trocar: Point3<f64>,
}

impl Probe {
    /// A probe of the front face near its middle ([`front_middle`] of the surface
    /// points given, m), by an instrument with `trocar`, centred on the front point
    /// over its slide. `None` when no surface point is near the middle.
    pub fn on_front(
        surface: impl IntoIterator<Item = Point3<f64>>,
        trocar: Point3<f64>,
        depth: f64,
        slide: f64,
    ) -> Option<Self> {
        let front = front_middle(surface)?;
        Some(Probe {
            start: front + Vector3::new(-slide / 2.0, 0.0, PROBE_STANDOFF_M),
            depth,
            slide,
            trocar,
        })
    }

    /// The tip at time `t`, s.
    pub fn tip(&self, t: f64) -> Point3<f64> {
        let ramp = |a: f64, b: f64| ((t - a) / (b - a)).clamp(0.0, 1.0);
        let inward = PROBE_STANDOFF_M + self.depth;
        let z = -inward * (ramp(phase(1), phase(2)) - ramp(phase(5), phase(6)));
        let x = self.slide * ramp(phase(3), phase(4));
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
