//! A simulated hand holding the instrument: a point mass on a spring-damper toward a
//! scripted target, pushed back by the rendered force.

use nalgebra::{Point3, Unit, Vector3};

use super::{HapticDevice, Trajectory};
use crate::proto::force::DeviceForce;

/// The hand model's parameters, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandParams {
    /// Mass `m` of hand and device handle moved together, kg.
    pub mass: f64,
    /// Stiffness `k_h` of the pull toward the target, N/m.
    pub stiffness: f64,
    /// Damping `c_h` of the hand, N·s/m.
    pub damping: f64,
    /// The largest force the device renders, N.
    pub max_force: f64,
    /// The stiffest plane the device renders, N/m (see
    /// [`HapticDevice::max_stiffness`]).
    pub max_stiffness: f64,
}

impl Default for HandParams {
    /// A light grip on a desktop device: 0.15 kg, 200 N/m, 5 N·s/m (damping ratio
    /// about 0.46), 10 N, and planes up to 200 kN/m: the mass on a wall of stiffness
    /// λ, stepped at 1 kHz by the scheme below, is stable while λ < 4m/T² = 600 kN/m;
    /// a third of that leaves a margin.
    fn default() -> Self {
        HandParams {
            mass: 0.15,
            stiffness: 200.0,
            damping: 5.0,
            max_force: 10.0,
            max_stiffness: 200_000.0,
        }
    }
}

/// A hand holding the instrument.
///
/// The instrument tip `x` (m) is a point mass `m` pulled toward the tip of a scripted
/// target pose by a spring `k_h` with damping `c_h`, and pushed by the rendered force
/// `F`. Its axis points from the tip toward the fixed trocar the instrument pivots
/// about. Each [`render`](HapticDevice::render) at time `t` advances the hand by
/// `h = t − t_prev` (nothing on the first call), with `F` held over the step and the
/// spring taken at the current position (semi-implicit, symplectic Euler) and the
/// damping at the step's mean velocity:
///
/// ```text
/// m (v' − v) = h (k_h (x_t − x) + F) − h c_h (v + v')/2,     x' = x + h v'
/// ```
///
/// Energy bookkeeping (J): [`kinetic_energy`](Self::kinetic_energy) `½ m |v|²`,
/// [`spring_energy`](Self::spring_energy) `½ k_h |x − x_t|²`,
/// [`force_work`](Self::force_work) `∫ F·v dt` (the work of the rendered force on the
/// hand, summed as `h F·(v + v')/2`), [`damping_loss`](Self::damping_loss)
/// `∫ c_h |v|² dt` (summed as `h c_h |(v + v')/2|²`). With a fixed target and a
/// constant step, the scheme's own energy
/// [`discrete_energy`](Self::discrete_energy)
/// `E = ½ m |v|² + ½ k_h (x₋ − x_t)·(x − x_t)` (`x₋` the position one step back)
/// satisfies exactly `E' − E = h F·(v + v')/2 − h c_h |(v + v')/2|²`: multiply the
/// update by `(v + v')/2` and use `h v = x − x₋`, `h v' = x' − x`. So with no rendered
/// force the energy never grows, and any growth of `E` is work the force loop put
/// into the hand. `E` is the true energy up to `−½ k_h h v·(x − x_t)`, and positive
/// definite while `h² k_h / m < 4`.
pub struct HandDevice {
    params: HandParams,
    trocar: Point3<f64>,
    target: Trajectory,
    target_tip: Point3<f64>,
    x: Point3<f64>,
    x_back: Point3<f64>,
    v: Vector3<f64>,
    axis: Unit<Vector3<f64>>,
    t_prev: Option<f64>,
    force_work: f64,
    damping_loss: f64,
}

impl HandDevice {
    /// A hand at rest with the tip at `start`, pulled toward the tip of `target`, the
    /// instrument pivoting about `trocar`.
    pub fn new(
        params: HandParams,
        trocar: Point3<f64>,
        start: Point3<f64>,
        target: Trajectory,
    ) -> Self {
        let axis = Unit::try_new(trocar - start, 1e-12).unwrap_or_else(Vector3::z_axis);
        let target_tip = target(0.0).0;
        HandDevice {
            params,
            trocar,
            target,
            target_tip,
            x: start,
            x_back: start,
            v: Vector3::zeros(),
            axis,
            t_prev: None,
            force_work: 0.0,
            damping_loss: 0.0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &HandParams {
        &self.params
    }

    /// The instrument tip, m.
    pub fn tip(&self) -> Point3<f64> {
        self.x
    }

    /// The tip's velocity, m/s.
    pub fn velocity(&self) -> Vector3<f64> {
        self.v
    }

    /// The target tip at the last step, m.
    pub fn target_tip(&self) -> Point3<f64> {
        self.target_tip
    }

    /// `½ m |v|²`, J.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.params.mass * self.v.norm_squared()
    }

    /// `½ k_h |x − x_t|²` toward the target of the last step, J.
    pub fn spring_energy(&self) -> f64 {
        0.5 * self.params.stiffness * (self.x - self.target_tip).norm_squared()
    }

    /// The scheme's energy `½ m |v|² + ½ k_h (x₋ − x_t)·(x − x_t)`, J; see the type's
    /// documentation.
    pub fn discrete_energy(&self) -> f64 {
        self.kinetic_energy()
            + 0.5
                * self.params.stiffness
                * (self.x_back - self.target_tip).dot(&(self.x - self.target_tip))
    }

    /// Cumulative work of the rendered force on the hand, `∫ F·v dt`, J.
    pub fn force_work(&self) -> f64 {
        self.force_work
    }

    /// Cumulative energy the hand's damping dissipated, `∫ c_h |v|² dt`, J.
    pub fn damping_loss(&self) -> f64 {
        self.damping_loss
    }
}

impl HapticDevice for HandDevice {
    fn pose(&mut self, _t: f64) -> (Point3<f64>, Unit<Vector3<f64>>) {
        (self.x, self.axis)
    }

    fn render(&mut self, t: f64, force: &DeviceForce) {
        let h = match self.t_prev.replace(t) {
            Some(prev) if t > prev => t - prev,
            _ => return,
        };
        let HandParams {
            mass: m,
            stiffness: k,
            damping: c,
            ..
        } = self.params;
        self.target_tip = (self.target)(t).0;
        let pull = (self.target_tip - self.x) * k + force.force;
        let v_new = (self.v * (m - 0.5 * h * c) + pull * h) / (m + 0.5 * h * c);
        let v_mean = (self.v + v_new) * 0.5;
        self.force_work += h * force.force.dot(&v_mean);
        self.damping_loss += h * c * v_mean.norm_squared();
        self.x_back = self.x;
        self.x += v_new * h;
        self.v = v_new;
        if let Some(axis) = Unit::try_new(self.trocar - self.x, 1e-12) {
            self.axis = axis;
        }
    }

    fn max_force(&self) -> f64 {
        self.params.max_force
    }

    fn max_stiffness(&self) -> f64 {
        self.params.max_stiffness
    }
}

impl std::fmt::Debug for HandDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HandDevice")
            .field("params", &self.params)
            .field("trocar", &self.trocar)
            .field("tip", &self.x)
            .field("velocity", &self.v)
            .finish_non_exhaustive()
    }
}
