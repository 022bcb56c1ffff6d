//! Static equilibrium: `K u = M g` with the imposed displacements.
//!
//! Solved by conjugate gradient on the free vertices, warm-started from the current
//! displacement. The stopping rule is relative to the size of the loads,
//! `‖r_f‖ ≤ tol · (‖(M g)_f‖ + ‖(K u_c)_f‖)`, where `u_c` is the imposed displacement
//! alone (zero on free vertices): the gravity load plus the load the supports and
//! instruments put on the free vertices. `K` is positive definite on the free vertices
//! only if the imposed ones remove every rigid motion (three non-collinear vertices);
//! scenes are checked for that before a static solve.
//!
//! Corotational: the equilibrium `Σ_e R_e K_e (R_eᵀ x_e − X_e) = M g` is nonlinear in
//! `x` through the rotations. It is reached by fixed-point ("lagged rotation")
//! iterations: extract the rotations at the current `x`, solve the linear system
//! `K̂ u = M g − o` they define, repeat. The forces derive from an energy (see
//! [`corotational`](crate::engine::elastic::corotational)), so a fixed point is an
//! equilibrium. The iterations stop when the true nonlinear residual
//! `‖(M g − K̂ u − o)_f‖`, with the rotations of the current `x`, meets the same
//! tolerance as the linear solve, or after [`MAX_ROTATION_UPDATES`], or when the CG
//! iterations of all its linear solves together reach the tick-work bound's cap for
//! the mesh ([`max_cg_iterations`]: the scene's `cg_max_iterations` bounds each
//! solve, and a thousand solves at that cap would have been a thousand times the
//! bound; liver-5k at E = 1 Pa under 1000 g ran one static tick of 141,153
//! iterations, 74 s). Each tick of the static integrator starts from the last
//! equilibrium, so a tick whose loads have not changed costs one rotation update
//! and no CG iteration. Each linear solve stops at
//! a tenth of the current nonlinear residual (or the tolerance, when tighter): an
//! inexact fixed-point iteration, since solving exactly for rotations about to
//! change buys nothing.
//!
//! Written as a correction, each iteration is `K̂ Δu = M g − f(x)`: a Newton step
//! whose tangent `K̂` holds nothing of the energy's twist modes (see
//! [`twist_tangent`]). Where elements are strongly deformed that tangent is too
//! soft along them and the iteration overshoots: the default liver at E = 300 Pa,
//! sagging 10 cm under its own weight, cycled and ended 1,000 updates at a relative
//! residual of 1.8. So, as the implicit step does, the solve adds the positive
//! twists of the elements whose twist may pass a tenth of `λ + 2μ`: the system is
//! `(K̂ + K_tw) u = M g − o + K_tw u₀`, the same correction with the projected
//! Hessian. That liver then meets 1e-8 in 283 updates; the default at 1 kPa and
//! 600 Pa took 47 and 84 updates without and 52 and 86 with, liver-5k at 1 kPa 41
//! and 32, SOFA's liver demo 18 either way.
//!
//! [`max_cg_iterations`]: crate::engine::scene::limits::max_cg_iterations
//! [`twist_tangent`]: crate::engine::elastic::twist_tangent

use nalgebra::Vector3;

use super::cg::{Stop, free_norm};
use super::{Imposed, Integrator, SolveLimit, State, StepReport};
use crate::engine::elastic::ElasticModel;

/// Cap on the rotation updates of one corotational static solve. The fixed-point
/// iteration converges linearly, at a rate set by how much the rotations change
/// with the load: SOFA's liver demo, sagging by 7% of its size, meets 1e-10 in 18;
/// liver-5k held as the default scene at 1 kPa (a 2.6 cm sag) 1e-6 in 32; the
/// default liver at 300 Pa (10 cm) 1e-8 in 283 (see the module notes). Each update
/// solves its linear system only as far as the nonlinear residual warrants (see
/// [`solve`]), so most cost a few CG iterations.
pub const MAX_ROTATION_UPDATES: u32 = 1000;

pub(super) fn solve(
    it: &mut Integrator,
    model: &ElasticModel,
    state: &mut State,
    imposed: &Imposed,
    gravity: Vector3<f64>,
) -> StepReport {
    let mask = imposed.mask();
    // Imposed displacement alone, for the load reference (with the rest stiffness:
    // it only measures the size of the loads).
    for i in 0..model.vertex_count() {
        it.u[i] = if mask[i] {
            imposed.target(i) - model.rest[i]
        } else {
            Vector3::zeros()
        };
    }
    model.stiffness.mul(&it.u, &mut it.f);
    let support_load = free_norm(&it.f, mask);
    for i in 0..model.vertex_count() {
        it.f[i] = model.mass[i] * gravity;
        if mask[i] {
            state.x[i] = imposed.target(i);
        } else {
            it.u[i] = state.x[i] - model.rest[i];
        }
    }
    let reference = free_norm(&it.f, mask) + support_load;
    let stop = Stop {
        reference,
        tolerance: it.config.cg_tolerance,
        max_iterations: it.config.cg_max_iterations,
    };
    it.preconditioned_for = f64::NAN;
    it.select_preconditioner(model, mask, 0.0, 1.0);
    let mut report = StepReport {
        substeps: 1,
        cg_iterations: 0,
        relative_residual: 0.0,
        converged: false,
        stopped_by: None,
    };
    let updates = if it.corotated.is_some() {
        MAX_ROTATION_UPDATES
    } else {
        1
    };
    // The CG iterations of all the updates together stay within the tick-work
    // bound: the most a mesh of this size may be given for one tick.
    let budget = it.static_budget;
    for _ in 0..updates {
        let mut inner = stop;
        inner.max_iterations = inner
            .max_iterations
            .min(budget.saturating_sub(report.cg_iterations));
        // b = M g (linear) or M g − o + K_tw u (corotational, with the rotations
        // of x).
        let (k, twist) = match &mut it.corotated {
            Some(c) => {
                c.update(model, &state.x, &mut it.w);
                // o = f₀ − K̂ u₀, with K̂ u₀ in f (u holds x − X throughout).
                c.tangent.mul(&it.u, &mut it.f);
                let mut residual = 0.0;
                for i in 0..model.vertex_count() {
                    let load = model.mass[i] * gravity;
                    it.f[i] = load - (it.w[i] - it.f[i]);
                    if !mask[i] {
                        residual += (load - it.w[i]).norm_squared();
                    }
                }
                let relative = if reference > 0.0 {
                    residual.sqrt() / reference
                } else {
                    0.0
                };
                report.relative_residual = relative;
                if relative <= it.config.cg_tolerance {
                    report.converged = true;
                    break;
                }
                inner.tolerance = stop.tolerance.max(0.1 * relative);
                // The twists' share of the right-hand side, K_tw u₀.
                c.update_twist(model);
                c.twist().mul_add(1.0, &it.u, &mut it.f);
                (&c.tangent, Some(c.twist()))
            }
            None => (&model.stiffness, None),
        };
        // Checked after the rotation update, not before it: the report then holds
        // the nonlinear residual of the state the solve returns.
        if it.interrupt.is_raised() {
            report.stopped_by = Some(SolveLimit::Interrupted);
            break;
        }
        if inner.max_iterations == 0 {
            report.stopped_by = Some(SolveLimit::Budget);
            break;
        }
        for i in 0..model.vertex_count() {
            it.cg.precond[i] = k.block[k.diag[i] as usize]
                .try_inverse()
                .unwrap_or_else(nalgebra::Matrix3::identity);
        }
        let cg = it.cg.solve(
            |p, out| {
                k.mul(p, out);
                if let Some(twist) = twist {
                    twist.mul_add(1.0, p, out);
                }
            },
            mask,
            &it.f,
            &mut it.u,
            inner,
        );
        report.cg_iterations += cg.iterations;
        if it.corotated.is_none() {
            report.relative_residual = cg.relative_residual;
        }
        report.converged = cg.converged;
        for i in 0..model.vertex_count() {
            state.x[i] = model.rest[i] + it.u[i];
        }
        if !cg.converged {
            report.stopped_by = Some(if it.interrupt.is_raised() {
                SolveLimit::Interrupted
            } else if inner.max_iterations < stop.max_iterations {
                SolveLimit::Budget
            } else {
                SolveLimit::Iterations
            });
            break;
        }
        // A corotational solve loops back to check the residual at the new x.
        report.converged = it.corotated.is_none();
    }
    if !report.converged && report.stopped_by.is_none() {
        report.stopped_by = Some(SolveLimit::RotationUpdates);
    }
    for v in &mut state.v {
        *v = Vector3::zeros();
    }
    report
}
