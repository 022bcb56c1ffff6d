//! Smoothed-aggregation algebraic multigrid (SA-AMG) as a preconditioner for the
//! conjugate gradient of the implicit and static solves (Vaněk, Mandel and Brezina
//! 1996; for elasticity with the rigid-body modes, Vaněk, Brezina and Mandel 2001).
//!
//! Block Jacobi leaves CG with iterations that grow with the mesh (6, 10, 16, 27 and
//! 110 a tick from SOFA's 596-tetrahedron liver to liver-300k at tolerance 1e-4):
//! the condition number of `(1 + hα) M + h² K` grows as the inverse square of the edge
//! length, and a diagonal preconditioner only fixes the scale of each row. Multigrid
//! removes the error a local smoother leaves (smooth, nearly rigid over many
//! elements) on coarser levels where it is local again, so each preconditioned
//! iteration reduces the error by a factor that does not depend on the mesh.
//!
//! **Setup** ([`Amg::new`], once per scene and tick length): from the assembled rest
//! system matrix `A = s_M M + s_K K` (3×3 vertex blocks; `s_M = 1 + hα`, `s_K = h²`
//! implicit, `s_M = 0`, `s_K = 1` static) with the scene's supports left out, each
//! level (1) measures strength of connection between nodes on block norms and groups
//! them into aggregates ([`aggregate`]); (2) builds the tentative prolongator from
//! the six rigid-body modes on each aggregate, orthonormalised by QR, and smooths it,
//! `P = (I − ω D⁻¹ A) P_tent` ([`prolong`]); (3) forms the Galerkin coarse operator
//! `Pᵀ A P`. Levels are added until the coarsest has at most [`MAX_COARSE`]
//! unknowns, which a dense Cholesky factor solves exactly.
//!
//! **Application** ([`Amg::apply`], one symmetric V-cycle per CG iteration, see
//! [`cycle`]): damped block-Jacobi pre- and post-smoothing, coarse correction in
//! between. On the finest level the smoother and residuals use the tick's *actual*
//! operator and its block diagonal (for the corotational model, the rotated `K̂` of
//! the tick), and the vertices imposed in this tick (supports and the vertices
//! instruments hold) are masked out; coarse levels keep the rest matrix. The V-cycle
//! is then a symmetric positive-definite operator on the free unknowns whatever the
//! coarse levels hold (its smoother converges, `ω ρ < 2`, and every coarse
//! correction is `Π P B_c Pᵀ Π` with `B_c` symmetric positive definite), so PCG stays
//! valid; how much the rotations drift from rest only changes how fast it converges.
//!
//! **Precision.** The prolongators, restrictions and coarse operators are built in
//! f64 and, where the scene's `[mechanics] stiffness` says so for their size, held
//! in f32 from then on ([`Amg::round_to_f32`]; sums stay f64): half the bytes a
//! cycle streams, the cycle still symmetric positive definite.
//!
//! Every vector a cycle touches is allocated by the setup: an application allocates
//! nothing.

mod aggregate;
mod blocks;
mod cycle;
mod dense;
mod prolong;
mod setup;
mod sparse;

pub use setup::AmgError;

use nalgebra::Vector3;

use blocks::Blocks;
use dense::DenseCholesky;
use prolong::BlockDiag;

/// Strength threshold θ on the finest level: the value Vaněk, Mandel and Brezina
/// recommend for elasticity, halved on each coarser level (their `θ_ℓ = 0.08 · ½^ℓ`),
/// since coarse operators are denser and their off-diagonal blocks relatively weaker.
pub const THETA: f64 = 0.08;

/// Largest coarsest level, in unknowns, solved by a dense factor. Its forward and
/// backward substitutions stream the `n²/2` packed entries twice per cycle: 8 MB at
/// 1,000, a fraction of a cycle on the meshes that need multigrid (liver-300k's
/// finest product alone streams about 35 MB), and cheaper than one more level
/// with its smoothing (on liver-300k a 726-unknown level solved densely gives the
/// same iterations as smoothing it over a 30-unknown one, in less time).
pub const MAX_COARSE: usize = 1000;

/// Smoothing sweeps before and after the coarse correction on each level (equal
/// counts keep the V-cycle symmetric). Two sweeps cut liver-300k's iterations from
/// about 15 to 11 a tick but cost more than they save (each fine sweep is a product).
pub const SWEEPS: usize = 1;

/// The finest level: its prolongator and restriction, the smoother's weight, and the
/// vectors of a cycle there.
#[derive(Clone, Debug)]
struct Fine {
    /// `ω = 4 / (3 ρ(D⁻¹ A))` of the rest operator.
    omega: f64,
    p: Blocks<3, 6>,
    r: Blocks<6, 3>,
    t: Vec<Vector3<f64>>,
    flat: Vec<f64>,
}

/// A coarse level above the coarsest.
#[derive(Clone, Debug)]
struct Level {
    a: Blocks<6, 6>,
    dinv: BlockDiag,
    omega: f64,
    p: Blocks<6, 6>,
    r: Blocks<6, 6>,
    x: Vec<f64>,
    b: Vec<f64>,
    t: Vec<f64>,
}

/// The coarsest level: its factor, and its right-hand side, solved in place.
#[derive(Clone, Debug)]
struct Coarsest {
    factor: DenseCholesky,
    x: Vec<f64>,
}

/// An SA-AMG hierarchy with its preallocated cycle vectors.
#[derive(Clone, Debug)]
pub struct Amg {
    /// `(s_M, s_K)` of the rest matrix it was built from.
    scales: (f64, f64),
    fine: Fine,
    levels: Vec<Level>,
    coarsest: Coarsest,
}

/// What a hierarchy holds, level by level (for reports and tests).
#[derive(Clone, Debug, PartialEq)]
pub struct LevelSizes {
    /// Unknowns of each level, finest first.
    pub unknowns: Vec<usize>,
    /// Stored entries of each coarse level's operator (with the zeros its blocks
    /// hold; the coarsest's dense square).
    pub nonzeros: Vec<usize>,
    /// Stored entries of each prolongator, finest first (with the zeros of its
    /// blocks).
    pub prolongator_nonzeros: Vec<usize>,
}

impl Amg {
    /// The `(s_M, s_K)` the hierarchy was built for.
    pub fn scales(&self) -> (f64, f64) {
        self.scales
    }

    /// Unknowns and nonzeros of each coarse level (the finest is the caller's).
    pub fn coarse_sizes(&self) -> LevelSizes {
        let mut unknowns: Vec<usize> = self.levels.iter().map(|l| l.x.len()).collect();
        let mut nonzeros: Vec<usize> = self.levels.iter().map(|l| l.a.entries()).collect();
        let n = self.coarsest.factor.order();
        unknowns.push(n);
        nonzeros.push(n * n);
        let mut prolongator_nonzeros = vec![self.fine.p.entries()];
        prolongator_nonzeros.extend(self.levels.iter().map(|l| l.p.entries()));
        LevelSizes {
            unknowns,
            nonzeros,
            prolongator_nonzeros,
        }
    }

    /// Bytes of the sparse matrices a cycle streams (the prolongators, restrictions
    /// and coarse operators above the coarsest), as they are held.
    pub fn matrix_bytes(&self) -> usize {
        let f = &self.fine;
        f.p.heap_bytes()
            + f.r.heap_bytes()
            + self
                .levels
                .iter()
                .map(|l| l.a.heap_bytes() + l.p.heap_bytes() + l.r.heap_bytes())
                .sum::<usize>()
    }

    /// Holds the sparse matrices of [`matrix_bytes`](Self::matrix_bytes) in f32
    /// from now on (see [`StiffnessStorage`](super::StiffnessStorage)): half the
    /// bytes a cycle streams. The cycle stays a symmetric positive-definite
    /// operator: each restriction is still exactly its prolongator's transpose (the
    /// same entries, rounded alike), each coarse operator still symmetric, and its
    /// smoother's `ω ρ(D⁻¹A) = 4/3` moves by the rounding, about 1e-7 of itself,
    /// far from 2. The coarse operators' inverse diagonal blocks and the coarsest
    /// factor, built from the f64 values, stay f64; they no longer invert the
    /// rounded operators exactly, which only changes how fast CG converges, by the
    /// same 1e-7.
    pub fn round_to_f32(&mut self) {
        let f = &mut self.fine;
        f.p.round_to_f32();
        f.r.round_to_f32();
        for l in &mut self.levels {
            l.a.round_to_f32();
            l.p.round_to_f32();
            l.r.round_to_f32();
        }
    }

    /// Products of the caller's fine operator one application makes: one per
    /// smoothing sweep, before and after, and the residual before restriction.
    pub fn operator_products(&self) -> usize {
        2 * SWEEPS
    }

    /// Bytes one application streams besides its
    /// [`operator_products`](Self::operator_products): each matrix once per pass
    /// that reads it (as held: f64 or f32), each vector once per pass that reads or
    /// writes it, the fine level's inverse diagonal blocks and imposed flags
    /// included, as [`apply`](Self::apply) and the cycle below it make them. A
    /// model of what the cycle moves, for the bench `step`'s achieved bytes per
    /// second; cache reuse is not credited.
    pub fn cycle_bytes(&self) -> usize {
        let f = &self.fine;
        let n = f.t.len();
        let (vector, dinv, flags) = (24 * n, 72 * n, n);
        // A sweep after the operator's product: z += ω D⁻¹ (r − t), reading r, t,
        // D⁻¹, z and the flags, writing z.
        let sweep = 4 * vector + dinv + flags;
        let fine = (vector + dinv + flags + vector)
            + (SWEEPS - 1) * sweep
            + (2 * vector + flags + vector)
            + (f.r.heap_bytes() + vector)
            + (f.p.heap_bytes() + vector)
            + (3 * vector + flags)
            + SWEEPS * sweep;
        let levels: usize = self
            .levels
            .iter()
            .enumerate()
            .map(|(k, l)| {
                let m = 8 * l.x.len();
                let coarser = 8 * match self.levels.get(k + 1) {
                    Some(c) => c.x.len(),
                    None => self.coarsest.x.len(),
                };
                let (a, d) = (l.a.heap_bytes(), l.dinv.heap_bytes());
                // x = A x, t = b − t, x += ω D⁻¹ t.
                let sweep = (a + 2 * m) + 3 * m + (d + 3 * m);
                (m + d + 3 * m)
                    + (SWEEPS - 1) * sweep
                    + (a + 2 * m + 3 * m)
                    + (l.r.heap_bytes() + m + coarser)
                    + (l.p.heap_bytes() + coarser + 2 * m)
                    + SWEEPS * sweep
            })
            .sum();
        // The restriction into the first coarse level writes its right-hand side,
        // the prolongation reads its solution.
        let first = 8 * self
            .levels
            .first()
            .map_or(self.coarsest.x.len(), |l| l.x.len());
        // Forward and backward substitution read the packed factor and the vector.
        let coarsest = 2 * (self.coarsest.factor.heap_bytes() + 8 * self.coarsest.x.len());
        fine + 2 * first + levels + coarsest
    }

    /// Whether [`round_to_f32`](Self::round_to_f32) has been applied.
    pub fn is_f32(&self) -> bool {
        self.fine.p.is_f32()
    }

    /// Bytes held.
    pub fn heap_bytes(&self) -> usize {
        let f = &self.fine;
        let fine =
            f.p.heap_bytes() + f.r.heap_bytes() + f.t.capacity() * 24 + f.flat.capacity() * 8;
        let levels: usize = self
            .levels
            .iter()
            .map(|l| {
                l.a.heap_bytes()
                    + l.dinv.heap_bytes()
                    + l.p.heap_bytes()
                    + l.r.heap_bytes()
                    + (l.x.capacity() + l.b.capacity() + l.t.capacity()) * 8
            })
            .sum();
        fine + levels + self.coarsest.factor.heap_bytes() + self.coarsest.x.capacity() * 8
    }
}

#[cfg(test)]
mod tests;
