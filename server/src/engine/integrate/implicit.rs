//! Implicit integration: backward Euler, solved by conjugate gradient.
//!
//! With `u = x − X`, damping `C = α M` and elastic force `−K u`, one step of length `h`
//! is `M (v₁ − v₀) = h (M g − K u₁ − α M v₁)`, `u₁ = u₀ + h v₁`, that is
//!
//! `((1 + hα) M + h² K) v₁ = M v₀ + h (M g − K u₀)`.
//!
//! Corotational: the rotations `R_e` are extracted at `x₀` and frozen over the tick,
//! so the elastic force is affine, `−(K̂ u + o)` (see
//! [`corotational`](crate::engine::elastic::corotational)), and the step is the same
//! with `K` replaced by `K̂ = Σ_e R_e K_e R_eᵀ` and `K u₀` by `K̂ u₀ + o`, the exact
//! force at `x₀`. `K̂` is symmetric positive semi-definite like `K`, so the step keeps
//! its unconditional stability; the lag of the rotations by one tick is first order in
//! the tick's rotation increment and vanishes at rest.
//!
//! `K̂` holds nothing of the energy's twist modes, whose stiffness grows without bound
//! in an element pressed through its flat state; there the frozen step overshot and
//! the tissue cycled with period two (two instruments crossing deep in the liver,
//! held still: 8.2 ↔ 8.9 N on alternate ticks). The products therefore add the
//! positive twists of the strongly deformed elements,
//! [`TwistTangent`](crate::engine::elastic::twist_tangent::TwistTangent): the step is
//! then one Newton step of backward Euler on the energy's Hessian with its negative
//! twists set to zero, still symmetric positive definite. The preconditioner's
//! diagonal blocks leave them out (any symmetric positive definite preconditioner
//! serves).
//!
//! The matrix is symmetric positive definite for any `h > 0`, so the step is
//! unconditionally stable and dissipative: stiff tissue and long ticks only cost CG
//! iterations. Imposed vertices get `v₁ = (target − x₀)/h`, which lands them exactly on
//! their targets. The solve is warm-started from `v₀`. (Extrapolating `2v₀ − v₋₁` was
//! tried: it saves a few iterations in a smooth transient but amplifies solver noise
//! near rest, where it cost liver-20k 1.8× the tick time; `v₀` is better overall.)
//!
//! The products read the blocks of `K` (or `K̂`) in the precision the scene's
//! `[mechanics] stiffness` gives ([`StiffnessStorage`](super::StiffnessStorage));
//! everything else, the preconditioner's diagonal blocks and the reactions
//! included, reads them in f64.
//!
//! Stopping rule: `‖r_f‖ ≤ tol · (‖M v₀‖ + h‖M g‖ + h‖K u₀‖ + ‖h² K_fc v_c‖)` over free
//! vertices — the residual is small against the momenta and impulses that form the
//! right-hand side (the last term is the push of moving imposed vertices), which stays
//! meaningful at equilibrium where those terms cancel.

use nalgebra::{Matrix3, Vector3};

use super::cg::{Stop, free_norm};
use super::{Imposed, Integrator, SolveLimit, State, StepReport};
use crate::engine::elastic::ElasticModel;
use crate::engine::workers::{Disjoint, share};

pub(super) fn step(
    it: &mut Integrator,
    model: &ElasticModel,
    state: &mut State,
    imposed: &Imposed,
    gravity: Vector3<f64>,
    h: f64,
) -> StepReport {
    let alpha = it.config.damping;
    let mass_factor = 1.0 + h * alpha;
    it.select_preconditioner(model, imposed.mask(), mass_factor, h * h);
    // f = K u₀ (linear), or f = K̂ u₀ + o with the rotations of x₀, which then stay
    // frozen over the tick: K is K̂ below, and K̂ changes every tick.
    let corotational = it.corotated.is_some();
    let (k, twist) = match &mut it.corotated {
        Some(c) => {
            c.update_shared(
                model,
                &state.x,
                &mut it.f,
                it.tangent_turn,
                it.workers.as_ref(),
            );
            c.update_twist(model);
            (&c.tangent, Some(c.twist()))
        }
        None => {
            state.displacement_into(model, &mut it.u);
            model.stiffness.mul(&it.u, &mut it.f);
            (&model.stiffness, None)
        }
    };
    let (workers, parts) = (it.workers.as_ref(), &it.parts);
    if corotational || it.preconditioned_for != h {
        let precond = Disjoint::new(&mut it.cg.precond);
        share(workers, parts.count(), &|t| {
            let rows = parts.range(t);
            // SAFETY: each part writes its own range.
            let precond = unsafe { precond.range(rows.clone()) };
            for (p, i) in precond.iter_mut().zip(rows) {
                let a_ii = Matrix3::identity() * (mass_factor * model.mass[i])
                    + h * h * k.block[k.diag[i] as usize];
                *p = a_ii.try_inverse().unwrap_or_else(Matrix3::identity);
            }
        });
        it.preconditioned_for = if corotational { f64::NAN } else { h };
    }
    // f = b = M v₀ + h (M g − K u₀).
    let mask = imposed.mask();
    let (mut momentum, mut weight, mut elastic) = (0.0, 0.0, 0.0);
    for i in 0..it.f.len() {
        let m = model.mass[i];
        let ku = it.f[i];
        it.f[i] = m * state.v[i] + h * (m * gravity - ku);
        if !mask[i] {
            momentum += (m * state.v[i]).norm_squared();
            weight += (m * gravity).norm_squared();
            elastic += ku.norm_squared();
        }
    }
    for &i in imposed.list() {
        let i = i as usize;
        state.v[i] = (imposed.target(i) - state.x[i]) / h;
    }
    // The load the moving imposed vertices put on the free ones, h² K_fc v_c, gathered
    // from the imposed rows (K is symmetric, K_jc = K_cjᵀ): zero for fixed supports.
    it.w.iter_mut().for_each(|w| *w = Vector3::zeros());
    for &c in imposed.list() {
        let c = c as usize;
        if state.v[c] == Vector3::zeros() {
            continue;
        }
        let vc = state.v[c];
        let w = &mut it.w;
        k.for_each_in_row(c, |j, k_cj| w[j] += h * h * k_cj.tr_mul(&vc));
    }
    let reference = momentum.sqrt() + h * (weight.sqrt() + elastic.sqrt()) + free_norm(&it.w, mask);
    if corotational && !it.blocks32.is_empty() {
        k.round_f32_shared(workers, parts, &mut it.blocks32);
    }
    let blocks32 = &it.blocks32;
    let apply = |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
        let a = |i| mass_factor * model.mass[i];
        if blocks32.is_empty() {
            k.mul_shared(workers, parts, a, h * h, p, out);
        } else {
            k.mul_shared_by(blocks32, workers, parts, a, h * h, p, out);
        }
        if let Some(twist) = twist {
            twist.mul_add(h * h, p, out);
        }
    };
    let report = it.cg.solve_shared(
        workers,
        apply,
        mask,
        &it.f,
        &mut state.v,
        Stop {
            reference,
            tolerance: it.config.cg_tolerance,
            max_iterations: it.config.cg_max_iterations,
        },
    );
    for i in 0..state.x.len() {
        if imposed.is_imposed(i) {
            state.x[i] = imposed.target(i);
        } else {
            state.x[i] += h * state.v[i];
        }
    }
    StepReport {
        substeps: 1,
        cg_iterations: report.iterations,
        relative_residual: report.relative_residual,
        converged: report.converged,
        stopped_by: (!report.converged).then(|| {
            if it.interrupt.is_raised() {
                SolveLimit::Interrupted
            } else {
                SolveLimit::Iterations
            }
        }),
    }
}
