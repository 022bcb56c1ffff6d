//! Static equilibrium: `K u = M g` with the imposed displacements.
//!
//! Solved by conjugate gradient on the free vertices, warm-started from the current
//! displacement. The stopping rule is relative to the size of the loads,
//! `‖r_f‖ ≤ tol · (‖(M g)_f‖ + ‖(K u_c)_f‖)`, where `u_c` is the imposed displacement
//! alone (zero on free vertices): the gravity load plus the load the supports and
//! instruments put on the free vertices. `K` is positive definite on the free vertices
//! only if the imposed ones remove every rigid motion (three non-collinear vertices);
//! scenes are checked for that before a static solve.

use nalgebra::Vector3;

use super::cg::{Stop, free_norm};
use super::{Imposed, Integrator, State, StepReport};
use crate::engine::elastic::ElasticModel;

pub(super) fn solve(
    it: &mut Integrator,
    model: &ElasticModel,
    state: &mut State,
    imposed: &Imposed,
    gravity: Vector3<f64>,
) -> StepReport {
    let k = &model.stiffness;
    for i in 0..model.vertex_count() {
        it.cg.precond[i] = k.block[k.diag[i] as usize]
            .try_inverse()
            .unwrap_or_else(nalgebra::Matrix3::identity);
    }
    it.preconditioned_for = f64::NAN;
    let mask = imposed.mask();
    // Imposed displacement alone, for the load reference.
    for i in 0..model.vertex_count() {
        it.u[i] = if mask[i] {
            imposed.target(i) - model.rest[i]
        } else {
            Vector3::zeros()
        };
    }
    k.mul(&it.u, &mut it.f);
    let support_load = free_norm(&it.f, mask);
    for i in 0..model.vertex_count() {
        it.f[i] = model.mass[i] * gravity;
        if !mask[i] {
            it.u[i] = state.x[i] - model.rest[i];
        }
    }
    let reference = free_norm(&it.f, mask) + support_load;
    let report = it.cg.solve(
        |p, out| k.mul(p, out),
        mask,
        &it.f,
        &mut it.u,
        Stop {
            reference,
            tolerance: it.config.cg_tolerance,
            max_iterations: it.config.cg_max_iterations,
        },
    );
    for i in 0..model.vertex_count() {
        state.x[i] = model.rest[i] + it.u[i];
        state.v[i] = Vector3::zeros();
    }
    StepReport {
        substeps: 1,
        cg_iterations: report.iterations,
        relative_residual: report.relative_residual,
        converged: report.converged,
    }
}
