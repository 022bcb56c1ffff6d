//! The demo's gesture: the instrument presses the liver's front with its tip, then
//! lies across it and presses with its shaft.

use nalgebra::{Unit, Vector3};

use super::surface::front;
use crate::haptics::Trajectory;
use crate::proto::v1::{InstrumentDescription, SceneDescription};

/// Duration of one gesture, s; it repeats.
pub const PERIOD_S: f64 = 10.0;

/// The demo gesture, [`PERIOD_S`] long, repeating. With `f` the [`front`] point:
/// - 0–0.5 s: the tip 2 cm in front of `f` (2 cm to its left), axis +z;
/// - 0.5–2.5 s: in along −z to 1 cm past the surface; held to 3.5 s; out by 4 s;
/// - 4–5 s: turning the axis to −x (the shaft across the front face, 2 cm in front
///   of it), the tip 6 cm to the right of `f`;
/// - 5–7 s: the shaft pushed 3 cm along −z into the face; held to 8.5 s; back out by
///   9.5 s.
pub fn tip_and_shaft(scene: &SceneDescription, _instrument: &InstrumentDescription) -> Trajectory {
    let f = front(scene);
    Box::new(move |t: f64| {
        let t = t.rem_euclid(PERIOD_S);
        let ramp = |a: f64, b: f64| ((t - a) / (b - a)).clamp(0.0, 1.0);
        let tip_start = f + Vector3::new(-0.02, 0.0, 0.02);
        let shaft_start = f + Vector3::new(0.06, 0.0, 0.02);
        if t < 4.0 {
            let z = -0.03 * ramp(0.5, 2.5) + 0.03 * ramp(3.5, 4.0);
            (tip_start + Vector3::new(0.0, 0.0, z), Vector3::z_axis())
        } else {
            let turn = ramp(4.0, 5.0);
            let axis = Unit::new_normalize(
                Vector3::z() * (1.0 - turn) + Vector3::new(-1.0, 0.0, 0.0) * turn,
            );
            let tip = tip_start + (shaft_start - tip_start) * turn;
            let z = -0.03 * ramp(5.0, 7.0) + 0.03 * ramp(8.5, 9.5);
            (tip + Vector3::new(0.0, 0.0, z), axis)
        }
    })
}
