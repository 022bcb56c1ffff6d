//! A press into the liver along the instrument's trocar direction: the default
//! gesture of simulated stations.
//!
//! The press aims at the rest-surface vertex nearest to the instrument's trocar
//! ([`nearest_surface_vertex`]): the instrument moves along a line that touches the
//! liver there first, with its axis through the trocar as the contract asks.

use std::f64::consts::TAU;

use nalgebra::{Point3, Unit, Vector3};

use super::surface::{nearest_surface_vertex, trocar};
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
