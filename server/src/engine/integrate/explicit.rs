//! Explicit integration: symplectic (semi-implicit) Euler with automatic substeps.
//!
//! Each substep of length `h`:
//!
//! `v ← (v + h (g + f_i/m_i)) / (1 + h α)`,  `x ← x + h v`,  with `f = −K u`
//! (linear) or `f = −Σ_e R_e K_e (R_eᵀ x_e − X_e)` with the rotations extracted at the
//! start of every substep (corotational): the exact force of the corotated energy, so
//! symplectic Euler keeps its bounded shadow energy. (Freezing the rotations over a
//! tick, as the implicit step must, was tried: it saves the extraction per substep but
//! the one-tick lag of the rotations then slows the settling of a soft, strongly
//! sagging liver, 0.8% off its equilibrium after 1.5 s at 1 kPa and 50 Hz.)
//!
//! The damping term is taken implicitly (the division), so it never limits `h`; the
//! elastic term is stable for `h ω_max < 2`. The substep count is chosen per tick from
//! the bound `ω̂ ≥ ω_max` of the mesh and material (for the corotational model, one
//! that holds for the rotated stiffness `R K Rᵀ` at every rotation), so no Young's modulus,
//! Poisson ratio or tick length can make it blow up: a stiffer material simply takes
//! more substeps. Imposed vertices move linearly from where they are to their target
//! over the tick.
//!
//! That bound is the linear stiffness's, and the corotational force's Jacobian also
//! has the turning of the rotations, whose twist stiffness passes it in elements
//! pressed through their flat state (see [`twist`](crate::engine::elastic::twist)).
//! So at the start of each tick the substep count is multiplied by `√ρ`, `ρ` the
//! largest twist ratio of the elements there (1 when no element passes the bound, the
//! usual case), up to [`MAX_TWIST_FACTOR`] and within the tick-work bound.
//!
//! The interrupt flag is read before each substep: a closing session stops within one
//! substep, leaving the state partway through the tick.

use nalgebra::Vector3;

use super::{Imposed, Integrator, State, StepReport};
use crate::engine::elastic::ElasticModel;
use crate::engine::scene::limits::MAX_TICK_WORK;

/// Most the twist of inverted elements multiplies a tick's substeps by, where two
/// stretches of an element sum to nearly zero and the twist stiffness has no bound;
/// the count also stays within the tick-work bound [`MAX_TICK_WORK`], as the scene's
/// own does. Such a tick takes up to 16 ticks' time. The 6.5 cm press at 1 m/s of
/// `tests/explicit_inversion.rs` reaches the bound (3,520 substeps where the scene's
/// are 220).
pub const MAX_TWIST_FACTOR: f64 = 16.0;

pub(super) fn step(
    it: &mut Integrator,
    model: &ElasticModel,
    state: &mut State,
    imposed: &Imposed,
    gravity: Vector3<f64>,
    dt: f64,
) -> StepReport {
    let twist = match &mut it.corotated {
        Some(c) => c.twist_ratio(model, &state.x).max(1.0).sqrt(),
        None => 1.0,
    };
    let scene = it.explicit_substeps(dt);
    // The scene keeps its own count within the tick-work bound; the twist's extra
    // substeps stay within it too.
    let most = (MAX_TICK_WORK / state.x.len().max(1) as f64).floor();
    let substeps = (f64::from(scene) * twist.min(MAX_TWIST_FACTOR))
        .ceil()
        .min(most)
        .max(f64::from(scene)) as u32;
    let h = dt / substeps as f64;
    let damp = 1.0 / (1.0 + h * it.config.damping);
    for &i in imposed.list() {
        let i = i as usize;
        it.start[i] = state.x[i];
        state.v[i] = (imposed.target(i) - state.x[i]) / dt;
    }
    let mut taken = substeps;
    for s in 1..=substeps {
        if it.interrupt.is_raised() {
            taken = s - 1;
            break;
        }
        it.exact_negated_elastic_force(model, &state.x);
        for i in 0..state.x.len() {
            if imposed.is_imposed(i) {
                continue;
            }
            let f = -it.f[i];
            let v = (state.v[i] + h * (gravity + f / model.mass[i])) * damp;
            state.v[i] = v;
            state.x[i] += h * v;
        }
        let frac = s as f64 / substeps as f64;
        for &i in imposed.list() {
            let i = i as usize;
            state.x[i] = it.start[i] + (imposed.target(i) - it.start[i]) * frac;
        }
    }
    // The reaction reads K̂ and o: assemble them with the rotations of the end state.
    it.freeze_rotations(model, &state.x);
    StepReport {
        substeps: taken,
        cg_iterations: 0,
        relative_residual: 0.0,
        converged: true,
        stopped_by: None,
    }
}
