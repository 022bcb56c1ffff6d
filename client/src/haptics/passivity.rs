//! Time-domain passivity: the local models never give the hand more energy than it
//! put into them.
//!
//! Each local model is a spring the loop renders at haptic rate, and a passive one
//! (a plane does no work over a closed path). But the model changes at every
//! mechanics tick: a plane whose anchor moves toward the instrument, a contact let go
//! and taken again, a fitted stiffness that changes — each switch can do work on the
//! hand. Resting a 0.15 kg hand on stiff tissue (0.3–3 MPa) with the mechanics at
//! 120 Hz, the held vertex under the tip was let go and taken again every other tick,
//! the anchor moved by 0.1–0.3 mm on a 59 kN/m plane at each model, and the hand kept
//! bouncing at 37 of the 84 targets of `tests/tests/haptics.rs`' grid (8 of 84 at
//! 1 kHz, none at 30 and 60 Hz). With the controller below it gains energy at none
//! of them at 1 kHz (asserted there) and at 8 at 120 Hz, against 6 and 24 without.
//!
//! The cure is Hannaford and Ryu's (2002) passivity observer and controller, on the
//! one port between the device and the environment (the models and the server behind
//! them):
//!
//! - **Observer.** `E_k = Σ_{j ≤ k} −F_{j−1}·(x_j − x_{j−1})`, J: the energy the
//!   environment has absorbed since the contact began. `F_{j−1}` is the force the
//!   device rendered from tick `j − 1` to tick `j` (after the clamp), and `x` the
//!   point of the instrument where it applies, followed as a point of the rigid
//!   instrument (`x = P + s Z` with the same `s` at both ticks), so that a turn about
//!   the trocar counts. A passive environment keeps `E ≥ 0`; what it has stored, it
//!   may give back, and no more.
//! - **Controller.** Before rendering the models' force `F` at tick `k`, the loop
//!   predicts what the environment will have absorbed one tick later if the
//!   instrument keeps its velocity `v_k = (x_k − x_{k−1}) / h`:
//!   `Ê = E_k − F·v_k h`. If `Ê < 0` it renders `F − α v_k` instead, a damper at the
//!   same point with `α = −Ê / (|v_k|² h)`, which brings the prediction back to zero.
//!   Counting the tick's own force, as Hannaford and Ryu's observer does with the
//!   current force and velocity, catches the energy a stiff contact gives back on its
//!   last tick before the contact ends; damping only after the fact, a mass thrown at
//!   a stiff wall left it before the damper could act. `α` is capped at
//!   `α_max = K_max h / 4`, with `K_max` the device's
//!   [`max_stiffness`](super::HapticDevice::max_stiffness): a discrete damper on a
//!   mass `m` is stable while `α h / m < 2`, and a device that renders `K_max`
//!   stably has `K_max ≤ 4 m / h²`, so `α_max h / m ≤ 1`. A device without a
//!   stiffness limit (a script, with no dynamics to destabilise) gets no damper.
//! - **Reset.** While the models give no force the environment stores nothing:
//!   `E = 0`. The energy a contact dissipated (friction, the tissue's damping) does not
//!   license energy made in the next, and free motion is never damped.
//!
//! The damper acts only when the models are about to have made energy, and only as
//! much as they made: a still instrument (`v = 0`) feels nothing of it, so a hand at
//! rest on the tissue feels the models' force exactly. Thrown at a wall of 20 kN/m at
//! 0.2 m/s, a mass leaves it with 1.8 times its energy when the wall's force is held
//! over each tick, and with its own energy (to 5e-6) through the controller
//! (`passivity/tests.rs`).

use nalgebra::{Point3, Unit, Vector3};

/// The passivity observer and controller of one force loop; see the
/// [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct Passivity {
    /// `α_max h⁻¹ = K_max / 4`, N/m (infinite: no damper).
    max_damping_per_period: f64,
    /// `E`, J.
    energy: f64,
    /// What the last tick rendered: haptic time, force (N), the instrument point it
    /// applied at (m), and that point's distance `s` from the tip along the axis.
    last: Option<Rendered>,
    /// Velocity of that point over the last tick, m/s, and the tick's length, s.
    velocity: Vector3<f64>,
    period: f64,
    /// Ticks on which the damper acted.
    damped_ticks: u64,
}

#[derive(Clone, Copy, Debug)]
struct Rendered {
    time: f64,
    force: Vector3<f64>,
    point: Point3<f64>,
    along: f64,
}

impl Passivity {
    /// An observer and controller for a device that renders planes up to
    /// `max_stiffness` N/m stably (infinite: observe only).
    pub fn new(max_stiffness: f64) -> Self {
        Passivity {
            max_damping_per_period: if max_stiffness.is_finite() && max_stiffness > 0.0 {
                0.25 * max_stiffness
            } else {
                f64::INFINITY
            },
            energy: 0.0,
            last: None,
            velocity: Vector3::zeros(),
            period: 0.0,
            damped_ticks: 0,
        }
    }

    /// Observes the instrument at haptic time `t` (s) with tip `tip` and axis `axis`:
    /// adds the energy the environment absorbed over the tick just ended.
    pub fn observe(&mut self, t: f64, tip: &Point3<f64>, axis: &Unit<Vector3<f64>>) {
        let Some(last) = self.last else { return };
        let h = t - last.time;
        let moved = tip + axis.into_inner() * last.along - last.point;
        if !(h > 0.0 && moved.iter().all(|c| c.is_finite())) {
            self.velocity = Vector3::zeros();
            return;
        }
        self.energy -= last.force.dot(&moved);
        self.velocity = moved / h;
        self.period = h;
    }

    /// The force to render for the models' force `force` (N), at the point where it
    /// applies: `force` itself, or with the damper while the environment would make
    /// energy over the coming tick. No force resets the observer.
    pub fn control(&mut self, force: &Vector3<f64>) -> Vector3<f64> {
        if *force == Vector3::zeros() {
            self.energy = 0.0;
            return *force;
        }
        if !self.max_damping_per_period.is_finite() {
            return *force;
        }
        // What the environment will have absorbed after this tick if the instrument
        // keeps its velocity under this force.
        let h = self.period;
        let predicted = self.energy - force.dot(&self.velocity) * h;
        let speed_squared = self.velocity.norm_squared();
        if predicted >= 0.0 || !(speed_squared > 0.0 && h > 0.0) {
            return *force;
        }
        let alpha = (-predicted / (speed_squared * h)).min(self.max_damping_per_period * h);
        self.damped_ticks += 1;
        force - self.velocity * alpha
    }

    /// Records what the device rendered at haptic time `t`: `force` (N, after the
    /// clamp) at `point` (m), `along` m from the tip along the axis.
    pub fn rendered(&mut self, t: f64, force: Vector3<f64>, point: Point3<f64>, along: f64) {
        self.last = Some(Rendered {
            time: t,
            force,
            point,
            along,
        });
    }

    /// `E`, J: the energy the environment has absorbed since the contact began.
    pub fn energy(&self) -> f64 {
        self.energy
    }

    /// Ticks on which the damper acted.
    pub fn damped_ticks(&self) -> u64 {
        self.damped_ticks
    }
}

#[cfg(test)]
mod tests;
