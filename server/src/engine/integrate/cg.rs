//! Preconditioned conjugate gradient on a symmetric positive-definite block system with
//! some unknowns imposed.
//!
//! The system `A x = b` is solved for the free vertices only, the imposed ones keeping
//! the values already in `x` ("projected" CG): residuals and search directions are kept
//! zero on imposed vertices, which is CG on `A_ff x_f = b_f − A_fc x_c`. The
//! preconditioner is block Jacobi, `P = diag(A_ii)⁻¹`, exact on each 3×3 vertex block,
//! or, when [`CgWorkspace::amg`] holds a hierarchy and [`CgWorkspace::use_amg`] is
//! set, one V-cycle of smoothed-aggregation multigrid ([`Amg`]) whose finest level
//! smooths with the solve's own operator and those inverse blocks.

use std::ops::Range;

use nalgebra::{Matrix3, Vector3};

use super::Interrupt;
use super::amg::Amg;
use crate::engine::elastic::Parts;
use crate::engine::workers::{Disjoint, Workers, share};

/// Buffers of one CG solve, allocated once.
#[derive(Clone, Debug)]
pub struct CgWorkspace {
    r: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    p: Vec<Vector3<f64>>,
    q: Vec<Vector3<f64>>,
    /// Inverse diagonal blocks `A_ii⁻¹`, filled by the caller.
    pub precond: Vec<Matrix3<f64>>,
    /// The multigrid hierarchy, built by the caller for the rest part of its system.
    pub amg: Option<Amg>,
    /// Whether the next solves precondition with [`amg`](Self::amg) (if built).
    pub use_amg: bool,
    /// Read before each iteration: a raised flag ends the solve (unconverged).
    pub interrupt: Interrupt,
    /// The ranges the vector updates of [`solve_shared`](Self::solve_shared) are
    /// shared by (one part unless [`set_parts`](Self::set_parts)).
    parts: Parts,
    /// Each part's partial sums of the dot products of one update.
    partial: Vec<[f64; 2]>,
}

/// When a solve stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stop {
    /// The caller's measure of the size of the forces forming `b`.
    pub reference: f64,
    /// Stop when `‖r_f‖ ≤ tolerance · reference`.
    pub tolerance: f64,
    /// Or after this many iterations.
    pub max_iterations: u32,
}

/// Outcome of a solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgReport {
    pub iterations: u32,
    /// `‖r_f‖ / reference`, the final relative residual.
    pub relative_residual: f64,
    pub converged: bool,
}

impl CgWorkspace {
    pub fn new(n: usize) -> Self {
        let z = vec![Vector3::zeros(); n];
        CgWorkspace {
            r: z.clone(),
            p: z.clone(),
            q: z.clone(),
            z,
            precond: vec![Matrix3::identity(); n],
            amg: None,
            use_amg: false,
            interrupt: Interrupt::default(),
            parts: Parts::new(n, 1, std::iter::empty()),
            partial: vec![[0.0; 2]; 1],
        }
    }

    /// Shares the vector updates of later solves by `parts` (of the same vertices).
    pub fn set_parts(&mut self, parts: Parts) {
        self.partial = vec![[0.0; 2]; parts.count()];
        self.parts = parts;
    }

    pub fn heap_bytes(&self) -> usize {
        self.r.capacity() * 24 * 4
            + self.precond.capacity() * 72
            + self.amg.as_ref().map_or(0, Amg::heap_bytes)
    }

    /// Solves `A x = b` on the free vertices (`imposed[i] == false`), starting from the
    /// values in `x` (a warm start) and leaving imposed entries of `x` untouched.
    ///
    /// Stops when `‖r_f‖ ≤ stop.tolerance · stop.reference`. `reference` is the caller's measure of
    /// the size of the forces forming `b` (never the residual of the warm start alone,
    /// or a good guess would demand a better answer); if it is zero the free solution is
    /// zero. `apply(v, out)` must write `out = A v`.
    pub fn solve(
        &mut self,
        apply: impl Fn(&[Vector3<f64>], &mut [Vector3<f64>]),
        imposed: &[bool],
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        stop: Stop,
    ) -> CgReport {
        self.solve_shared(None, apply, imposed, b, x, stop)
    }

    /// [`solve`](Self::solve), the vector updates of each iteration shared among
    /// `workers` by the parts of [`set_parts`](Self::set_parts) (the product is
    /// `apply`'s to share). Each part's dot products are summed over its range and the
    /// partial sums added in part order: with one part, the sequential sums to the
    /// last bit. The multigrid cycle itself runs on this thread.
    pub fn solve_shared(
        &mut self,
        workers: Option<&Workers>,
        apply: impl Fn(&[Vector3<f64>], &mut [Vector3<f64>]),
        imposed: &[bool],
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        stop: Stop,
    ) -> CgReport {
        let Stop {
            reference,
            tolerance,
            max_iterations,
        } = stop;
        let n = x.len();
        if reference == 0.0 {
            for i in 0..n {
                if !imposed[i] {
                    x[i] = Vector3::zeros();
                }
            }
            return CgReport {
                iterations: 0,
                relative_residual: 0.0,
                converged: true,
            };
        }
        let goal = tolerance * reference;
        apply(x, &mut self.q);
        for i in 0..n {
            self.r[i] = if imposed[i] {
                Vector3::zeros()
            } else {
                b[i] - self.q[i]
            };
        }
        let mut multigrid = self.amg.as_mut().filter(|_| self.use_amg);
        if let Some(amg) = multigrid.as_mut() {
            amg.apply(&apply, &self.precond, imposed, &self.r, &mut self.z);
        } else {
            for i in 0..n {
                self.z[i] = self.precond[i] * self.r[i];
            }
        }
        let mut rz = 0.0;
        for i in 0..n {
            self.p[i] = self.z[i];
            rz += self.r[i].dot(&self.z[i]);
        }
        let mut r_norm = norm(&self.r);
        let mut iterations = 0;
        while r_norm > goal && iterations < max_iterations && !self.interrupt.is_raised() {
            // A residual that has sunk into subnormal numbers is round-off: its
            // quotients (α = rz/pq, β = rz'/rz) would divide by underflowed values
            // and blow up to infinity or NaN. It cannot be reduced further.
            if !rz.is_normal() {
                break;
            }
            apply(&self.p, &mut self.q);
            let (p, q) = (&self.p, Disjoint::new(&mut self.q));
            let [pq, _] = over_parts(workers, &self.parts, &mut self.partial, |rows| {
                // SAFETY: each part writes its own range.
                let q = unsafe { q.range(rows.clone()) };
                let mut pq = 0.0;
                for (q, i) in q.iter_mut().zip(rows) {
                    if imposed[i] {
                        *q = Vector3::zeros();
                    }
                    pq += p[i].dot(q);
                }
                [pq, 0.0]
            });
            if pq <= 0.0 || !pq.is_normal() {
                // A is SPD on the free set, so this is a breakdown from round-off at a
                // converged residual (or one sunk into subnormals, whose quotient would
                // overflow), or a system without enough supports.
                break;
            }
            let alpha = rz / pq;
            let mut rz_new = 0.0;
            let mut rr = 0.0;
            if let Some(amg) = multigrid.as_mut() {
                for i in 0..n {
                    x[i] += alpha * self.p[i];
                    self.r[i] -= alpha * self.q[i];
                    rr += self.r[i].norm_squared();
                }
                if rr.sqrt() > goal {
                    amg.apply(&apply, &self.precond, imposed, &self.r, &mut self.z);
                    for i in 0..n {
                        rz_new += self.r[i].dot(&self.z[i]);
                    }
                } else {
                    // Converged: the next direction, and its V-cycle, are not needed.
                    rz_new = rz;
                }
            } else {
                let (p, q, precond) = (&self.p, &self.q, &self.precond);
                let (xs, r, z) = (
                    Disjoint::new(x),
                    Disjoint::new(&mut self.r),
                    Disjoint::new(&mut self.z),
                );
                [rz_new, rr] = over_parts(workers, &self.parts, &mut self.partial, |rows| {
                    // SAFETY: each part writes its own range.
                    let (x, r, z) = unsafe {
                        (
                            xs.range(rows.clone()),
                            r.range(rows.clone()),
                            z.range(rows.clone()),
                        )
                    };
                    let (mut rz, mut rr) = (0.0, 0.0);
                    for (k, i) in rows.enumerate() {
                        x[k] += alpha * p[i];
                        r[k] -= alpha * q[i];
                        z[k] = precond[i] * r[k];
                        rz += r[k].dot(&z[k]);
                        rr += r[k].norm_squared();
                    }
                    [rz, rr]
                });
            }
            let beta = rz_new / rz;
            let (z, p) = (&self.z, Disjoint::new(&mut self.p));
            over_parts(workers, &self.parts, &mut self.partial, |rows| {
                // SAFETY: each part writes its own range.
                let p = unsafe { p.range(rows.clone()) };
                for (p, i) in p.iter_mut().zip(rows) {
                    *p = z[i] + beta * *p;
                }
                [0.0; 2]
            });
            rz = rz_new;
            r_norm = rr.sqrt();
            iterations += 1;
        }
        CgReport {
            iterations,
            relative_residual: r_norm / reference,
            converged: r_norm <= goal,
        }
    }
}

/// Runs `sums(range)` for each part's range, on `workers`, and adds the partial
/// sums it returns in part order (from zero: with one part, its sums exactly).
fn over_parts(
    workers: Option<&Workers>,
    parts: &Parts,
    partial: &mut [[f64; 2]],
    sums: impl Fn(Range<usize>) -> [f64; 2] + Sync,
) -> [f64; 2] {
    let cells = Disjoint::new(partial);
    // SAFETY: part `t` writes slot `t` only.
    share(workers, parts.count(), &|t| unsafe {
        *cells.at(t) = sums(parts.range(t))
    });
    partial
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]])
}

/// Euclidean norm of a block vector.
pub fn norm(v: &[Vector3<f64>]) -> f64 {
    v.iter().map(|x| x.norm_squared()).sum::<f64>().sqrt()
}

/// Euclidean norm of a block vector over the free vertices only.
pub fn free_norm(v: &[Vector3<f64>], imposed: &[bool]) -> f64 {
    v.iter()
        .zip(imposed)
        .filter(|(_, c)| !**c)
        .map(|(x, _)| x.norm_squared())
        .sum::<f64>()
        .sqrt()
}
