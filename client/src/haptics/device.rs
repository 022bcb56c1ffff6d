//! The haptic device as the force loop sees it, and two simulated devices.
//!
//! A device gives the instrument's pose at each haptic tick and takes the force to
//! render. Real drivers implement [`HapticDevice`]; [`ScriptedDevice`] follows a
//! scripted path (tests, benchmarks, demos) and [`HandDevice`] is a hand holding the
//! instrument, pushed back by the rendered force (stability and passivity tests).

use nalgebra::{Point3, Unit, Vector3};

use crate::proto::force::DeviceForce;

mod hand;
mod scripted;

pub use hand::{HandDevice, HandParams};
pub use scripted::{RenderedForce, ScriptedDevice};

/// A haptic device holding one laparoscopic instrument.
///
/// Times are haptic time in seconds, increasing from one call to the next; the force
/// loop calls `pose` then `render` once per tick, from its own thread. Neither should
/// block or allocate.
pub trait HapticDevice: Send {
    /// The instrument's tip `P` (m, world frame) and unit axis `Z` (tip toward handle)
    /// at haptic time `t`.
    fn pose(&mut self, t: f64) -> (Point3<f64>, Unit<Vector3<f64>>);

    /// Renders `force` (N, world frame; axial part N; torque about the trocar N·m)
    /// from haptic time `t` until the next call.
    fn render(&mut self, t: f64, force: &DeviceForce);

    /// The largest force magnitude the device can render, N. The force loop clamps
    /// to it, keeping the direction.
    fn max_force(&self) -> f64;

    /// The stiffest plane the device renders stably at the loop's rate, N/m: the
    /// force loop lowers any plane's stiffness so that none of its springs is stiffer
    /// (`laparo_proto::force::Plane::limit_stiffness`; the device then sinks deeper
    /// into a stiff tissue to feel the same force, as real devices do). A device that
    /// only follows a script has no dynamics to destabilise: no limit.
    fn max_stiffness(&self) -> f64 {
        f64::INFINITY
    }
}

/// A device pose sampled by the force loop, as published to the network side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DevicePose {
    /// Haptic time of the sample, s.
    pub time: f64,
    /// Instrument tip `P`, m, world frame.
    pub tip: Point3<f64>,
    /// Instrument axis `Z`, unit, tip toward handle.
    pub axis: Unit<Vector3<f64>>,
}

/// A scripted instrument path: the pose (tip, axis) at each haptic time, s.
pub type Trajectory = Box<dyn Fn(f64) -> (Point3<f64>, Unit<Vector3<f64>>) + Send>;

#[cfg(test)]
mod tests;
