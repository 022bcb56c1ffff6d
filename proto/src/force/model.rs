//! The local model of one instrument at one tick, evaluated at any device pose.

use nalgebra::{Point3, Unit, Vector3};

use super::{Plane, combine, plane_force};

/// How the apparent stiffnesses of a local model were obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ForceModel {
    /// The paper's: `λ` proportional to the average Young's modulus near the contact.
    #[default]
    Geometric,
    /// Fitted to the elastic model's reaction on the vertices the instrument holds.
    Calibrated,
}

/// The two-plane local model ("buffer model", paper §3) of one instrument, made by the
/// server at one mechanics tick for one instrument pose, and evaluated by force loops
/// at every haptic tick at the device's pose until the next one arrives.
///
/// Each plane's anchor is placed so that its penetration depth at the pose the model
/// was made for is the indentation the instrument has made in the tissue (how the
/// server chooses it is documented where it builds the model); moving the instrument
/// deeper adds to that depth one for one, withdrawing takes from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalModel {
    /// Mechanics tick the model was made at.
    pub tick: u64,
    /// Simulated time of that tick, s.
    pub sim_time: f64,
    /// Instrument tip `P` the model was made for, m.
    pub tip: Point3<f64>,
    /// Instrument axis `Z` (tip toward handle) the model was made for.
    pub axis: Unit<Vector3<f64>>,
    /// The tip plane (normal `n_prox`), while the tip touches the tissue.
    pub tip_plane: Option<Plane>,
    /// The shaft plane (normal orthogonal to the axis), while the shaft touches it.
    pub shaft_plane: Option<Plane>,
    /// How the stiffnesses were obtained.
    pub kind: ForceModel,
    /// Average Young's modulus near the contact, Pa; `None` without contact.
    pub young_modulus: Option<f64>,
}

/// A force on the instrument and the point of the axis where it applies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AppliedForce {
    /// N, world frame.
    pub force: Vector3<f64>,
    /// m, world frame: on the instrument axis.
    pub point: Point3<f64>,
}

impl LocalModel {
    /// A model with no plane: no contact, no force.
    pub fn free(tick: u64, sim_time: f64, tip: Point3<f64>, axis: Unit<Vector3<f64>>) -> Self {
        LocalModel {
            tick,
            sim_time,
            tip,
            axis,
            tip_plane: None,
            shaft_plane: None,
            kind: ForceModel::default(),
            young_modulus: None,
        }
    }

    /// Whether any plane is in use.
    pub fn in_contact(&self) -> bool {
        self.tip_plane.is_some() || self.shaft_plane.is_some()
    }

    /// The force of the model on the instrument at tip `tip` and axis `axis`.
    ///
    /// - Tip plane (eq. 8, corrected sign): depth `d₀ = (A₀ − P)·n₀` of the tip `P`,
    ///   force `f₀ = λ₀ max(0, d₀) n₀`, applied at `P`.
    /// - Shaft plane: the plane holds the axis, so the depth is taken at the point of
    ///   the axis level with the anchor, `Q = P + max(0, (A₁ − P)·Z) Z`:
    ///   `d₁ = (A₁ − Q)·n₁`, `f₁ = λ₁ max(0, d₁) n₁`, applied at `Q`. At the pose the
    ///   model was made for, `n₁ ⟂ Z` and `d₁ = (A₁ − P)·n₁`, the paper's depth of the
    ///   tip; when the instrument pivots about its trocar, the shaft contact moves by
    ///   its own lever arm rather than the tip's.
    /// - Each plane that carries a drag (the calibrated model's) adds it, with the
    ///   held tissue's pull back toward where its contact point (`P`, or `Q`) was at
    ///   the model's pose (`held_drag` below).
    /// - The two combine by eq. 9 ([`combine`]); the result applies at the
    ///   magnitude-weighted point `C = (|f₀| P + |f₁| Q) / (|f₀| + |f₁|)`, which moves
    ///   continuously from `P` to `Q` as the contacts change (and is `P` without force).
    pub fn force(&self, tip: &Point3<f64>, axis: &Unit<Vector3<f64>>) -> AppliedForce {
        let f0 = self.tip_plane.as_ref().map_or_else(Vector3::zeros, |p| {
            plane_force(p, tip) + held_drag(p, &self.tip, tip)
        });
        let (f1, q) = match &self.shaft_plane {
            Some(plane) => {
                let s = (plane.anchor - tip).dot(axis).max(0.0);
                let q = tip + axis.into_inner() * s;
                let s0 = (plane.anchor - self.tip).dot(&self.axis).max(0.0);
                let q0 = self.tip + self.axis.into_inner() * s0;
                (plane_force(plane, &q) + held_drag(plane, &q0, &q), q)
            }
            None => (Vector3::zeros(), *tip),
        };
        let (m0, m1) = (f0.norm(), f1.norm());
        let point = if m0 + m1 > 0.0 {
            Point3::from((tip.coords * m0 + q.coords * m1) / (m0 + m1))
        } else {
            *tip
        };
        AppliedForce {
            force: combine(&f0, &f1),
            point,
        }
    }
}

/// How much stiffer sideways than along `n` the held tissue pulls: the drag's
/// lateral spring is `κ λ` with `κ = 1.5`.
///
/// `λ`, fitted along `n`, is the held tissue's normal secant stiffness. Measured on
/// the default liver (a tip pressed and held, then moved 0.05 mm and let settle, at
/// E = 0.1, 0.5, 1 and 10 MPa, with and without the footprint scale), the drag
/// changes by 1.7–1.9 `λ` per metre when the instrument moves against the held tissue
/// (which stays stuck to it) and by 0.4–0.9 `λ` when it moves the other way (the
/// tissue at its friction limit slips); with three or four vertices held, 1.9–3.7 `λ`
/// stuck. A force loop that renders the pull softer than the stuck tissue leaves the
/// rest to the next model, a lateral spring sampled at the mechanics rate: with
/// `κ = 1`, a 0.15 kg hand resting 2–8 mm past the surface at 60 Hz gained energy at
/// 49 of 84 targets over E = 0.1–10 MPa with and without the footprint scale. Over
/// the same grid `κ` = 1.5, 1.75, 2 and 2.5 left 0, 2, 1 and 3 such targets; 1.5 is
/// the stuck tissue's single-vertex stiffness rounded down to the grid's best
/// (`tests/tests/haptics.rs` runs the grid).
pub const LATERAL_STIFFNESS_RATIO: f64 = 1.5;

/// The drag of the tissue a plane holds, at contact point `X` (`at`) of a model made
/// with that point at `X₀` (`made_at`), N:
///
/// `f_t = clamp(D min(1, d/d₀) + κ λ (X₀ − X)_⊥,  c λ d)`,  `c = max(1, |D| / (λ d₀))`,
///
/// with `D` the plane's drag at the model's pose, `(·)_⊥` the part orthogonal to `n`,
/// `d` and `d₀` the depths at `X` and `X₀`, `κ` the
/// [`LATERAL_STIFFNESS_RATIO`], and the clamp on the magnitude. At the model's pose
/// it is `D`, so the model gives the elastic reaction there. Moving the instrument
/// sideways pulls back at once with the stiffness `κ λ`, as the held tissue does,
/// rather than at the next model. Withdrawing, the drag fades with the
/// depth and the clamp (a cone about `n` wide enough for `D`) brings the whole to
/// zero continuously as the contact ends. Zero without drag, when not pressed
/// (`d ≤ 0`), and for a plane ahead of a tip that holds nothing (`d₀ ≤ 0`).
fn held_drag(plane: &Plane, made_at: &Point3<f64>, at: &Point3<f64>) -> Vector3<f64> {
    let n = plane.normal.into_inner();
    let depth = (plane.anchor - at).dot(&n);
    let made = (plane.anchor - made_at).dot(&n);
    if depth <= 0.0 || made <= 0.0 || plane.drag == Vector3::zeros() {
        return Vector3::zeros();
    }
    let offset = made_at - at;
    let lateral = offset - n * offset.dot(&n);
    let pull = plane.drag * (depth / made).min(1.0)
        + lateral * (LATERAL_STIFFNESS_RATIO * plane.stiffness);
    let cone = (plane.drag.norm() / (plane.stiffness * made)).max(1.0);
    let cap = cone * plane.stiffness * depth;
    let norm = pull.norm();
    if norm > cap {
        pull * (cap / norm)
    } else {
        pull
    }
}
