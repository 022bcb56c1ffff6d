//! Forces from a local model: the pure functions the server and every force loop must
//! agree on (paper §3).
//!
//! A local model is two planes — the tip plane and the shaft plane — each with a unit
//! normal `n` pointing out of the tissue, an anchor `A` and an apparent stiffness `λ`.
//! Each gives a force on the instrument from the penetration of the instrument into
//! the plane's half-space (eq. 8); the two combine smoothly (eq. 9); and a laparoscopic
//! device takes the result as an axial force and torques about the trocar.
//! [`LocalModel`] bundles the two planes with the tick and pose they were made for and
//! evaluates them at any device pose; [`wire`] converts it to and from the contract's
//! message, checking what arrives.

use nalgebra::{Point3, Unit, Vector3};

/// One plane of a local model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal `n`, out of the tissue.
    pub normal: Unit<Vector3<f64>>,
    /// A point `A` of the plane, m.
    pub anchor: Point3<f64>,
    /// Apparent stiffness `λ`, N/m.
    pub stiffness: f64,
    /// The drag of the tissue the plane's contact holds, at the pose the model was
    /// made for: the reaction's part along the plane (orthogonal to `n`), N.
    pub drag: Vector3<f64>,
}

impl Plane {
    /// The stiffest spring the plane renders, N/m: `λ` along `n`, and `κ λ` along the
    /// plane for the held tissue's pull when it carries a drag
    /// ([`LATERAL_STIFFNESS_RATIO`]).
    pub fn stiffest_spring(&self) -> f64 {
        if self.drag == Vector3::zeros() {
            self.stiffness
        } else {
            LATERAL_STIFFNESS_RATIO * self.stiffness
        }
    }

    /// Lowers `λ` so that no spring of the plane is stiffer than `limit` (N/m).
    pub fn limit_stiffness(&mut self, limit: f64) {
        let stiffest = self.stiffest_spring();
        if stiffest > limit {
            self.stiffness *= limit / stiffest;
        }
    }
}

/// Eq. 8: the plane's force on the instrument whose tip is at `tip`,
/// `F = λ · max(0, (A − P)·n) · n`, N.
///
/// The printed eq. 8, `λ (P − A)·n`, is a scalar with the opposite sign: with `n` out
/// of the tissue, the tip is inside by the depth `d = (A − P)·n > 0`, and the tissue
/// pushes it back along `+n`. A tip outside (`d ≤ 0`) feels nothing.
pub fn plane_force(plane: &Plane, tip: &Point3<f64>) -> Vector3<f64> {
    let depth = (plane.anchor - tip).dot(&plane.normal);
    if depth > 0.0 {
        plane.normal.into_inner() * (plane.stiffness * depth)
    } else {
        Vector3::zeros()
    }
}

/// Eq. 9: the tip force `f0` and the shaft force `f1` combined as the paper's prose
/// defines it: pointing the same way, the larger; orthogonal or opposed, the sum; and
/// continuous everywhere, so that contacts appearing or vanishing never make the force
/// jump.
///
/// With `p = f0·f1`:
/// - `p ≤ 0` (orthogonal or opposed): `f0 + f1`;
/// - `p ≥ |f0|²` (f1's part along f0 reaches past f0: f1 is the larger): `f1`;
/// - `p ≥ |f1|²`: `f0`;
/// - otherwise the blend
///   `(f0 |f1|² (|f0|² − p) + f1 |f0|² (|f1|² − p)) / (|f0|² |f1|² − p²)`,
///   which is `f0 + f1` at `p = 0`, `f1` at `p = |f0|²` and `f0` at `p = |f1|²`, so
///   the four cases meet continuously.
///
/// The printed eq. 9 swaps cases (b) and (c) — `|F0|² ≤ F0·F1` makes F1 the larger,
/// yet it returns F0 — and its denominator `(F0·F1)² − ‖F0‖·‖F1‖` mixes squared and
/// plain norms; with the cases swapped back and the denominator `p² − |F0|²|F1|²`,
/// its numerator is the one above with both signs flipped.
///
/// Accuracy when the two forces are nearly equal: the denominator is computed as
/// `|f0 × f1|²` (Lagrange's identity) and `|f0|² − p` as `f0·(f0 − f1)`, so neither
/// is a difference of nearly equal large numbers.
pub fn combine(f0: &Vector3<f64>, f1: &Vector3<f64>) -> Vector3<f64> {
    let p = f0.dot(f1);
    let (n0, n1) = (f0.norm_squared(), f1.norm_squared());
    if p <= 0.0 {
        return f0 + f1;
    }
    if p >= n0 {
        return *f1;
    }
    if p >= n1 {
        return *f0;
    }
    let denominator = f0.cross(f1).norm_squared();
    let (a, b) = (f0.dot(&(f0 - f1)), f1.dot(&(f1 - f0)));
    if denominator <= 0.0 {
        // Parallel to the last bit inside the blend region: p < |f0|² and p < |f1|²
        // with f0 ∥ f1 leaves only equal forces, for which every case agrees.
        return (f0 + f1) * 0.5;
    }
    (f0 * (n1 * a) + f1 * (n0 * b)) / denominator
}

/// What a laparoscopic device takes: the force along the shaft and the torque about
/// the trocar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceForce {
    /// The total force on the instrument, N.
    pub force: Vector3<f64>,
    /// Its component along the axis `Z`, N: positive toward the handle (the tissue
    /// pushing the instrument out).
    pub axial: f64,
    /// Torque about the trocar point, N·m: `(C − T) × F`, with `C` the point where
    /// the force applies (see [`LocalModel::force`]).
    pub torque: Vector3<f64>,
}

/// Splits `force`, applied at `point` on an instrument of axis `axis` entering through
/// `trocar`, into its axial part and its torque about the trocar.
pub fn split(
    force: &Vector3<f64>,
    point: &Point3<f64>,
    axis: &Unit<Vector3<f64>>,
    trocar: &Point3<f64>,
) -> DeviceForce {
    DeviceForce {
        force: *force,
        axial: force.dot(axis),
        torque: (point - trocar).cross(force),
    }
}

mod model;
pub mod wire;

pub use model::{AppliedForce, ForceModel, LATERAL_STIFFNESS_RATIO, LocalModel};

#[cfg(test)]
mod tests;
