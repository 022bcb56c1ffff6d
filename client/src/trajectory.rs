//! Scripted instrument gestures for simulated stations: a press into the liver along
//! the instrument's trocar direction.
//!
//! The press aims at the rest-surface vertex nearest to the instrument's trocar. No
//! surface point is nearer the trocar than that vertex, so the open segment from the
//! trocar to it crosses no surface: an instrument moving along that line touches the
//! liver there first, with its axis through the trocar as the contract asks.

use std::f64::consts::TAU;

use nalgebra::{Point3, Unit, Vector3};

use crate::haptics::Trajectory;
use crate::proto::v1::{InstrumentDescription, SceneDescription};

/// How far outside the surface the default press starts, m.
pub const DEFAULT_STANDOFF_M: f64 = 0.01;
/// How deep below the rest surface the default press goes, m.
pub const DEFAULT_DEPTH_M: f64 = 0.01;
/// Period of the default press (out, in, out), s.
pub const DEFAULT_PERIOD_S: f64 = 4.0;

/// The default press of an instrument with trocar `trocar` on the surface point
/// `target`: [`press`] with [`DEFAULT_STANDOFF_M`], [`DEFAULT_DEPTH_M`] and
/// [`DEFAULT_PERIOD_S`].
pub fn default_press(trocar: Point3<f64>, target: Point3<f64>) -> Trajectory {
    press(
        trocar,
        target,
        DEFAULT_STANDOFF_M,
        DEFAULT_DEPTH_M,
        DEFAULT_PERIOD_S,
    )
}

/// A repeated press on `target` along the line from `trocar`.
///
/// The axis `Z` is the unit vector from `target` toward `trocar` (tip toward handle,
/// through the trocar); the tip is at `target + h(t) Z` with
/// `h(t) = standoff − (standoff + depth)(1 − cos(2πt/period))/2`: `standoff` m outside
/// at `t = 0`, `depth` m inside the rest surface at half a period, back out at a full
/// period, smooth throughout. If `target` is the trocar itself the axis is +z.
pub fn press(
    trocar: Point3<f64>,
    target: Point3<f64>,
    standoff: f64,
    depth: f64,
    period: f64,
) -> Trajectory {
    let axis = Unit::try_new(trocar - target, 1e-9).unwrap_or_else(Vector3::z_axis);
    let period = if period > 0.0 {
        period
    } else {
        DEFAULT_PERIOD_S
    };
    Box::new(move |t| {
        let h = standoff - (standoff + depth) * 0.5 * (1.0 - (TAU * t / period).cos());
        (target + axis.into_inner() * h, axis)
    })
}

/// The rest-surface vertex nearest to `point`; `None` for a scene without surface.
pub fn nearest_surface_vertex(
    scene: &SceneDescription,
    point: &Point3<f64>,
) -> Option<Point3<f64>> {
    let surface = scene.rest_surface.as_ref()?;
    surface
        .positions
        .chunks_exact(3)
        .map(|p| Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .min_by(|a, b| {
            let da = (a - point).norm_squared();
            let db = (b - point).norm_squared();
            da.total_cmp(&db)
        })
}

/// The instrument's trocar, m (the origin when the scene leaves it out).
pub fn trocar(instrument: &InstrumentDescription) -> Point3<f64> {
    instrument
        .trocar
        .as_ref()
        .map_or_else(Point3::origin, |v| Point3::new(v.x, v.y, v.z))
}

/// The default press of `instrument` in `scene`: on the rest-surface vertex nearest
/// its trocar, or straight down the axis 10 cm below the trocar for a scene without
/// surface.
pub fn default_press_for(
    scene: &SceneDescription,
    instrument: &InstrumentDescription,
) -> Trajectory {
    let trocar = trocar(instrument);
    let target = nearest_surface_vertex(scene, &trocar)
        .unwrap_or_else(|| trocar - Vector3::new(0.0, 0.0, 0.1));
    default_press(trocar, target)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::v1::{SurfaceMesh, Vec3};

    #[test]
    fn press_starts_outside_goes_in_and_keeps_the_axis_through_the_trocar() {
        let trocar = Point3::new(0.0, 0.0, 0.2);
        let target = Point3::origin();
        let path = default_press(trocar, target);
        let (tip0, axis) = path(0.0);
        assert!((tip0.z - DEFAULT_STANDOFF_M).abs() < 1e-12);
        assert!((axis.into_inner() - Vector3::z()).norm() < 1e-12);
        let (tip_half, _) = path(DEFAULT_PERIOD_S / 2.0);
        assert!((tip_half.z + DEFAULT_DEPTH_M).abs() < 1e-12);
        let (tip1, _) = path(DEFAULT_PERIOD_S);
        assert!((tip1 - tip0).norm() < 1e-12);
    }

    #[test]
    fn aims_at_the_surface_vertex_nearest_the_trocar() {
        let scene = SceneDescription {
            rest_surface: Some(SurfaceMesh {
                positions: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.05, 1.0, 1.0, 1.0],
                triangles: vec![0, 1, 2],
            }),
            ..Default::default()
        };
        let instrument = InstrumentDescription {
            trocar: Some(Vec3 {
                x: 0.0,
                y: 0.0,
                z: 0.2,
            }),
            ..Default::default()
        };
        let (tip, _) = default_press_for(&scene, &instrument)(0.0);
        assert!((tip.z - (0.05 + DEFAULT_STANDOFF_M)).abs() < 1e-6, "{tip}");
    }
}
