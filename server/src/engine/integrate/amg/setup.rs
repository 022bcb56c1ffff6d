//! Building the hierarchy: aggregation, prolongators and Galerkin coarse operators,
//! level after level, down to a dense factor.

use nalgebra::{Point3, Vector3};

use super::aggregate::{aggregate, strength};
use super::blocks::Blocks;
use super::dense::DenseCholesky;
use super::prolong::{BlockDiag, rigid_modes, smooth, spectral_radius, tentative};
use super::sparse::Csr;
use super::{Amg, Coarsest, Fine, Level, MAX_COARSE, THETA};
use crate::engine::elastic::BlockMatrix;

/// A coarse level must have at most this fraction of the unknowns of the level above
/// it: aggregates of a vertex's star give about a fifth on the livers, so a level
/// that keeps more than four fifths has stopped coarsening (a matrix with hardly any
/// strong connections), and another level would cost without helping.
const MAX_COARSENING_RATIO: f64 = 0.8;

/// Why a hierarchy could not be built (the solver then keeps block Jacobi).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AmgError {
    #[error("no unknowns are strongly connected: nothing to aggregate")]
    NothingToAggregate,
    #[error(
        "coarsening stalled at {unknowns} unknowns (from {above}): the matrix has too few strong connections"
    )]
    Stalled { unknowns: usize, above: usize },
    #[error(
        "the coarsest operator ({unknowns} unknowns) is not positive definite: the supports do not hold every rigid motion"
    )]
    NotPositiveDefinite { unknowns: usize },
}

impl Amg {
    /// Builds the hierarchy of `A = mass_scale · M + stiffness_scale · K` (`K` the
    /// rest stiffness, `M` the lumped masses `mass`), the vertices with `excluded[i]`
    /// (supports) left out, the rigid-body modes taken from the rest `positions`.
    pub fn new(
        k: &BlockMatrix,
        mass: &[f64],
        mass_scale: f64,
        stiffness_scale: f64,
        excluded: &[bool],
        positions: &[Point3<f64>],
    ) -> Result<Amg, AmgError> {
        let n = k.rows();
        let mut a = Csr::from_blocks(k, mass, mass_scale, stiffness_scale, excluded);
        let mut node_start: Vec<usize> = (0..=n).map(|i| 3 * i).collect();
        let mut modes = rigid_modes(positions);
        let mut excluded = excluded.to_vec();
        let mut theta = THETA;
        let mut fine: Option<Fine> = None;
        let mut levels = Vec::new();
        loop {
            let dinv = BlockDiag::new(&a, &node_start);
            let omega = 4.0 / (3.0 * spectral_radius(&a, &dinv));
            let s = strength(&a, &node_start, &excluded, theta);
            let (agg, count) = aggregate(&s, &excluded);
            if count == 0 {
                return Err(AmgError::NothingToAggregate);
            }
            let (p_tent, coarse_modes, coarse_start) = tentative(&agg, count, &node_start, &modes);
            let p = smooth(&a, &dinv, &p_tent, omega);
            let r = p.transpose();
            let coarse = r.times(&a.times(&p)).symmetrised().with_padded_diagonal();
            let rows = a.rows;
            match &fine {
                None => {
                    fine = Some(Fine {
                        omega,
                        p: Blocks::from_csr(&p),
                        r: Blocks::from_csr(&r),
                        t: vec![Vector3::zeros(); n],
                        flat: vec![0.0; 3 * n],
                    })
                }
                Some(_) => levels.push(Level {
                    x: vec![0.0; rows],
                    b: vec![0.0; rows],
                    t: vec![0.0; rows],
                    a: Blocks::from_csr(&a),
                    dinv,
                    omega,
                    p: Blocks::from_csr(&p),
                    r: Blocks::from_csr(&r),
                }),
            }
            if coarse.rows <= MAX_COARSE {
                let unknowns = coarse.rows;
                let mut dense = vec![0.0; unknowns * unknowns];
                for i in 0..unknowns {
                    let (cs, vs) = coarse.row(i);
                    for (&c, &v) in cs.iter().zip(vs) {
                        dense[i * unknowns + c as usize] = v;
                    }
                }
                let factor = DenseCholesky::new(unknowns, |i, j| dense[i * unknowns + j])
                    .ok_or(AmgError::NotPositiveDefinite { unknowns })?;
                return Ok(Amg {
                    scales: (mass_scale, stiffness_scale),
                    fine: fine.expect("the finest level is built first"),
                    levels,
                    coarsest: Coarsest {
                        factor,
                        x: vec![0.0; unknowns],
                    },
                });
            }
            if coarse.rows as f64 > MAX_COARSENING_RATIO * rows as f64 {
                return Err(AmgError::Stalled {
                    unknowns: coarse.rows,
                    above: rows,
                });
            }
            excluded = vec![false; count];
            a = coarse;
            node_start = coarse_start;
            modes = coarse_modes;
            theta *= 0.5;
        }
    }
}
