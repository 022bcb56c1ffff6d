//! The demo's gesture: the left instrument presses the liver's front with its tip,
//! then lies across it and presses with its shaft.

use laparo_proto::v1::{InstrumentDescription, SceneDescription};
use nalgebra::{Point3, Unit, Vector3};

use crate::haptics::Trajectory;

/// The front point of the rest surface: the most forward (+z) surface vertex near the
/// middle (|x| < 3 cm, |y| < 2 cm), or the most forward of all.
pub fn front(scene: &SceneDescription) -> Point3<f64> {
    let positions = scene
        .rest_surface
        .as_ref()
        .map(|s| s.positions.as_slice())
        .unwrap_or_default();
    let points = positions
        .chunks_exact(3)
        .map(|c| Point3::new(f64::from(c[0]), f64::from(c[1]), f64::from(c[2])));
    let forward = |a: &Point3<f64>, b: &Point3<f64>| a.z.total_cmp(&b.z);
    points
        .clone()
        .filter(|p| p.x.abs() < 0.03 && p.y.abs() < 0.02)
        .max_by(forward)
        .or_else(|| points.max_by(forward))
        .unwrap_or_else(Point3::origin)
}

/// The demo gesture, 10 s, repeating. With `f` the front point:
/// - 0–0.5 s: the tip 2 cm in front of `f` (2 cm to its left), axis +z;
/// - 0.5–2.5 s: in along −z to 1 cm past the surface; held to 3.5 s; out by 4 s;
/// - 4–5 s: turning the axis to −x (the shaft across the front face, 2 cm in front
///   of it), the tip 6 cm to the right of `f`;
/// - 5–7 s: the shaft pushed 3 cm along −z into the face; held to 8.5 s; back out by
///   9.5 s.
pub fn gesture(scene: &SceneDescription, _instrument: &InstrumentDescription) -> Trajectory {
    let f = front(scene);
    Box::new(move |t: f64| {
        let t = t.rem_euclid(10.0);
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
