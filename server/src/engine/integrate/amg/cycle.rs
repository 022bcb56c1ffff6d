//! The V-cycle: `z = B r`, one application of the preconditioner.
//!
//! On each level `ℓ` with operator `A`, block diagonal `D` and weight `ω`, the cycle
//! for right-hand side `b` is:
//!
//! 1. pre-smooth from zero: `x = ω D⁻¹ b`, then [`SWEEPS`]` − 1` more sweeps
//!    `x += ω D⁻¹ (b − A x)`;
//! 2. restrict the residual, `b_c = Pᵀ (b − A x)`, and cycle on the coarser level
//!    (solve exactly on the coarsest);
//! 3. correct, `x += P x_c`;
//! 4. post-smooth with [`SWEEPS`] sweeps `x += ω D⁻¹ (b − A x)`.
//!
//! Damped Jacobi is symmetric and the pre- and post-sweeps are as many, so the cycle
//! is a symmetric operator; it is positive definite because each level's sweeps
//! converge (`ω ρ(D⁻¹A) = 4/3 < 2`) and the coarse solve is. On the finest level, `A`
//! is the caller's operator of the tick and `D⁻¹` its inverse diagonal blocks, and
//! every vector is kept zero on the imposed vertices (see the module comment of
//! [`amg`](super)).

use nalgebra::{Matrix3, Vector3};

use super::{Amg, Coarsest, Level, SWEEPS};

impl Amg {
    /// `z = B r` on the free vertices (zero on the imposed ones, where `r` must be
    /// zero), with `op(v, out)` writing `out = A v` for the tick's operator and
    /// `dinv` its inverse diagonal blocks. Allocates nothing.
    pub fn apply(
        &mut self,
        op: &impl Fn(&[Vector3<f64>], &mut [Vector3<f64>]),
        dinv: &[Matrix3<f64>],
        imposed: &[bool],
        r: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
    ) {
        let f = &mut self.fine;
        let omega = f.omega;
        let n = r.len();
        for i in 0..n {
            z[i] = if imposed[i] {
                Vector3::zeros()
            } else {
                omega * (dinv[i] * r[i])
            };
        }
        let sweep = |z: &mut [Vector3<f64>], t: &mut [Vector3<f64>]| {
            op(z, t);
            for i in 0..n {
                if !imposed[i] {
                    z[i] += omega * (dinv[i] * (r[i] - t[i]));
                }
            }
        };
        for _ in (0..SWEEPS).skip(1) {
            sweep(z, &mut f.t);
        }
        op(z, &mut f.t);
        for i in 0..n {
            let d = if imposed[i] {
                Vector3::zeros()
            } else {
                r[i] - f.t[i]
            };
            f.flat[3 * i..3 * i + 3].copy_from_slice(d.as_slice());
        }
        f.r.mul(&f.flat, next_rhs(&mut self.levels, &mut self.coarsest));
        cycle(&mut self.levels, &mut self.coarsest);
        f.p.mul(next_solution(&self.levels, &self.coarsest), &mut f.flat);
        for i in 0..n {
            if !imposed[i] {
                z[i] += Vector3::new(f.flat[3 * i], f.flat[3 * i + 1], f.flat[3 * i + 2]);
            }
        }
        for _ in 0..SWEEPS {
            sweep(z, &mut f.t);
        }
    }
}

/// The right-hand side of the first of `levels`, or of the coarsest level.
fn next_rhs<'a>(levels: &'a mut [Level], coarsest: &'a mut Coarsest) -> &'a mut [f64] {
    match levels.first_mut() {
        Some(l) => &mut l.b,
        None => &mut coarsest.x,
    }
}

/// The solution of the first of `levels`, or of the coarsest level.
fn next_solution<'a>(levels: &'a [Level], coarsest: &'a Coarsest) -> &'a [f64] {
    match levels.first() {
        Some(l) => &l.x,
        None => &coarsest.x,
    }
}

/// One sweep `x += ω D⁻¹ (b − A x)` on a coarse level.
fn sweep(l: &mut Level) {
    l.a.mul(&l.x, &mut l.t);
    l.t.iter_mut().zip(&l.b).for_each(|(t, b)| *t = b - *t);
    l.dinv.apply_add(l.omega, &l.t, &mut l.x);
}

/// The V-cycle from the first of `levels` down: right-hand side in its `b`, solution
/// left in its `x` (on the coarsest level, both in `x`).
fn cycle(levels: &mut [Level], coarsest: &mut Coarsest) {
    let Some((l, rest)) = levels.split_first_mut() else {
        coarsest.factor.solve(&mut coarsest.x);
        return;
    };
    l.x.iter_mut().for_each(|x| *x = 0.0);
    l.dinv.apply_add(l.omega, &l.b, &mut l.x);
    for _ in (0..SWEEPS).skip(1) {
        sweep(l);
    }
    l.a.mul(&l.x, &mut l.t);
    l.t.iter_mut().zip(&l.b).for_each(|(t, b)| *t = b - *t);
    l.r.mul(&l.t, next_rhs(rest, coarsest));
    cycle(rest, coarsest);
    l.p.mul_add(next_solution(rest, coarsest), &mut l.x);
    for _ in 0..SWEEPS {
        sweep(l);
    }
}
