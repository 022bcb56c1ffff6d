//! Energies, for stability checks and reports.

use nalgebra::Vector3;

use super::State;
use crate::engine::elastic::ElasticModel;

/// Kinetic energy `½ Σ m_i |v_i|²`, J.
pub fn kinetic_energy(model: &ElasticModel, state: &State) -> f64 {
    state
        .v
        .iter()
        .zip(&model.mass)
        .map(|(v, m)| 0.5 * m * v.norm_squared())
        .sum()
}

/// Total mechanical energy under uniform gravity `g`:
/// `½ Σ m_i |v_i|² + W(x) − Σ m_i g · u_i` (J), with `W` the strain energy of the
/// model (`½ uᵀ K u` when linear),, zero at rest in the reference
/// configuration. With damping and fixed supports it can only decrease over time in
/// the exact dynamics; the static equilibrium is its minimum.
pub fn mechanical_energy(model: &ElasticModel, state: &State, gravity: Vector3<f64>) -> f64 {
    let gravity_work: f64 = state
        .x
        .iter()
        .zip(&model.rest)
        .zip(&model.mass)
        .map(|((x, r), m)| m * gravity.dot(&(x - r)))
        .sum();
    kinetic_energy(model, state) + model.strain_energy_at(&state.x) - gravity_work
}
