//! Progressive transitions between successive local models.
//!
//! The paper (§3) renders forces at haptic rate from the newest local model and makes
//! "transitions between two successive local models … progressively": the server
//! sends a model every mechanics tick (30–120 Hz), the force loop evaluates it about
//! a thousand times a second, and a model that simply replaced the previous one would
//! make the force jump at every arrival. [`Blender`] blends them instead.
//!
//! With `x` the device pose (tip `P`, axis `Z`), `F_prev` and `F_cur` the forces of the
//! previous and current models at `x`, `t_a` the haptic time the current model
//! arrived and `τ` the transition time:
//!
//! ```text
//! F(t, x) = (1 − w)(F_prev(x) + Δ) + w F_cur(x),
//! w = smoothstep(clamp((t − t_a)/τ, 0, 1)),   smoothstep(s) = 3s² − 2s³
//! ```
//!
//! `smoothstep` is C¹ with slope 0 at both ends and at most 1.5 (at `s = ½`), so a
//! transition neither starts nor ends with a kink, and over one haptic tick `dt` the
//! weight moves by at most `1.5 dt/τ`.
//!
//! When a model arrives at time `t`, with the device at `x`:
//! `prev := cur`, `cur := new`, `t_a := t`, and
//! `Δ := F(t⁻, x) − F_prev(x)`: the force rendered just before the switch minus the
//! force of the model that just became the previous one. At `w = 0` the output is
//! therefore exactly what it was just before the switch, so an arrival never makes the
//! force jump, even in the middle of a transition (when `F(t⁻, x)` is itself a blend).
//! `Δ` is zero when the previous transition had finished, and it fades out with
//! `1 − w`: after `τ` the output is exactly the new model's force.
//!
//! The point where the force applies is blended the same way, as an abscissa along the
//! axis: each model's point is `P + s Z` ([`LocalModel::force`] puts it on the axis),
//! and `s = (1 − w)(s_prev + δs) + w s_cur`, with `δs` taken at the switch like `Δ`.
//! The point stays on the instrument and the torque about the trocar is as continuous
//! as the force.
//!
//! Before any model has arrived the force is zero; the first model blends in from
//! zero over `τ`, as if the previous model had been "no contact".

use nalgebra::{Point3, Unit, Vector3};

use crate::proto::force::{AppliedForce, LocalModel};

/// The smoothstep weight `3s² − 2s³` of `s` clamped to `[0, 1]`.
pub fn smoothstep(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

/// The largest slope of [`smoothstep`], reached at `s = ½`.
pub const SMOOTHSTEP_MAX_SLOPE: f64 = 1.5;

/// Blends the previous and the current local model over a transition time; see the
/// [module documentation](self).
#[derive(Clone, Debug)]
pub struct Blender {
    transition_s: f64,
    prev: Option<LocalModel>,
    cur: Option<LocalModel>,
    arrival: f64,
    delta: Vector3<f64>,
    delta_s: f64,
}

impl Blender {
    /// A blender with transition time `transition_s` (s, finite and positive; the
    /// force loop's configuration checks it) and no model yet.
    pub fn new(transition_s: f64) -> Self {
        Blender {
            transition_s,
            prev: None,
            cur: None,
            arrival: 0.0,
            delta: Vector3::zeros(),
            delta_s: 0.0,
        }
    }

    /// The transition time `τ`, s.
    pub fn transition_s(&self) -> f64 {
        self.transition_s
    }

    /// The current (newest) model, if any has arrived.
    pub fn current(&self) -> Option<&LocalModel> {
        self.cur.as_ref()
    }

    /// The previous model, the one being blended out.
    pub fn previous(&self) -> Option<&LocalModel> {
        self.prev.as_ref()
    }

    /// Haptic time the current model arrived, s; `None` before any model.
    pub fn arrival_time(&self) -> Option<f64> {
        self.cur.map(|_| self.arrival)
    }

    /// The weight `w` of the current model at haptic time `t`.
    pub fn weight(&self, t: f64) -> f64 {
        smoothstep((t - self.arrival) / self.transition_s)
    }

    /// Takes `model` as the current model at haptic time `t`, with the device at tip
    /// `tip` and axis `axis` (the pose the force is evaluated at in the same tick).
    /// The force at `(t, tip, axis)` is the same just before and just after.
    pub fn arrive(
        &mut self,
        t: f64,
        model: LocalModel,
        tip: &Point3<f64>,
        axis: &Unit<Vector3<f64>>,
    ) {
        let before = self.force(t, tip, axis);
        let s_before = (before.point - tip).dot(axis);
        self.prev = self.cur.take();
        let (f_prev, s_prev) = evaluate(self.prev.as_ref(), tip, axis);
        self.delta = before.force - f_prev;
        self.delta_s = s_before - s_prev;
        self.cur = Some(model);
        self.arrival = t;
    }

    /// The blended force on the instrument at haptic time `t` and device pose
    /// `(tip, axis)`, and the point of the axis where it applies. No allocation.
    pub fn force(&self, t: f64, tip: &Point3<f64>, axis: &Unit<Vector3<f64>>) -> AppliedForce {
        let Some(cur) = &self.cur else {
            return AppliedForce {
                force: Vector3::zeros(),
                point: *tip,
            };
        };
        let w = self.weight(t);
        if w >= 1.0 {
            return cur.force(tip, axis);
        }
        let (f_cur, s_cur) = evaluate(Some(cur), tip, axis);
        let (f_prev, s_prev) = evaluate(self.prev.as_ref(), tip, axis);
        let force = (f_prev + self.delta) * (1.0 - w) + f_cur * w;
        let s = (1.0 - w) * (s_prev + self.delta_s) + w * s_cur;
        AppliedForce {
            force,
            point: tip + axis.into_inner() * s,
        }
    }
}

/// A model's force at the pose and the abscissa of its point along the axis; zero
/// force at the tip without a model.
fn evaluate(
    model: Option<&LocalModel>,
    tip: &Point3<f64>,
    axis: &Unit<Vector3<f64>>,
) -> (Vector3<f64>, f64) {
    match model {
        Some(m) => {
            let applied = m.force(tip, axis);
            (applied.force, (applied.point - tip).dot(axis))
        }
        None => (Vector3::zeros(), 0.0),
    }
}

#[cfg(test)]
mod tests;
